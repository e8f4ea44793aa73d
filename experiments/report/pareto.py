"""Accuracy against cost: RMSE/CRLB against time per fit, one point per method per cell class.

Cell classes split a grid's cells in four: short or long records × low or high noise (thresholds below).
Per method and class: the median RMSE/CRLB over the identifiable (mode, cell) pairs where the method
fails in at most half the replicates (as in the RMSE figures), the mean failure rate over all identifiable
pairs (so that a method that is accurate when it answers but rarely answers is seen), and the median time
per fit over the class's cells. The winner of a class is the method with the lowest median RMSE/CRLB
among those failing ≤ 10 % of identifiable pairs on average; the Pareto front joins the methods that no
other method beats on both accuracy and time.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from experiments.report import plots  # noqa: E402

__all__ = ["SHORT_BELOW_SAMPLES", "LOW_NOISE_UG", "MAX_MEAN_FAILURE", "CLASSES", "cell_class", "class_table",
           "pareto_front", "figure", "winners_text"]

# A record is "short" below 128 samples (2.56 s at Δt = 0.02 s: less than the 2π/1.76 rad/s = 3.6 s that
# separates modes 2 and 3 by one Fourier bin); noise is "low" up to 100 µg (the paper's grid centre).
SHORT_BELOW_SAMPLES = 128
LOW_NOISE_UG = 100.0
MAX_MEAN_FAILURE = 0.1
CLASSES = ["short, low noise", "short, high noise", "long, low noise", "long, high noise"]


def cell_class(n_samples, noise_ug) -> np.ndarray:
    n, noise = np.asarray(n_samples), np.asarray(noise_ug)
    length = np.where(n < SHORT_BELOW_SAMPLES, "short", "long")
    level = np.where(noise <= LOW_NOISE_UG, "low noise", "high noise")
    return np.char.add(np.char.add(length.astype(str), ", "), level.astype(str))


def class_table(summary: pd.DataFrame) -> pd.DataFrame:
    """One row per (class, method): median RMSE/CRLB, mean failure rate, median ms per fit, pairs."""
    s = summary.assign(cell_class=cell_class(summary["n_samples"], summary["noise_ug"]))
    rows = []
    for (cls, method), g in s.groupby(["cell_class", "method"], sort=True):
        ident = g[g["identifiable"]]
        usable = ident[ident["failure_rate"] <= plots.MAX_FAILURE_RATE].dropna(subset=["rmse_over_crlb"])
        per_cell = g.drop_duplicates(["noise_ug", "n_samples"])["median_runtime_s"]
        rows.append({"cell_class": cls, "method": method,
                     "median_rmse_over_crlb": float(usable["rmse_over_crlb"].median()) if len(usable) else np.nan,
                     "mean_failure_rate": float(ident["failure_rate"].mean()) if len(ident) else np.nan,
                     "median_ms_per_fit": 1e3 * float(per_cell.median()),
                     "identifiable_pairs": int(len(ident)), "pairs_scored": int(len(usable))})
    table = pd.DataFrame(rows)
    if table.empty:
        return table
    table["winner"] = False
    for _, g in table.groupby("cell_class"):
        ok = g[(g["mean_failure_rate"] <= MAX_MEAN_FAILURE) & g["median_rmse_over_crlb"].notna()]
        if len(ok):
            table.loc[ok["median_rmse_over_crlb"].idxmin(), "winner"] = True
    order = {c: i for i, c in enumerate(CLASSES)}
    return table.sort_values(["cell_class", "median_rmse_over_crlb"], key=lambda c: c.map(order)
                             if c.name == "cell_class" else c).reset_index(drop=True)


def pareto_front(points: pd.DataFrame) -> pd.DataFrame:
    """The points no other point beats in both time and RMSE/CRLB, sorted by time."""
    p = points.sort_values(["median_ms_per_fit", "median_rmse_over_crlb"])
    best, keep = np.inf, []
    for idx, row in p.iterrows():
        if row["median_rmse_over_crlb"] < best:
            best = row["median_rmse_over_crlb"]
            keep.append(idx)
    return p.loc[keep]


def figure(table: pd.DataFrame, stem: Path) -> list[Path]:
    """Four panels (one per cell class): RMSE/CRLB against ms per fit, a labelled point per method."""
    classes = [c for c in CLASSES if c in set(table["cell_class"])]
    cols = min(len(classes), 2)
    rows = -(-len(classes) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 4.6 * rows), squeeze=False)
    for ax in axes.flat[len(classes):]:
        ax.set_visible(False)
    for ax, cls in zip(axes.flat, classes, strict=False):
        g = table[(table["cell_class"] == cls)].dropna(subset=["median_rmse_over_crlb"])
        g = g[g["median_ms_per_fit"] > 0].sort_values("median_ms_per_fit")
        names = []
        for row in g.itertuples():
            color, marker = plots._style(row.method)
            faint = row.mean_failure_rate > MAX_MEAN_FAILURE
            ax.scatter(row.median_ms_per_fit, row.median_rmse_over_crlb, color=color, marker=marker, s=48,
                       alpha=0.35 if faint else 1.0, zorder=3)
            if row.winner:
                ax.scatter(row.median_ms_per_fit, row.median_rmse_over_crlb, s=160, facecolors="none",
                           edgecolors="k", zorder=2)
            name = row.method + (f" ({row.mean_failure_rate:.0%} fail)" if faint else "")
            names.append((row.median_ms_per_fit, row.median_rmse_over_crlb, name, 0.5 if faint else 1.0))
        front = pareto_front(g[g["mean_failure_rate"] <= MAX_MEAN_FAILURE])
        if len(front) > 1:
            ax.step(front["median_ms_per_fit"], front["median_rmse_over_crlb"], where="post", color="k",
                    lw=0.8, ls="--", zorder=1)
        ax.axhline(1.0, color="k", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("median time per fit (ms)")
        ax.set_title(cls)
        ax.grid(True, which="both", alpha=0.3)
        plots.label_points(ax, names)
    for ax in axes[:, 0]:
        ax.set_ylabel("median RMSE/CRLB, identifiable pairs")
    fig.suptitle(f"Accuracy against cost per cell class (short < {SHORT_BELOW_SAMPLES} samples, low noise "
                 f"≤ {LOW_NOISE_UG:g} µg)\ndotted: the bound; dashed: Pareto front of methods failing "
                 f"≤ {MAX_MEAN_FAILURE:.0%}; faint: failing more; ringed: the class winner", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    return plots._save(fig, stem)


def winners_text(table: pd.DataFrame) -> str:
    """One line per class: its winner and the runner-up, with their numbers."""
    lines = []
    for cls in CLASSES:
        g = table[(table["cell_class"] == cls)]
        ok = g[(g["mean_failure_rate"] <= MAX_MEAN_FAILURE)].dropna(subset=["median_rmse_over_crlb"])
        if ok.empty:
            continue
        ok = ok.sort_values("median_rmse_over_crlb")
        parts = [f"{r.method} {r.median_rmse_over_crlb:.2f}× the bound at {r.median_ms_per_fit:.3g} ms"
                 for r in ok.head(3).itertuples()]
        lines.append(f"- {cls}: " + "; ".join(parts))
    return "\n".join(lines)
