"""Monte-Carlo statistics of a per-replicate results table, per (method, noise, record length, mode).

Bias, std and RMSE are over the replicates the method reported as converged with a finite estimate; the
others count as failures. RMSE/CRLB is the efficiency yardstick (1 = at the bound); it is reported for every
cell, but it means something only where the mode is identifiable (see experiments.report.scoring). Two bounds:
``crlb`` with the sensor offset known (docs/physics.md §4) and ``crlb_offset`` with it unknown, which is what a
method that does not assume a calibrated sensor faces; on short records the second is several times larger
for the slow mode 1.

Each row also says how honest the method's own 1σ is (experiments.report.coverage): the share of converged
replicates whose error lies within ±1σ and ±2σ of the reported std (ideal 68 % / 95 %) and the median
|error|/σ (ideal 0.67); NaN where the method reports no std (fft).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from experiments.report.coverage import COLUMNS as COVERAGE_COLUMNS
from experiments.report.coverage import coverage
from experiments.simulate.scenarios import AXES

__all__ = ["KEYS", "YARDSTICK_COLUMNS", "cell_keys", "summarize", "attach_yardstick", "job_metrics"]

KEYS = ["method", "noise_ug", "n_samples", "mode"]


def cell_keys(table: pd.DataFrame) -> list[str]:
    """The columns that name a cell: noise, length and the scenario axes present in the table."""
    return ["noise_ug", "n_samples", *[a for a in AXES if a in table.columns]]


STATS_COLUMNS = ["true_rad_s", "replicates", "failures", "failure_rate", "bias_rad_s", "std_rad_s", "rmse_rad_s",
                 "crlb_std_rad_s", "crlb_offset_std_rad_s", "rmse_over_crlb", "rmse_over_crlb_offset",
                 "identifiable", "median_runtime_s", *COVERAGE_COLUMNS]


def _stats(conv, est, err, std, crlb, crlb_offset, true, identifiable, replicate, runtime) -> dict:
    """The statistics of one (method, cell, mode) group from its rows' columns (numpy arrays, in table order)."""
    ok = conv & np.isfinite(est)
    err = err[ok]
    crlb0, crlb_off = float(crlb[0]), float(crlb_offset[0])
    n, n_ok = len(conv), int(ok.sum())
    rmse = float(np.sqrt(np.mean(err**2))) if n_ok else np.nan
    first = np.unique(replicate, return_index=True)[1]      # drop_duplicates("replicate"): each one's first row
    return {
        "true_rad_s": float(true[0]),
        "replicates": int(n),
        "failures": int(n - n_ok),
        "failure_rate": float(1 - n_ok / n),
        "bias_rad_s": float(np.mean(err)) if n_ok else np.nan,
        "std_rad_s": float(np.std(err, ddof=1)) if n_ok > 1 else np.nan,
        "rmse_rad_s": rmse,
        "crlb_std_rad_s": crlb0,
        "crlb_offset_std_rad_s": crlb_off,
        "rmse_over_crlb": rmse / crlb0 if n_ok and crlb0 > 0 else np.nan,
        "rmse_over_crlb_offset": rmse / crlb_off if n_ok else np.nan,
        "identifiable": bool(identifiable[0]),
        "median_runtime_s": float(np.median(runtime[first])),
        **coverage(err, std[ok]),
    }


def summarize(results: pd.DataFrame) -> pd.DataFrame:
    """One row per (method, noise_ug, n_samples, [scenario axes,] mode), sorted. A cell without an axis
    that other cells of the table have keeps NaN there (``dropna=False``).

    pandas finds the groups (``groupby``, sorted); each group's statistics come from numpy slices of the
    columns (a pandas ``apply`` with a Series per group cost 16 ms on a one-cell table: the MLflow step
    summarises each of a grid's jobs)."""
    if results.empty:
        return pd.DataFrame(columns=[*KEYS, *STATS_COLUMNS])
    keys = ["method", *cell_keys(results), "mode"]
    codes = results.groupby(keys, sort=True, dropna=False).ngroup().to_numpy()     # the sorted groups' numbers
    order = np.argsort(codes, kind="stable")                 # each group's rows together, in table order
    bounds = np.r_[np.flatnonzero(np.r_[True, np.diff(codes[order]) != 0]), order.size]
    cols = [results[c].to_numpy(t)[order] for c, t in (
        ("converged", bool), ("estimate_rad_s", float), ("error_rad_s", float), ("std_rad_s", float),
        ("crlb_std_rad_s", float), ("crlb_offset_std_rad_s", float), ("true_rad_s", float),
        ("identifiable", bool), ("replicate", None), ("runtime_s", float))]
    rows = [_stats(*(c[lo:hi] for c in cols)) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)]
    names = results[keys].iloc[order[bounds[:-1]]].reset_index(drop=True)       # each group's keys, its first row's
    return pd.concat([names, pd.DataFrame(rows, columns=STATS_COLUMNS)], axis=1)


# The columns the Bayesian yardstick (experiments/simulate/yardstick.py) adds, after rmse_over_crlb_offset.
YARDSTICK_COLUMNS = ["van_trees_std_rad_s", "posterior_mean_rmse_rad_s", "posterior_mean_mc_rad_s",
                     "rmse_over_posterior_mean"]


def attach_yardstick(summary: pd.DataFrame, yardstick: pd.DataFrame) -> pd.DataFrame:
    """The summary with the yardstick of its plain cells, per (noise, length, mode): the van Trees bound
    (every cell), the posterior mean's RMSE on the cell's records and its Monte-Carlo error, and the method's
    RMSE over it, beside RMSE/CRLB. The posterior mean is the yardstick of every mode of a cell where the CRLB
    of some mode is loose (the modes share the record: the prior that pins one sharpens the others, e.g.
    mode 4 at 20 samples, whose RMSE is far below its CRLB); elsewhere NaN. Scenario cells get NaN."""
    y = yardstick.copy()
    loose = y.groupby(["noise_ug", "n_samples"])["loose"].transform("any").astype(bool)
    for col in ("posterior_mean_rmse_rad_s", "posterior_mean_mc_rad_s"):
        y[col] = y[col].where(loose)
    y = y[["noise_ug", "n_samples", "mode", *YARDSTICK_COLUMNS[:3]]]
    scenario = [c for c in cell_keys(summary)[2:]]
    plain = summary[scenario].isna().all(axis=1) if scenario else pd.Series(True, index=summary.index)
    out = summary.drop(columns=[c for c in YARDSTICK_COLUMNS if c in summary.columns])
    merged = out.merge(y, on=["noise_ug", "n_samples", "mode"], how="left")
    merged.loc[~plain.to_numpy(), YARDSTICK_COLUMNS[:3]] = np.nan
    merged["rmse_over_posterior_mean"] = merged["rmse_rad_s"] / merged["posterior_mean_rmse_rad_s"]
    cols = list(out.columns)
    at = cols.index("rmse_over_crlb_offset") + 1
    return merged[cols[:at] + YARDSTICK_COLUMNS + cols[at:]]


def job_metrics(summary: pd.DataFrame) -> dict[str, float]:
    """Flat MLflow metrics of one (method, cell) job: per-mode RMSE, bias, RMSE/CRLB, failure rate."""
    m = {}
    for row in summary.itertuples(index=False):
        for name in ("rmse_rad_s", "bias_rad_s", "rmse_over_crlb", "failure_rate"):
            m[f"mode{row.mode}_{name}"] = getattr(row, name)
    if not summary.empty:
        m["failure_rate"] = float(summary["failure_rate"].max())
        m["median_runtime_s"] = float(summary["median_runtime_s"].iloc[0])
    return m
