"""The result every tracker returns, and the checks every tracker shares."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Track:
    """Frequencies of the modes over time, estimated online.

    The estimate at ``t_s[k]`` uses the samples y(t) with t ≤ ``t_s[k]`` only (causal): a later sample
    never changes it.

    Attributes
    ----------
    t_s : ndarray, shape (K,)
        Times of the estimates, s, t = k·Δt of the last sample used (sample 0 at t = 0); increasing.
    frequencies : ndarray, shape (K, m)
        Estimated natural frequencies, rad/s, in prior order; NaN where the tracker has none.
    std : ndarray, shape (K, m)
        1σ of each estimate, rad/s, as the tracker itself reports it; NaN where it gives none.
    converged : ndarray of bool, shape (K, m)
        Whether the tracker judges each estimate determined by the data (locked, in the filter's
        determined range, a mode found in the window).
    runtime_s : float
        CPU time of the whole run (``time.process_time``), s.
    message : str
        What happened (divergences, restarts, windows without a mode).
    extra : dict
        Tracker-specific diagnostics (plain numbers or arrays).
    """

    t_s: np.ndarray
    frequencies: np.ndarray
    std: np.ndarray
    converged: np.ndarray
    runtime_s: float = 0.0
    message: str = ""
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        t = np.asarray(self.t_s, dtype=float).reshape(-1)
        freq = np.asarray(self.frequencies, dtype=float)
        if freq.ndim != 2 or freq.shape[0] != t.size:
            raise ValueError(f"frequencies of shape {freq.shape} do not match {t.size} times")
        std = np.broadcast_to(np.asarray(self.std, dtype=float), freq.shape).copy()
        conv = np.broadcast_to(np.asarray(self.converged, dtype=bool), freq.shape).copy()
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "frequencies", freq)
        object.__setattr__(self, "std", std)
        object.__setattr__(self, "converged", conv & np.isfinite(freq))
        object.__setattr__(self, "runtime_s", float(self.runtime_s))


def with_runtime(track: Track, runtime_s: float) -> Track:
    """``track`` with its CPU time set."""
    return dataclasses.replace(track, runtime_s=runtime_s)


def check_window(window_samples, hop_samples, tracker: str, n_samples: int | None = None) -> None:
    """A sliding window of W samples every H samples: W ≥ 8 (the shortest record a method accepts),
    H ≥ 1, and W no longer than the record when its length is known; ``ValueError`` naming the option."""
    for name, value, low in (("window_samples", window_samples, 8), ("hop_samples", hop_samples, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{tracker}: {name} = {value!r} must be an integer number of samples ≥ {low}")
    if n_samples is not None and window_samples > n_samples:
        raise ValueError(f"{tracker}: window_samples = {window_samples} is longer than the record "
                         f"({n_samples} samples)")


def window_ends(n_samples: int, window_samples: int, hop_samples: int) -> np.ndarray:
    """Index of the last sample of each window: W − 1, W − 1 + H, … ≤ n − 1."""
    return np.arange(window_samples - 1, n_samples, hop_samples)


def usable_prior(candidate: np.ndarray, fallback: np.ndarray, nyquist: float) -> np.ndarray:
    """``candidate`` where it is a valid prior (finite, positive, strictly increasing, below Nyquist), mode
    by mode falling back to ``fallback``; the whole ``fallback`` if the mix is still not increasing."""
    mix = np.where(np.isfinite(candidate) & (candidate > 0) & (candidate < nyquist), candidate, fallback)
    if np.all(np.diff(mix) > 0):
        return mix
    return fallback.copy()
