"""A line in the residual outside every mode's band: an unmodelled mode, fitted and set aside.

An unmodelled mode (the beam's next mode above the prior's band, a harmonic of a clipped or nonlinear
response) biases the modes the fit has: its projection on their Jacobian columns moves them. That bias is
deterministic and invisible in the residual (the normal equations make Jᵀε = 0), so no std, robust or not,
can cover it. The residual check sees the line itself (``extra["residual_check"]["peak_rad_s"]``): when it
stands above both the floor and its neighbouring bins (a line, not a hump of coloured noise) and lies
outside every prior frequency's search band, :func:`absorb` refits with one more mode started there and
reports the prior's modes only. ``extra["absorbed_line_rad_s"]`` gives the line's fitted frequency.
"""

from __future__ import annotations

import dataclasses

import numpy as np

# per-mode entries of the estimate's extra (and of its residual check) that follow the prior's modes
PER_MODE_EXTRA = ("damping", "damping_std", "identified", "white_noise_std")
PER_MODE_CHECK = ("robust_std_rad_s", "hac_std_rad_s", "spectral_std_rad_s")


def outside_bands(w: float, prior: np.ndarray, band: float | None, nyquist: float) -> bool:
    """Whether ω lies outside every search band prior·(1 + band)^±1 (and below 0.95 of Nyquist)."""
    if band is None or not 0 < w < 0.95 * nyquist:
        return False
    return bool(np.all((w < prior / (1 + band)) | (w > prior * (1 + band))))


def absorb(est, y: np.ndarray, dt: float, prior: np.ndarray, opts, identify_prior):
    """The estimate refitted with the residual's strongest line as an extra mode, when the residual check
    found a line (above its threshold) outside every mode's band and ``opts.absorb_lines``; otherwise
    ``est``. ``identify_prior(prior)`` runs the fit (the caller's, without this step) on another prior."""
    check = est.extra.get("residual_check")
    if (not opts.absorb_lines or check is None or check["white"]
            or not check["peak_over_floor"] > check["peak_threshold"]
            or not check["peak_over_neighbours"] > check["peak_threshold"]):     # a line, not coloured noise
        return est
    line = float(check["peak_rad_s"])
    if not outside_bands(line, prior, opts.frequency_band, np.pi / dt) or np.any(np.isclose(prior, line)):
        return est
    wider = np.sort(np.append(prior, line))
    keep = np.flatnonzero(~np.isclose(wider, line))
    refit = identify_prior(wider)
    if not refit.converged_per_mode[keep].any():
        return est
    extra = {key: (np.asarray(v)[keep] if key in PER_MODE_EXTRA and np.ndim(v) else v)
             for key, v in refit.extra.items()}
    if isinstance(extra.get("residual_check"), dict):
        extra["residual_check"] = {k: (np.asarray(v)[keep] if k in PER_MODE_CHECK else v)
                                   for k, v in extra["residual_check"].items()}
    fitted = refit.frequencies[np.setdiff1d(np.arange(wider.size), keep)][0]
    extra["absorbed_line_rad_s"] = float(fitted)
    message = (f"{refit.message}; a line at {line:.4g} rad/s outside every mode's band was fitted as an extra "
               f"mode ({fitted:.6g} rad/s, not reported)")
    return dataclasses.replace(refit, frequencies=refit.frequencies[keep], std=refit.std[keep],
                               converged_per_mode=refit.converged_per_mode[keep], extra=extra, message=message,
                               history=None)
