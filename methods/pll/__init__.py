"""A bank of phase-locked loops, one per mode (paper §3.4, §4.4, Fig. 2, eqs. 32–37, Table 6).

The face: :func:`identify`, :class:`Options` and :func:`check_options`. :mod:`methods.pll.design` derives a
loop's filters and gains from its prior frequency and Δt (eq. 37 and the input band-pass of §4.4); the
paper's figure scripts use it directly. The loop itself is ``_loop``. See methods/pll/README.md.

>>> import numpy as np
>>> from methods import pll
>>> t = 0.02 * np.arange(4096)
>>> est = pll.identify(np.sin(20.3 * t), 0.02, [19.0])
>>> bool(abs(est.frequencies[0] - 20.3) < 0.1)
True
"""

from methods.pll import design
from methods.pll._loop import PER_LOOP_OPTIONS, Options, check_options, identify

__all__ = ["PER_LOOP_OPTIONS", "Options", "check_options", "design", "identify"]
