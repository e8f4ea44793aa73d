"""The one face every identification method shows: ``identify(y, dt, prior, **options) -> Estimate``.

A method gets the sampled tip acceleration ``y`` (m/s²), the sample interval ``dt`` (s), the a-priori
frequencies ``prior`` (rad/s, one per mode to identify) and its own keyword options. It never sees the
truth, files, Hydra or MLflow. Inputs are checked once, here, with one clear message each.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Estimate:
    """Result of one identification.

    Attributes
    ----------
    frequencies : ndarray, shape (m,)
        Estimated natural frequencies in rad/s, one per prior entry, in prior order.
    std : ndarray, shape (m,)
        1σ uncertainty of each frequency in rad/s; NaN where the method gives none.
    history : ndarray, shape (n, m) or None
        Frequency estimates after every sample, for the recursive methods; None otherwise.
    converged : bool
        False when the method itself judges its answer unusable (divergence, no lock, no peak).
    iterations : int
        Iterations of the search (0 for one-pass methods, the number of samples for recursive ones).
    message : str
        Why it stopped, or why it failed.
    extra : dict
        Method-specific diagnostics (plain numbers/arrays), e.g. damping estimates or lock indicators.
        ``extra["converged_per_mode"]`` (bool per prior entry), when present, is what the scorer uses.
    """

    frequencies: np.ndarray
    std: np.ndarray
    history: np.ndarray | None = None
    converged: bool = True
    iterations: int = 0
    message: str = ""
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        freq = np.asarray(self.frequencies, dtype=float).reshape(-1)
        std = np.broadcast_to(np.asarray(self.std, dtype=float), freq.shape).copy()
        object.__setattr__(self, "frequencies", freq)
        object.__setattr__(self, "std", std)
        if self.history is not None:
            object.__setattr__(self, "history", np.asarray(self.history, dtype=float))


def failed(prior: np.ndarray, message: str, *, iterations: int = 0, history=None, **extra) -> Estimate:
    """An Estimate for a run that produced no usable answer: NaN frequencies, ``converged=False``."""
    nan = np.full(np.shape(prior), np.nan)
    return Estimate(nan, nan, history=history, converged=False, iterations=iterations,
                    message=message, extra=dict(extra))


def check_inputs(y, dt, prior) -> tuple[np.ndarray, float, np.ndarray]:
    """Validate and convert the three common arguments; raise ``ValueError`` naming the bad value.

    Returns ``y`` as a 1-D float array, ``dt`` as float and ``prior`` as a 1-D float array.
    """
    y = np.asarray(y, dtype=float)
    if y.ndim != 1:
        raise ValueError(f"y must be a 1-D record of samples, got shape {y.shape}")
    if y.size < 8:
        raise ValueError(f"record length {y.size} is too short: at least 8 samples are needed")
    if not np.all(np.isfinite(y)):
        bad = int(np.flatnonzero(~np.isfinite(y))[0])
        raise ValueError(f"y[{bad}] = {y[bad]} is not a finite number")
    dt = float(dt)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"sample interval dt = {dt} s must be a positive number")
    prior = np.atleast_1d(np.asarray(prior, dtype=float))
    if prior.ndim != 1 or prior.size == 0:
        raise ValueError(f"prior must be a non-empty list of frequencies in rad/s, got {prior.tolist()}")
    nyquist = np.pi / dt
    for i, w in enumerate(prior):
        if not (np.isfinite(w) and w > 0):
            raise ValueError(f"prior[{i}] = {w} rad/s must be a positive frequency")
        if w >= nyquist:
            raise ValueError(f"prior[{i}] = {w} rad/s is above the Nyquist frequency {nyquist:.4g} rad/s "
                             f"(dt = {dt:.6g} s)")
    return y, dt, prior


def make_options(options_cls, options: dict, method: str):
    """Build a method's options dataclass from keywords, naming an unknown key in the error."""
    known = {f.name for f in dataclasses.fields(options_cls)}
    for key in options:
        if key not in known:
            raise ValueError(f"unknown option '{key}' for method '{method}'; known: {sorted(known)}")
    return options_cls(**options)
