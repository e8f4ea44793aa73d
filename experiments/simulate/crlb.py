"""Cramér–Rao lower bound for the frequencies of damped sinusoids in white Gaussian noise (docs/physics.md §4).

Model of the noise-free record, t_k = k·Δt:  μ(t) = Σᵢ aᵢ e^(−ζᵢωᵢt) cos(ωᵢ rᵢ t + φᵢ), rᵢ = √(1−ζᵢ²),
with 4 unknowns per mode (aᵢ, φᵢ, ωᵢ, ζᵢ) and, optionally, a constant offset. Fisher information
J = GᵀG/σ², G the N × p Jacobian of μ; the bound is √[J⁻¹]ωω.

No kept library computes this bound, so it is written here. J is badly conditioned for short records
(cond of the column-scaled G ≈ 1e9 at N = 20), so the columns are scaled and J⁻¹ is formed from the SVD of
the scaled G, which squares singular values instead of the condition number.
"""

from __future__ import annotations

import numpy as np


def signal_jacobian(freq_rad_s, damping, amplitude, phase, t, *, offset: bool = False) -> np.ndarray:
    """∂μ/∂(a, φ, ω, ζ) for each mode (columns grouped per mode, in that order), plus ∂μ/∂offset if asked."""
    t = np.asarray(t, dtype=float)
    cols = []
    for a, phi, w, z in zip(amplitude, phase, freq_rad_s, damping, strict=True):
        r = np.sqrt(1.0 - z**2)
        e = np.exp(-z * w * t)
        c = np.cos(w * r * t + phi)
        s = np.sin(w * r * t + phi)
        cols += [e * c,                                   # ∂/∂a
                 -a * e * s,                              # ∂/∂φ
                 a * e * t * (-z * c - r * s),            # ∂/∂ω
                 a * e * t * (-w * c + (w * z / r) * s)]  # ∂/∂ζ
    if offset:
        cols.append(np.ones_like(t))
    return np.column_stack(cols)


def crlb_std(freq_rad_s, damping, amplitude, phase, n_samples: int, dt_s: float, noise_std: float,
             *, offset: bool = False) -> np.ndarray:
    """CRLB standard deviation (rad/s) of each frequency, for a record of ``n_samples`` at ``dt_s``.

    Parameters
    ----------
    freq_rad_s, damping, amplitude, phase : array_like, shape (m,)
        The true modal parameters (amplitudes in the units of the record, e.g. m/s²).
    noise_std : float
        1σ of the white measurement noise, same units as the amplitudes. The bound scales linearly with it.
    offset : bool
        Also treat a constant sensor bias as unknown.

    Returns
    -------
    ndarray, shape (m,)
    """
    t = np.arange(int(n_samples)) * float(dt_s)
    G = signal_jacobian(freq_rad_s, damping, amplitude, phase, t, offset=offset)
    norms = np.linalg.norm(G, axis=0)
    norms[norms == 0] = 1.0
    _, s, vt = np.linalg.svd(G / norms, full_matrices=False)
    if s[-1] <= s[0] * np.finfo(float).eps * G.shape[0]:
        return np.full(len(freq_rad_s), np.inf)          # not identifiable at all from this record
    cov_scaled = (vt.T / s**2) @ vt                      # (GsᵀGs)⁻¹ = V S⁻² Vᵀ
    idx = 4 * np.arange(len(freq_rad_s)) + 2
    var = np.diag(cov_scaled)[idx] / norms[idx] ** 2
    return float(noise_std) * np.sqrt(var)
