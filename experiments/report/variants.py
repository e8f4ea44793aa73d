"""Method variants side by side (a method at the paper's options, tuned, ...): a grid's "tuning" outputs.

A grid naming several variants of one method (``akf`` and ``akf:tuned``, ``pem`` and ``pem:paper``) gets, per
such method, each variant's accuracy and failures per cell: the median RMSE/CRLB over the identifiable modes
where the variant fails in at most half the replicates (as in the RMSE figures), its worst-mode failure rate,
and the coverage of its std; beside it the header of each variant's config
(``configs/method/<method>_<variant>.yaml``), which for a tuned variant is the tuning study's provenance.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from experiments import paths
from experiments.report import plots  # noqa: E402

__all__ = ["ROOT", "METHOD_CONFIGS", "base_of", "table", "provenance", "figure"]

ROOT = paths.ROOT
METHOD_CONFIGS = paths.METHOD_CONFIGS


def base_of(label: str) -> str:
    return label.partition(":")[0]


def table(summary: pd.DataFrame) -> pd.DataFrame:
    """One row per (method, variant, cell) for methods with more than one variant in ``summary``."""
    s = summary.assign(base=summary["method"].map(base_of))
    n_variants = s.groupby("base")["method"].nunique()
    s = s[s["base"].isin(n_variants[n_variants > 1].index)]
    rows = []
    for (base, label, noise, n), g in s.groupby(["base", "method", "noise_ug", "n_samples"], sort=True):
        ident = g[g["identifiable"].astype(bool) & (g["failure_rate"] <= plots.MAX_FAILURE_RATE)]
        rows.append({"method": base, "variant": label, "noise_ug": noise, "n_samples": n,
                     "identifiable_modes": int(g["identifiable"].astype(bool).sum()),
                     "median_rmse_over_crlb": float(ident["rmse_over_crlb"].median()) if len(ident) else np.nan,
                     "worst_failure_rate": float(g["failure_rate"].max()),
                     "coverage_1std": float(g["coverage_1std"].mean()) if "coverage_1std" in g else np.nan})
    return pd.DataFrame(rows, columns=["method", "variant", "noise_ug", "n_samples", "identifiable_modes",
                                       "median_rmse_over_crlb", "worst_failure_rate", "coverage_1std"])


def provenance(labels) -> list[tuple[str, str]]:
    """(label, the comment header of its config file) for each variant label that names a config file."""
    out = []
    for label in sorted(set(labels)):
        base, _, variant = label.partition(":")
        path = METHOD_CONFIGS / (f"{base}_{variant}.yaml" if variant else f"{base}.yaml")
        if path.is_file():
            header = [line.lstrip("# ").rstrip() for line in path.read_text(encoding="utf-8").splitlines()
                      if line.startswith("#")]
            out.append((f"{label}: configs/method/{path.name}", "\n".join(header) or "(no header)"))
    return out


def figure(tab: pd.DataFrame, stem: Path) -> list[Path]:
    """Per method (panel): each variant's median RMSE/CRLB per cell; open markers where it fails > 10 %."""
    bases = sorted(tab["method"].unique())
    cells = tab[["noise_ug", "n_samples"]].drop_duplicates().sort_values(["n_samples", "noise_ug"])
    names = [f"{v:g} µg\n{n}" for v, n in zip(cells["noise_ug"], cells["n_samples"], strict=True)]
    index = {(v, n): i for i, (v, n) in enumerate(zip(cells["noise_ug"], cells["n_samples"], strict=True))}
    fig, axes = plt.subplots(len(bases), 1, figsize=(max(6.0, 0.55 * len(names) + 2.5), 3.2 * len(bases)),
                             squeeze=False, layout="constrained")
    for ax, base in zip(axes[:, 0], bases, strict=True):
        for label, g in tab[tab["method"] == base].groupby("variant", sort=True):
            color, marker = plots._style(label)
            x = [index[(v, n)] for v, n in zip(g["noise_ug"], g["n_samples"], strict=True)]
            y = g["median_rmse_over_crlb"].to_numpy(float)
            bad = g["worst_failure_rate"].to_numpy(float) > 0.1
            ax.plot(x, y, marker=marker, color=color, ls="none", ms=7, label=label, mfc=color)
            ax.plot(np.asarray(x)[bad], y[bad], marker=marker, color=color, ls="none", ms=7, mfc="white")
        ax.axhline(1.0, color="k", ls="--", lw=1)
        ax.set_yscale("log")
        ax.set_xticks(range(len(names)), names, fontsize=7)
        ax.set_ylabel("median RMSE/CRLB")
        ax.set_title(base, fontsize=10)
        ax.grid(True, which="major", axis="y", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    axes[-1, 0].set_xlabel("cell (noise 1σ, record length in samples)")
    fig.suptitle("Variants side by side: median RMSE/CRLB over identifiable modes (dashed: the bound)\n"
                 "open marker: fails in > 10 % of the replicates of its worst mode", fontsize=9)
    return plots._save(fig, stem)
