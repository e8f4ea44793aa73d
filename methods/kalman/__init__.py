"""The paper's Kalman filters for the modal frequencies (§3.1–3.2, §4.1–4.2, eqs. 8–29).

Two methods, one module each, both registered by name:

- :mod:`methods.kalman.akf`: the augmented extended Kalman filter (eqs. 8–24);
- :mod:`methods.kalman.wkf`: the same filter on frequency-weighted measurements (eqs. 25–29, 38).

Behind them: ``_filter`` (the model, filterpy's EKF loop, the divergence test: the reference) and
``_lockstep`` (a cell's R filters stepped together on stacked arrays, each record getting what it gets
alone). ``modal_transition`` (the exact oscillator transition and its ω-derivative) is public: the tracking
family's force-driven filters (methods/tracking/_ambient.py, _rpem.py) share it. See methods/kalman/README.md.

>>> import numpy as np
>>> from methods.kalman import akf
>>> t = 0.02 * np.arange(512)
>>> y = 4.0 * np.cos(20.3 * t)
>>> est = akf.identify(y, 0.02, [19.0], measurement="acceleration")
>>> bool(abs(est.frequencies[0] - 20.3) < 0.05)
True
"""

from methods.kalman import akf, wkf
from methods.kalman._filter import modal_transition

__all__ = ["akf", "modal_transition", "wkf"]
