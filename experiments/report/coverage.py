"""Is a method's reported 1σ honest? Coverage of the error by ±1σ and ±2σ, and the median |error|/σ.

A method that reports a std σ̂ᵢ with each estimate ω̂ᵢ claims that the error eᵢ = ω̂ᵢ − ω is about
N(0, σ̂ᵢ²). If it is, the standardised error zᵢ = eᵢ/σ̂ᵢ is standard normal, so

    P(|z| ≤ 1) = erf(1/√2) = 0.683,   P(|z| ≤ 2) = erf(2/√2) = 0.954,   median |z| = Φ⁻¹(0.75) = 0.674.

Coverage well below these means the std is understated (the errors, bias included, are larger than the
method says); well above, overstated (conservative). "Well" means a binomial test rejects the ideal share
at the 0.1 % level and the share misses it by more than 10 points. Only converged replicates with a finite,
positive std count; a method that reports no std (NaN) gets NaN coverage.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from experiments.simulate.scenarios import AXES

__all__ = ["IDEAL_1STD", "IDEAL_2STD", "IDEAL_MEDIAN_Z", "ALPHA", "MIN_GAP", "FEW", "COLUMNS", "coverage", "verdict",
           "method_coverage", "coverage_table", "honesty_lines"]

IDEAL_1STD = float(stats.norm.cdf(1) - stats.norm.cdf(-1))      # 0.6827
IDEAL_2STD = float(stats.norm.cdf(2) - stats.norm.cdf(-2))      # 0.9545
IDEAL_MEDIAN_Z = float(stats.norm.ppf(0.75))                    # 0.6745
# A coverage is called off when a binomial test rejects the ideal at this level *and* it misses by more than
# MIN_GAP (replicates of one record share a noise draw across modes, so they are not quite independent, and
# a few-point miss says nothing useful either way).
ALPHA = 1e-3
MIN_GAP = 0.10
FEW = 20        # fewer (replicate, mode) pairs than this: say the evidence is weak
COLUMNS = ["n_with_std", "coverage_1std", "coverage_2std", "median_abs_err_over_std"]


def coverage(errors, stds) -> dict[str, float]:
    """Coverage of ``errors`` by the reported ``stds`` (same shape; NaN or non-positive std is skipped).

    Returns ``n_with_std`` (replicates counted), ``coverage_1std`` = share with |e| ≤ σ̂, ``coverage_2std``
    = share with |e| ≤ 2σ̂, and ``median_abs_err_over_std`` = median |e|/σ̂; the last three NaN when no
    replicate has a usable std.
    """
    e = np.asarray(errors, dtype=float).ravel()
    s = np.asarray(stds, dtype=float).ravel()
    ok = np.isfinite(e) & np.isfinite(s) & (s > 0)
    z = np.abs(e[ok]) / s[ok]
    if z.size == 0:
        return {"n_with_std": 0, "coverage_1std": np.nan, "coverage_2std": np.nan,
                "median_abs_err_over_std": np.nan}
    return {"n_with_std": int(z.size), "coverage_1std": float(np.mean(z <= 1)),
            "coverage_2std": float(np.mean(z <= 2)), "median_abs_err_over_std": float(np.median(z))}


def _off(share: float, n: int, ideal: float) -> bool:
    """Is ``share`` of ``n`` pairs significantly (ALPHA) and materially (MIN_GAP) off the ideal share?"""
    k = int(round(share * n))
    return abs(share - ideal) > MIN_GAP and stats.binomtest(k, n, ideal).pvalue < ALPHA


def verdict(row) -> str:
    """One phrase on a method's pooled coverage: consistent, understated, overstated or no std."""
    n = int(row["n_with_std"])
    if n == 0 or not np.isfinite(row["coverage_1std"]):
        return "reports no std"
    c1, c2 = row["coverage_1std"], row["coverage_2std"]
    if (_off(c1, n, IDEAL_1STD) and c1 < IDEAL_1STD) or (_off(c2, n, IDEAL_2STD) and c2 < IDEAL_2STD):
        return "std understated (errors larger than it claims)"
    if _off(c1, n, IDEAL_1STD):
        return "std overstated (conservative)"
    return "consistent with its errors" + (f" (only {n} pairs: weak evidence)" if n < FEW else "")


def method_coverage(results: pd.DataFrame, cells: pd.DataFrame | None = None) -> pd.DataFrame:
    """Coverage per method pooled over converged replicates, with a verdict.

    ``cells``, if given, is a table with columns method, noise_ug, n_samples, mode restricting the pool (the
    identifiable cells, say); the result has one row per method of ``results`` in either case.
    """
    res = results
    if cells is not None:
        keys = ["method", "noise_ug", "n_samples", *[a for a in AXES if a in cells and a in res], "mode"]
        res = res.merge(cells[keys].drop_duplicates(), how="inner")
    ok = res[res["converged"].astype(bool)]
    rows = []
    for method in sorted(results["method"].unique()):
        g = ok[ok["method"] == method]
        rows.append({"method": method, **coverage(g["error_rad_s"], g["std_rad_s"])})
    out = pd.DataFrame(rows, columns=["method", *COLUMNS])
    out["verdict"] = [verdict(r) for _, r in out.iterrows()]
    return out


def coverage_table(results: pd.DataFrame, summary: pd.DataFrame) -> pd.DataFrame:
    """Per method, coverage pooled over the identifiable (mode, cell) pairs of ``summary`` and over all."""
    ident = method_coverage(results, summary[summary["identifiable"].astype(bool)])
    every = method_coverage(results)
    table = pd.concat([ident.assign(cells="identifiable"), every.assign(cells="all")], ignore_index=True)
    table = table.sort_values(["method", "cells"], ascending=[True, False], kind="stable")
    return table[["method", "cells", *COLUMNS, "verdict"]].reset_index(drop=True)


def _numbers(row) -> str:
    return (f"{100 * row['coverage_1std']:.0f} % of errors within ±1σ (ideal 68 %), "
            f"{100 * row['coverage_2std']:.0f} % within "
            f"±2σ (ideal 95 %), median |error|/σ {row['median_abs_err_over_std']:.3g} (ideal 0.67), over "
            f"{int(row['n_with_std'])} converged (replicate, mode) pairs")


def honesty_lines(table: pd.DataFrame) -> list[str]:
    """One Markdown bullet per method of :func:`coverage_table`, judged on identifiable cells."""
    lines = []
    for method, g in table.groupby("method", sort=True):
        ident = g[g["cells"] == "identifiable"].iloc[0]
        every = g[g["cells"] == "all"].iloc[0]
        if every["verdict"] == "reports no std":
            lines.append(f"- {method} reports no std: coverage not applicable.")
        elif ident["n_with_std"] == 0:
            lines.append(f"- {method}: no converged estimate with a std in an identifiable cell; over all cells "
                         f"{_numbers(every)}.")
        elif ident["verdict"].startswith("consistent"):
            lines.append(f"- {method}: std {ident['verdict']} on identifiable cells: {_numbers(ident)}.")
        else:
            lines.append(f"- **{method}: its reported std is not honest** ({ident['verdict']}) on identifiable "
                         f"cells: {_numbers(ident)}.")
    return lines
