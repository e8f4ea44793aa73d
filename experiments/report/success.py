"""Success of a replicate: did the method land on the truth, or in another basin (a local minimum)?

A mode succeeds when the method says it converged, its estimate is finite and

    |ω̂ᵢ − ωᵢ| ≤ tolᵢ = min( max(5 σᵢ, 0.5 % · ωᵢ), ½ dᵢ )

with σᵢ the Cramér–Rao std of the cell with the sensor offset unknown and dᵢ the distance to the nearest other
true mode. An efficient estimator strays beyond 5 σ with probability 6·10⁻⁷; a mode closer to its neighbour
than half-way, or stuck at a prior that is several percent off, fails. The 0.5 % floor keeps a mode that the
record barely resolves (σ large) from being judged against noise, and the ½ dᵢ cap keeps "the neighbour's
frequency" from ever counting as success. A replicate succeeds when every mode does.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["SIGMAS", "REL_FLOOR", "tolerance", "mode_success", "replicate_success", "success_rates"]

SIGMAS = 5.0
REL_FLOOR = 0.005


def tolerance(true_rad_s: np.ndarray, crlb_offset_std: np.ndarray) -> np.ndarray:
    """tolᵢ of the module docstring for one cell's modes."""
    w = np.asarray(true_rad_s, dtype=float)
    gaps = np.abs(w[:, None] - w[None, :])
    np.fill_diagonal(gaps, np.inf)
    return np.minimum(np.maximum(SIGMAS * np.asarray(crlb_offset_std, dtype=float), REL_FLOOR * w),
                      0.5 * gaps.min(axis=1))


def mode_success(true_rad_s, crlb_offset_std, estimate, converged) -> np.ndarray:
    """Per mode: converged, finite and within tolᵢ of the truth."""
    est = np.asarray(estimate, dtype=float)
    ok = np.asarray(converged, dtype=bool) & np.isfinite(est)
    err = np.abs(np.where(ok, est, np.inf) - np.asarray(true_rad_s, dtype=float))
    return ok & (err <= tolerance(true_rad_s, crlb_offset_std))


def replicate_success(results: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """One row per (``by`` …, replicate) of a per-replicate results table with a boolean ``success``.

    ``by`` names a cell and a method (e.g. method, noise_ug, n_samples and the scenario axes); the modes of a
    replicate are the rows sharing those values and ``replicate``.
    """
    keys = [*by, "replicate"]
    rows = []
    for key, g in results.groupby(keys, sort=True, dropna=False):
        g = g.sort_values("mode")
        ok = mode_success(g["true_rad_s"], g["crlb_offset_std_rad_s"], g["estimate_rad_s"], g["converged"])
        rows.append((*key, bool(ok.all()), bool(g["converged"].all())))
    return pd.DataFrame(rows, columns=[*keys, "success", "converged"])


def success_rates(results: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Per ``by`` group: replicates, success rate and not-converged rate."""
    reps = replicate_success(results, by)
    return (reps.groupby(by, sort=True, dropna=False)
            .agg(replicates=("success", "size"), success_rate=("success", "mean"),
                 not_converged_rate=("converged", lambda c: 1.0 - c.mean()))
            .reset_index())
