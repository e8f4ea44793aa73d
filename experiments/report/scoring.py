"""Scoring one replicate's Estimate against the truth, as rows of the per-replicate results table.

One row per (replicate, mode). A mode is *identifiable* in a cell when its CRLB std is at most 1 % of its
frequency and at most 10 % of the distance to the nearest other mode (docs/physics.md §4); elsewhere the local
bound means little and the tables report failure rates rather than efficiency.
"""

from __future__ import annotations

import numpy as np

COLUMNS = ["method", "noise_ug", "n_samples", "replicate", "mode", "prior_rad_s", "true_rad_s",
           "estimate_rad_s", "std_rad_s", "error_rad_s", "crlb_std_rad_s", "crlb_offset_std_rad_s", "identifiable",
           "converged", "iterations", "runtime_s", "message"]


def identifiable(true_rad_s: np.ndarray, crlb_std_rad_s: np.ndarray) -> np.ndarray:
    true_rad_s = np.asarray(true_rad_s, dtype=float)
    gaps = np.abs(true_rad_s[:, None] - true_rad_s[None, :])
    np.fill_diagonal(gaps, np.inf)
    nearest = gaps.min(axis=1)
    return (crlb_std_rad_s <= 0.01 * true_rad_s) & (crlb_std_rad_s <= 0.1 * nearest)


def replicate_rows(method: str, noise_ug: float, n_samples: int, replicate: int, prior, truth_freq,
                   crlb, crlb_offset, estimate, runtime_s: float) -> list[dict]:
    """Rows for one replicate. The i-th prior is scored against the i-th true mode (modes sorted by
    frequency); a method that returned NaN, or said it did not converge, counts as a failure."""
    ident = identifiable(truth_freq, crlb)
    # A bank of independent loops (pll) may lock some modes and not others: it says so per mode.
    converged = np.asarray(estimate.converged_per_mode, dtype=bool)
    rows = []
    for i in range(len(prior)):
        est = float(estimate.frequencies[i])
        rows.append({
            "method": method, "noise_ug": float(noise_ug), "n_samples": int(n_samples),
            "replicate": int(replicate), "mode": i + 1, "prior_rad_s": float(prior[i]),
            "true_rad_s": float(truth_freq[i]), "estimate_rad_s": est, "std_rad_s": float(estimate.std[i]),
            "error_rad_s": est - float(truth_freq[i]), "crlb_std_rad_s": float(crlb[i]),
            "crlb_offset_std_rad_s": float(crlb_offset[i]),
            "identifiable": bool(ident[i]),
            "converged": bool(converged[i] and np.isfinite(est)),
            "iterations": int(estimate.iterations), "runtime_s": float(runtime_s),
            "message": " ".join(str(estimate.message).split()),     # one line per row in the CSV
        })
    return rows
