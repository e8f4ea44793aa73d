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

__all__ = ["FAILED_RATIO", "DEFAULT_PENALTY", "cell_objective", "objective"]

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
