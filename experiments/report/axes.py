"""Figures and tables against a grid's scenario axes (experiments/simulate/scenarios.py).

- ``axis_<name>.png``: per mode, RMSE/CRLB (top) and failure rate (bottom) against one swept axis, methods as
  lines. Where another axis varies in the same cells, the curve is drawn at that axis' reference value (the
  paper's: prior scale 1, gap 1.76 rad/s, ζ = 0.005, …, or the nearest swept value), named in the title.
- ``basin.png``: the basin of attraction: the share of replicates in which a method lands on the truth
  (experiments.report.success) against the prior error, one panel per mode gap for the common error and
  one for the independent per-mode errors. The paper's "local minima are often encountered", quantified.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from experiments.io import markdown_table  # noqa: E402
from experiments.report.plots import MAX_FAILURE_RATE, _save  # noqa: E402
from experiments.report.plots import _style as _base_style  # noqa: E402
from experiments.report.success import success_rates  # noqa: E402
from experiments.report.summary import cell_keys  # noqa: E402
from experiments.simulate.scenarios import AXES  # noqa: E402

REFERENCE = {"prior_scale": 1.0, "prior_spread": 0.0, "damping": 0.005, "gap_rad_s": 1.76, "excitation": 1.0,
             "dt_s": 0.02, "bias_m_s2": 0.0, "measurement": "position"}
LABEL = {"prior_scale": "common prior factor c (prior = c · ω)",
         "prior_spread": "independent prior error s (prior = ω (1 + s u), u ~ U(−1, 1))",
         "damping": "damping ratio ζ", "gap_rad_s": "mode 2–3 gap (rad/s)", "excitation": "excitation scale",
         "dt_s": "sample interval Δt (s)", "bias_m_s2": "sensor bias (m/s²)", "measurement": "measurement",
         "ar1": "AR(1) coefficient φ of the noise", "unmodelled_mode": "unmodelled mode (× mode 4's amplitude)",
         "duffing": "Duffing frequency shift δ at release", "saturation": "clipping level (× peak)",
         "quantisation": "rounding step (× noise std)"}
REFERENCE.update({"ar1": 0.0, "unmodelled_mode": 0.0, "duffing": 0.0, "saturation": 1.0, "quantisation": 0.0})
BASIN_LEVEL = 0.9
VARIANT_MARKERS = "xP*hd+"


def _style(label: str) -> dict:
    """Line style of a method or a variant (``name:variant``: the method's colour, dashed, another marker)."""
    method, _, variant = label.partition(":")
    color, marker = _base_style(method)
    if variant:
        marker = VARIANT_MARKERS[sum(map(ord, variant)) % len(VARIANT_MARKERS)]
    return {"color": color, "marker": marker, "ls": "--" if variant else "-"}


def swept_axes(table: pd.DataFrame) -> list[str]:
    """The scenario axes that take more than one value in a summary/results table."""
    return [a for a in AXES if a in table.columns and table[a].dropna().nunique() > 1]


def _nearest(values, target):
    vals = pd.Series(values).dropna().unique()
    if isinstance(target, str) or vals.dtype == object:
        return target if target in vals else sorted(vals)[0]
    return vals[np.argmin(np.abs(vals.astype(float) - target))]


def slice_for(table: pd.DataFrame, axis: str) -> tuple[pd.DataFrame, list[str]]:
    """The rows where ``axis`` is set, the other varying cell keys held at their reference value."""
    sub = table[table[axis].notna()]
    held = []
    for other in cell_keys(table):
        if other == axis or other not in sub.columns:
            continue
        vals = sub[other]
        if vals.isna().any() and vals.notna().any():
            sub = sub[vals.isna()]               # cells of another block: keep those without the other axis
            continue
        if vals.nunique() > 1:
            ref = {"noise_ug": 1000.0, "n_samples": sub["n_samples"].max()}.get(other, REFERENCE.get(other))
            value = _nearest(vals, ref)
            sub = sub[sub[other] == value]
            held.append(f"{other} = {value:g}" if not isinstance(value, str) else f"{other} = {value}")
    return sub, held


def axis_figure(summary: pd.DataFrame, axis: str, stem: Path) -> list[Path]:
    """RMSE/CRLB and failure rate against one axis; a column per mode, methods as lines."""
    sub, held = slice_for(summary, axis)
    modes = sorted(sub["mode"].unique())
    fig, axs = plt.subplots(2, len(modes), figsize=(3.6 * len(modes), 6.2), squeeze=False, sharex="col")
    categorical = sub[axis].dtype == object
    for j, mode in enumerate(modes):
        sm = sub[sub["mode"] == mode]
        for method, g in sm.groupby("method", sort=True):
            g = g.sort_values(axis)
            x = g[axis].astype(str) if categorical else g[axis]
            style = _style(method)
            ok = g["failure_rate"] <= MAX_FAILURE_RATE
            axs[0][j].plot(x[ok], g.loc[ok, "rmse_over_crlb"], lw=1.3, label=method, **style)
            axs[1][j].plot(x, 100 * g["failure_rate"], lw=1.3, label=method, **style)
        axs[0][j].axhline(1.0, color="k", ls="--", lw=1)
        axs[0][j].set_yscale("log")
        axs[0][j].set_title(f"mode {mode}")
        axs[1][j].set_ylim(-3, 103)
        axs[1][j].set_xlabel(LABEL.get(axis, axis), fontsize=8)
        for ax in axs[:, j]:
            ax.grid(True, which="both", alpha=0.3)
    axs[0][0].set_ylabel("RMSE / CRLB")
    axs[1][0].set_ylabel("failure rate (%)")
    handles, labels = axs[1][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8)
    where = ", ".join(held) if held else "no other axis held"
    fig.suptitle(f"Against {axis} ({where}); RMSE/CRLB not drawn where > {MAX_FAILURE_RATE:.0%} fail; "
                 "dashed: the bound", fontsize=9)
    fig.tight_layout(rect=(0, 0, 0.9, 0.96))
    return _save(fig, stem)


def basin_table(results: pd.DataFrame) -> pd.DataFrame:
    """Success rates per method and cell of the prior-error cells."""
    keys = ["method", *cell_keys(results)]
    sub = results[results[[a for a in ("prior_scale", "prior_spread") if a in results.columns]].notna().any(axis=1)]
    return success_rates(sub, keys)


def basin_figure(rates: pd.DataFrame, stem: Path) -> list[Path]:
    """Success rate against the prior error: a panel per gap (common factor), one for per-mode errors."""
    panels = []
    if "prior_scale" in rates.columns:
        common = rates[rates["prior_scale"].notna()]
        gaps = sorted(common["gap_rad_s"].dropna().unique()) if "gap_rad_s" in common.columns else []
        for gap in gaps or [None]:
            sel = common if gap is None else common[common["gap_rad_s"] == gap]
            if gap is None and "gap_rad_s" in common.columns:
                sel = common[common["gap_rad_s"].isna()]
            title = "common factor" + ("" if gap is None else f", gap {gap:g} rad/s")
            panels.append(("prior_scale", sel, title))
    if "prior_spread" in rates.columns and rates["prior_spread"].notna().any():
        sel = rates[rates["prior_spread"].notna()]
        if "prior_scale" in sel.columns:
            sel = sel[sel["prior_scale"].isna()]
        panels.append(("prior_spread", sel, "independent per-mode errors"))
    panels = [p for p in panels if not p[1].empty]
    fig, axs = plt.subplots(1, len(panels), figsize=(3.9 * len(panels), 3.9), squeeze=False, sharey=True)
    for ax, (axis, sel, title) in zip(axs[0], panels, strict=True):
        for method, g in sel.groupby("method", sort=True):
            g = g.sort_values(axis)
            ax.plot(g[axis], 100 * g["success_rate"], lw=1.4, label=method, **_style(method))
        ax.axhline(100 * BASIN_LEVEL, color="k", ls=":", lw=1)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(LABEL[axis].split(" (")[0] if axis == "prior_spread" else "prior factor c", fontsize=8)
        ax.set_ylim(-3, 103)
        ax.grid(True, alpha=0.3)
    axs[0][0].set_ylabel("success rate (% of replicates)")
    handles, labels = axs[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8)
    fig.suptitle("Basin of attraction: replicates in which every mode lands within tolerance of the truth "
                 f"(dotted: {BASIN_LEVEL:.0%})", fontsize=9)
    fig.tight_layout(rect=(0, 0, 0.9, 0.94))
    return _save(fig, stem)


def basin_edges(rates: pd.DataFrame) -> pd.DataFrame:
    """Per method (and gap): the range of the common prior factor around 1 over which success stays
    ≥ 90 %, and the largest per-mode error s up to which it does."""
    rows = []
    if "prior_scale" in rates.columns:
        common = rates[rates["prior_scale"].notna()]
        by = ["method", "gap_rad_s"] if "gap_rad_s" in common.columns else ["method"]
        for key, g in common.groupby(by, sort=True, dropna=False):
            key = key if isinstance(key, tuple) else (key,)
            c = g.sort_values("prior_scale")
            good = c["success_rate"].to_numpy() >= BASIN_LEVEL
            x = c["prior_scale"].to_numpy()
            i0 = int(np.argmin(np.abs(x - 1.0)))
            if not good[i0]:
                span = "none (fails at c = 1)"
            else:
                lo = hi = i0
                while lo > 0 and good[lo - 1]:
                    lo -= 1
                while hi < len(x) - 1 and good[hi + 1]:
                    hi += 1
                span = f"{x[lo]:g} … {x[hi]:g}"
            rows.append({"method": key[0], **({"gap_rad_s": key[1]} if len(key) > 1 else {}),
                         "c with success ≥ 90 %": span,
                         "min success": f"{100 * c['success_rate'].min():.0f} %"})
    return pd.DataFrame(rows)


def figures(summary: pd.DataFrame, results: pd.DataFrame, out: Path) -> tuple[list[Path], str]:
    """Every axis figure, the basin figure and table (the grid's page lists the figures with their captions,
    experiments/report/captions/); returns the files and a Markdown section with the basin's edges."""
    from experiments.io import write_table
    from experiments.report import htmltables

    files = []
    for axis in swept_axes(summary):
        files += axis_figure(summary, axis, out / "figures" / f"axis_{axis}")
    if not any(a in results.columns for a in ("prior_scale", "prior_spread")):
        return files, ""
    rates = basin_table(results)
    files += basin_figure(rates, out / "figures" / "basin")
    table = rates.assign(success_rate=(100 * rates["success_rate"]).round(1),
                         not_converged_rate=(100 * rates["not_converged_rate"]).round(1)).dropna(axis=1, how="all")
    edges = basin_edges(rates)
    files += write_table(table, out / "tables" / "basin_rates")
    files.append(htmltables.write(out / "tables" / "basin_rates.html", "Basin of attraction: success rates",
                                  [("Where success stays at or above 90 %", edges), ("Per cell (%)", table)]))
    text = ["## Basin of attraction: where success stays at or above 90 %", "",
            "A replicate succeeds when every mode converged within min(max(5 σ_CRLB, 0.5 % ω), half the distance "
            "to the nearest mode) of the truth (experiments/report/success.py); "
            "[success rates per cell](tables/basin_rates.md), [figure](figures/basin.png).", "",
            markdown_table(edges), ""]
    return files, "\n".join(text) + "\n"
