"""The one face every identification method shows: ``identify(y, dt, prior, **options) -> Estimate``.

A method gets the sampled tip acceleration ``y`` (m/s²), the sample interval ``dt`` (s), the a-priori
frequencies ``prior`` (rad/s, one per mode to identify) and its own keyword options. It never sees the
truth, files, Hydra or MLflow. Inputs are checked once, here, with one clear message each.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Estimate", "failed", "MAX_ABS_ACCEL_M_S2", "check_inputs", "check_prior", "FLAT_RELATIVE_SPREAD",
           "flat_record", "make_options", "relative_option"]


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
    converged_per_mode : ndarray of bool, shape (m,)
        Whether the record determined each mode: what the scorer uses. Defaults to ``converged`` for every
        mode. (A plugin written before this field may still put it in ``extra["converged_per_mode"]``: it
        is moved here.)
    """

    frequencies: np.ndarray
    std: np.ndarray
    history: np.ndarray | None = None
    converged: bool = True
    iterations: int = 0
    message: str = ""
    extra: dict = field(default_factory=dict)
    converged_per_mode: np.ndarray | None = None

    def __post_init__(self):
        freq = np.asarray(self.frequencies, dtype=float).reshape(-1)
        std = np.asarray(self.std, dtype=float)
        # the same values as broadcast_to(...).copy(); a plain copy when the shapes already agree
        std = std.copy() if std.shape == freq.shape else np.broadcast_to(std, freq.shape).copy()
        object.__setattr__(self, "frequencies", freq)
        object.__setattr__(self, "std", std)
        per_mode = self.converged_per_mode
        if "converged_per_mode" in self.extra:
            extra = dict(self.extra)
            legacy = extra.pop("converged_per_mode")
            per_mode = legacy if per_mode is None else per_mode
            object.__setattr__(self, "extra", extra)
        if per_mode is None:
            per_mode = [bool(self.converged)] * freq.size
        per_mode = np.asarray(per_mode, dtype=bool).reshape(-1)
        if per_mode.shape != freq.shape:
            raise ValueError(f"converged_per_mode has {per_mode.size} entries for {freq.size} frequencies")
        object.__setattr__(self, "converged_per_mode", per_mode)
        if self.history is not None:
            object.__setattr__(self, "history", np.asarray(self.history, dtype=float))


def failed(prior: np.ndarray, message: str, *, iterations: int = 0, history=None, **extra) -> Estimate:
    """An Estimate for a run that produced no usable answer: NaN frequencies, ``converged=False``, and
    ``converged_per_mode`` False for every mode."""
    nan = np.full(np.shape(prior), np.nan)
    return Estimate(nan, nan, history=history, converged=False, iterations=iterations,
                    message=message, extra=dict(extra), converged_per_mode=np.zeros(nan.size, bool))


# Largest |sample| accepted, m/s²: ±10⁵ g, the range of the largest shock accelerometers. A tip acceleration
# beyond it is a units or parsing error, not a measurement, and values near 1e300 overflow to inf in the
# methods' sums of squares (the filters' covariances hold products of y⁴).
MAX_ABS_ACCEL_M_S2 = 1e6


def check_inputs(y, dt, prior) -> tuple[np.ndarray, float, np.ndarray]:
    """Validate and convert the three common arguments; raise ``ValueError`` naming the bad value.

    Returns ``y`` as a 1-D float array, ``dt`` as float and ``prior`` as a 1-D float array.

    Rules: ``y`` holds at least 8 real (not boolean, complex or text), finite samples with
    |y| ≤ :data:`MAX_ABS_ACCEL_M_S2`; ``dt`` is a positive real number; ``prior`` holds one positive
    frequency per mode, below the Nyquist frequency π/dt and **strictly increasing**: estimates come back in
    prior order, and the i-th prior names the i-th mode counted from the lowest (the order the scorer
    matches them to the truth in), so a repeated or out-of-order prior would silently swap modes.
    """
    y = _real_array(y, "y", "a 1-D record of samples in m/s²")
    if y.ndim != 1:
        raise ValueError(f"y must be a 1-D record of samples, got shape {y.shape}")
    if y.size < 8:
        raise ValueError(f"record length {y.size} is too short: at least 8 samples are needed")
    if not float(np.abs(y).max()) <= MAX_ABS_ACCEL_M_S2:   # one pass for both checks (NaN fails it too)
        if not np.isfinite(y).all():
            bad = int(np.flatnonzero(~np.isfinite(y))[0])
            raise ValueError(f"y[{bad}] = {y[bad]} is not a finite number")
        bad = int(np.flatnonzero(np.abs(y) > MAX_ABS_ACCEL_M_S2)[0])
        raise ValueError(f"y[{bad}] = {y[bad]:g} m/s² is not a physical acceleration (|y| must be at most "
                         f"{MAX_ABS_ACCEL_M_S2:g} m/s², 1e5 g): check the units of the record")
    dt, prior = check_prior(dt, prior)
    return y, dt, prior


