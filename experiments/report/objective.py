"""The tuning objective (shared by the tuning command and a sweep's identify jobs): how far a method is from
the Cramér–Rao bound, with a price on failures.

For one cell (noise level, record length) with summary rows per mode (``experiments.report.summary``):

    J_cell = log10( median_n RMSE_n / CRLB_n ) + penalty · f_cell

where the median runs over the modes that delivered at least one converged replicate (RMSE over the
converged replicates only), and f_cell is the cell's failure rate, the mean over modes of each mode's share
of failed replicates. A cell where nothing converged gets J = log10(FAILED_RATIO) + penalty. Over several
cells, J = mean_cells J_cell. The logarithm puts a cell at 10 µg (RMSE/CRLB ~ 1e6 for the paper's filters)
and one at 1000 µg (~1e4) on one scale, so neither drowns the other; ``penalty`` = 4 makes failing every
replicate cost four decades of RMSE/CRLB (a 25 % failure rate costs one decade), so the search cannot win by
giving up on the hard modes and reporting the easy ones.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from experiments.report.tracking_metrics import DIVERGED_REL, TAIL, TOL, converged_from, sample_index

__all__ = ["FAILED_RATIO", "DEFAULT_PENALTY", "FAILED_REL", "TRACK_PENALTY", "cell_objective", "mode_failed",
           "objective", "track_objective"]

FAILED_RATIO = 1e12         # RMSE/CRLB charged to a cell where no mode converged in any replicate
DEFAULT_PENALTY = 4.0       # decades of RMSE/CRLB per unit failure rate


def cell_objective(summary: pd.DataFrame, penalty: float = DEFAULT_PENALTY) -> dict[str, float]:
    """J_cell of one (method, cell) summary (one row per mode). Returns the parts and ``value``."""
    ratio = summary["rmse_over_crlb"].to_numpy(float)
    delivered = ratio[np.isfinite(ratio)]
    median = float(np.median(delivered)) if delivered.size else FAILED_RATIO
    failure = float(summary["failure_rate"].to_numpy(float).mean())
    return {"median_rmse_over_crlb": median, "failure_rate": failure,
            "value": float(np.log10(median) + penalty * failure)}


def objective(summary: pd.DataFrame, penalty: float = DEFAULT_PENALTY) -> dict[str, float]:
    """J over every cell of a summary table (columns noise_ug, n_samples, mode, rmse_over_crlb,
    failure_rate): the mean of the cells' J_cell; also per-cell parts as ``cell<i>_*`` entries."""
    if summary.empty:
        raise ValueError("objective of an empty summary: no cell was scored")
    out: dict[str, float] = {}
    values = []
    for (noise, n), cell in summary.groupby(["noise_ug", "n_samples"], sort=True):
        parts = cell_objective(cell, penalty)
        values.append(parts["value"])
        tag = f"noise{noise:g}ug_n{n}"
        out.update({f"{tag}_{k}": v for k, v in parts.items()})
    out["value"] = float(np.mean(values))
    return out


# The tracking objective (``python -m experiments.tuning.tune tuning=track_<tracker>``). For one tracking
# cell (schedule, excitation, noise, duration) with R records:
#
#     J_cell = log10( median_r e_r ) + penalty · f_cell
#
# e_r is record r's median tracking error over time and modes relative to ω after the first convergence of
# every mode (``tracking_metrics.score_track``'s err_rel_median); a record that never held every mode within
# 1 % gives its late error instead (the median over the second half of the record, err_rel_median_late), so
# the search still sees a slope. f_cell is the share of (record, mode) pairs that failed: the mode never held
# within 1 % of the truth for HOLD_S, or it diverged (median error over the last 10 % of the record above
# 10 %), or the tracker raised. A cell with no finite e_r gets log10(FAILED_REL) + penalty. Over several
# cells, J = mean_cells J_cell. penalty = 2 makes losing every mode cost two decades of error (0.1 % -> 10 %).

FAILED_REL = 10.0           # relative error charged to a tracking cell where no record gave a finite error
TRACK_PENALTY = 2.0


def mode_failed(t_s, frequencies, truth: np.ndarray, dt_s: float) -> np.ndarray:
    """(m,) bool: per mode, never within 1 % of the truth for HOLD_S, or diverged over the record's tail."""

    t_s = np.asarray(t_s, dtype=float)
    w = truth[sample_index(t_s, dt_s, truth.shape[0])]
    rel = np.abs(np.asarray(frequencies, dtype=float) - w) / w
    rel = np.where(np.isfinite(rel), rel, np.inf)
    tail = t_s >= t_s[0] + (1 - TAIL) * (t_s[-1] - t_s[0])
    out = np.empty(truth.shape[1], dtype=bool)
    for i in range(truth.shape[1]):
        never = not np.isfinite(converged_from(t_s, rel[:, i] <= TOL, float(t_s[0])))
        out[i] = never or bool(np.median(rel[tail, i]) > DIVERGED_REL)
    return out


def track_objective(rows: pd.DataFrame, penalty: float = TRACK_PENALTY) -> dict[str, float]:
    """J over the records of a tracking study: ``rows`` has one row per (cell, record) with columns
    ``cell``, ``error`` (e_r, NaN for a failed record) and ``failed_share`` (the record's share of failed
    modes). Returns ``value`` and per-cell ``<cell>_median_error``, ``<cell>_failure_rate``, ``<cell>_value``."""
    if rows.empty:
        raise ValueError("objective of an empty table: no record was scored")
    out: dict[str, float] = {}
    values = []
    for cell, g in rows.groupby("cell", sort=True):
        err = g["error"].to_numpy(float)
        err = err[np.isfinite(err) & (err > 0)]
        median = float(np.median(err)) if err.size else FAILED_REL
        failure = float(g["failed_share"].mean())
        value = float(np.log10(median) + penalty * failure)
        values.append(value)
        out.update({f"{cell}_median_error": median, f"{cell}_failure_rate": failure, f"{cell}_value": value})
    out["value"] = float(np.mean(values))
    return out
