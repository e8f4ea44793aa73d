"""The prediction-error method with a Gauss–Newton search (paper §3.3, §4.3, eqs. 30–31, Tables 4–5).

The face of the family is :func:`identify` with its :class:`Options` (the measured best setting; the
paper's setting is the variant ``pem:paper``, configs/method/pem_paper.yaml). Behind it:

- ``_fit``: the starts, the search per start, the repair restarts and the :class:`~methods.estimate.Estimate`;
- :mod:`methods.pem.predictor`: the innovation-form predictor of eq. (31) and its exact Jacobian;
- :mod:`methods.pem.search`: the Gauss–Newton / Levenberg–Marquardt search of eq. (30) (the reference path);
- ``_fast``: the same search by variable projection for the default options; its per-record model (basis,
  linear solve, reduced Jacobian) is public as :class:`SeparableModel`;
- ``_separable``: :func:`separable_fit`, the variable-projection fit of shared poles over a record's
  pulse-free segments from a given start (``gated_pencil``'s window fit; the peers' mode picker's check);
- ``_pencil``: the matrix-pencil start from the record;
- ``_residual``: the residual's whiteness check (public as :func:`residual_check`) and the robust (sandwich)
  std, in every estimate;
- ``_drift``: :func:`segment_drift` (with pem's fit, from ``_fit``), the test for a frequency that drifts over
  the record;
- ``_chirp``: the small-amplitude frequency ω₀ from one fit of the record's backbone chirp;
- ``_saturation``: a clipped sensor's plateaus, left out of the fit.

``predictor`` and ``search`` are public so that a study can drive the search on its own problem
(``experiments.benchmarks.pem`` compares it with SciPy's ``least_squares`` on the same predictor).
See methods/pem/README.md.

>>> import numpy as np
>>> from methods import pem
>>> t = 0.02 * np.arange(256)
>>> y = np.cos(20.3 * t) * np.exp(-0.1 * t) + np.cos(56.7 * t) * np.exp(-0.3 * t)
>>> est = pem.identify(y, 0.02, [18.0, 52.0])
>>> np.round(est.frequencies, 2).tolist()
[20.3, 56.7]
"""

from __future__ import annotations

import contextlib

import numpy as np

from methods.pem import _fast, predictor, search
from methods.pem._drift import DriftReport
from methods.pem._fast import _Model as SeparableModel
from methods.pem._fit import (
    Options,
    check_options,
    detection_std,
    free_mask,
    identify,
    segment_drift,
    starts,
)
from methods.pem._residual import residual_check
from methods.pem._separable import separable_fit

__all__ = ["DriftReport", "Options", "SeparableModel", "check_options", "detection_std", "free_mask", "identify",
           "predictor", "reference_path", "residual_check", "search", "segment_drift", "separable_fit",
           "starts"]


@contextlib.contextmanager
def reference_path(recursive: bool = False):
    """Within the block, :func:`identify` takes the reference search (:mod:`methods.pem.search`) instead of
    the variable-projection fast path; ``recursive``: with the recursive CasADi predictor (gain zero)
    instead of the closed form. For benchmarks and equivalence checks; not thread-safe."""
    closed, applies = predictor.make_evaluator, _fast.applies
    _fast.applies = lambda opts: False
    if recursive:
        predictor.make_evaluator = lambda y, dt, m, free, K: predictor.Recursive(
            y.size, m, free, False, y, np.zeros(2 * m), dt)
    try:
        yield
    finally:
        predictor.make_evaluator, _fast.applies = closed, applies