def check_prior(dt, prior) -> tuple[float, np.ndarray]:
    """The checks of :func:`check_inputs` on ``dt`` and ``prior`` alone (no record needed)."""
    dt = _real_array(dt, "dt", "a sample interval in s")
    if dt.ndim != 0:
        raise ValueError(f"sample interval dt must be one number in s, got shape {dt.shape}")
    dt = float(dt)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"sample interval dt = {dt} s must be a positive number")
    prior = np.atleast_1d(_real_array(prior, "prior", "a list of frequencies in rad/s"))
    if prior.ndim != 1 or prior.size == 0:
        raise ValueError(f"prior must be a non-empty list of frequencies in rad/s, got {prior.tolist()}")
    nyquist = np.pi / dt
    for i, w in enumerate(prior.tolist()):       # Python floats: the same tests, without numpy scalar calls
        if not (math.isfinite(w) and w > 0):
            raise ValueError(f"prior[{i}] = {w} rad/s must be a positive frequency")
        if w >= nyquist:
            raise ValueError(f"prior[{i}] = {w} rad/s is above the Nyquist frequency {nyquist:.4g} rad/s "
                             f"(dt = {dt:.6g} s)")
        if i > 0 and not w > prior[i - 1]:
            raise ValueError(f"prior {prior.tolist()}: prior[{i}] = {w:g} rad/s is not above prior[{i - 1}] = "
                             f"{prior[i - 1]:g} rad/s; give one frequency per mode, in increasing order")
    return dt, prior


# A record whose samples all equal their mean to within this fraction of the largest |sample| (a thousand
# times double-precision round-off of the mean) carries no oscillation: all zero, or a constant bias.
FLAT_RELATIVE_SPREAD = 1e-12


def flat_record(y: np.ndarray) -> str:
    """Why the record carries no information on any frequency, or ``''`` when it may.

    A method returns :func:`failed` (every mode ``converged_per_mode = False``) for such a record instead of
    its prior with a meaningless uncertainty.
    """
    scale = float(np.max(np.abs(y)))
    spread = float(np.max(np.abs(y - np.mean(y))))
    if scale == 0.0:
        return "the record is identically zero: no oscillation to identify"
    if spread <= FLAT_RELATIVE_SPREAD * scale:
        return f"the record is constant ({float(np.mean(y)):.6g} m/s² in every sample): no oscillation to identify"
    return ""


def _real_array(value, name: str, what: str) -> np.ndarray:
    """``value`` as a float array if it holds real numbers only (not booleans, complex numbers, text,
    None or a mapping); else ``ValueError`` naming the argument."""
    if isinstance(value, (dict, str, bytes)) or value is None:
        raise ValueError(f"{name} must be {what}, got {type(value).__name__} {value!r:.60}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError) as exc:          # ragged nested lists
        raise ValueError(f"{name} must be {what}: {exc}") from None
    if arr.dtype.kind not in "iuf":
        kinds = {"b": "booleans", "c": "complex numbers", "U": "text", "S": "text", "O": "non-numbers"}
        raise ValueError(f"{name} must be {what}, got {kinds.get(arr.dtype.kind, arr.dtype.name)} "
                         f"({type(value).__name__})")
    return arr.astype(float, copy=False)


def make_options(options_cls, options: dict, method: str):
    """Build a method's options dataclass from keywords, naming an unknown key in the error."""
    if options:                                  # (the defaults need no check: a warm fit's µs)
        known = {f.name for f in dataclasses.fields(options_cls)}
        for key in options:
            if key not in known:
                raise ValueError(f"unknown option '{key}' for method '{method}'; known: {sorted(known)}")
    return options_cls(**options)


def relative_option(method: str, rel_name: str, rel, abs_name: str, abs_value, abs_default,
                    allow_zero: bool = False) -> float | None:
    """An option given in units of the prior (``rel_name``: per period of the slowest mode, a fraction of ω₀)
    beside its absolute twin ``abs_name``: a finite number, positive (non-negative with ``allow_zero``), and
    the twin left at its default. Returns it as a float, or None when it is not given."""
    if rel is None:
        return None
    sign = "non-negative" if allow_zero else "positive"
    if (isinstance(rel, bool) or not isinstance(rel, (int, float)) or not np.isfinite(rel)
            or not (rel >= 0 if allow_zero else rel > 0)):
        raise ValueError(f"{method}: {rel_name} = {rel!r} must be a {sign} number")
    if abs_value != abs_default:
        raise ValueError(f"{method}: give {rel_name} or {abs_name}, not both ({rel_name} = {rel!r}, "
                         f"{abs_name} = {abs_value!r})")
    return float(rel)
