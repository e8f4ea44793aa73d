"""The identified modes' damped sinusoids fitted to the record: amplitudes, the model and its residual.

Given the frequencies ωᵢ and damping ratios ζᵢ a method found, the record is linear in the rest:

    y(tₖ) ≈ c + Σᵢ e^(−ζᵢωᵢtₖ) (Aᵢ cos ω_dᵢtₖ + Bᵢ sin ω_dᵢtₖ),   ω_dᵢ = ωᵢ√(1 − ζᵢ²),

solved by linear least squares (``scipy.linalg.lstsq``). The amplitude of mode i is √(Aᵢ² + Bᵢ²), its
envelope at the first sample of the segment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["ModalFit", "fit_modes"]


@dataclass(frozen=True)
class ModalFit:
    """``model`` and ``residual`` (shape (N,), units of y), ``amplitude`` (m,) and ``offset``."""

    model: np.ndarray
    residual: np.ndarray
    amplitude: np.ndarray
    offset: float


def fit_modes(y: np.ndarray, dt: float, freq_rad_s, damping, start: int = 0) -> ModalFit:
    """Least-squares amplitudes of the modes (ωᵢ, ζᵢ) in ``y`` (module docstring); a mode with a NaN
    frequency gets a NaN amplitude and no column, a NaN damping is taken as 0. ``start``: the amplitudes
    from the samples from there on only (a clipped record's part after its last clipped sample, which is
    what the method fitted); the model and residual still cover every sample."""
    y = np.asarray(y, float)
    w = np.asarray(freq_rad_s, float)
    z = np.nan_to_num(np.asarray(damping, float), nan=0.0)
    ok = np.isfinite(w)
    t = np.arange(y.size) * dt
    env = np.exp(-np.outer(t, z[ok] * w[ok]))
    wd = w[ok] * np.sqrt(np.clip(1 - z[ok] ** 2, 0.0, None))
    V = np.hstack([np.ones((y.size, 1)), env * np.cos(np.outer(t, wd)), env * np.sin(np.outer(t, wd))])
    coef = scipy.linalg.lstsq(V[start:], y[start:], lapack_driver="gelsd")[0]
    k = int(ok.sum())
    amplitude = np.full(w.size, np.nan)
    amplitude[ok] = np.hypot(coef[1:1 + k], coef[1 + k:])
    model = V @ coef
    return ModalFit(model, y - model, amplitude, float(coef[0]))
