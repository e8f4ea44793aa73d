"""Comparison figures of a grid's summary table (matplotlib, PNG and SVG, units on every axis)."""

from __future__ import annotations

import zlib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402
from matplotlib.layout_engine import ConstrainedLayoutEngine  # noqa: E402

from experiments.io import save_figure  # noqa: E402
from experiments.report.coverage import IDEAL_1STD, IDEAL_2STD, IDEAL_MEDIAN_Z  # noqa: E402

__all__ = ["METHOD_STYLE", "EXTRA_COLOURS", "MAX_FAILURE_RATE", "VARIANT_SHADES", "label_points", "rmse_against",
           "winner_map", "failure_map", "coverage"]

METHOD_STYLE = {"fft": ("tab:gray", "o"), "akf": ("tab:blue", "s"), "wkf": ("tab:cyan", "D"),
                "pem": ("tab:red", "^"), "pll": ("tab:green", "v"),
                # the peers (methods/peers/README.md)
                "era": ("tab:orange", "P"), "n4sid": ("tab:purple", "X"), "ssi_cov": ("tab:brown", "<"),
                "ssi_data": ("tab:pink", ">"), "lsce": ("tab:olive", "h"), "hdmd": ("gold", "*"),
                "bopdmd": ("navy", "p"),
                # the trackers that are not also identifiers (methods/tracking/README.md)
                "rls_ar": ("maroon", "H"), "next_era": ("teal", "d"), "gated_pencil": ("black", "8"),
                "akf_ambient": ("darkblue", "s"), "rpem_ambient": ("firebrick", "H"),
                # variants that are a recommendation of their own get a hue of their own, not a shade of their
                # base's (a darker firebrick is rls_ar's maroon; a darker darkblue, bopdmd's navy)
                "rpem_ambient:two": ("magenta", "H"), "akf_ambient:slosh": ("darkgoldenrod", "s")}
# Any other method (a plugin) gets a colour from this list by a hash of its name, and the marker x.
EXTRA_COLOURS = ["darkgreen", "teal", "maroon", "indigo", "darkorange", "slategray", "crimson", "olive"]
MAX_FAILURE_RATE = 0.5   # a (method, cell) that failed more often than this is not drawn as a point


def _save(fig, stem: Path) -> list[Path]:
    """``<stem>.png`` and ``<stem>.svg``, then the figure closed. A figure with a constrained layout gets it
    computed once and kept for both files, with no tight crop: the layout ran at every save and the crop drew
    each file twice, 80 % of the tracking report's estimates figure (21 × 4 panels) and 1/3 of the paper
    grid's aggregate; the layout fills the figure already, so the files differ from a crop by its 0.1 in pad.
    Other figures (``tight_layout``) are cropped to what is drawn."""
    laid_out = isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
    if laid_out:
        fig.canvas.draw()                      # the constrained layout, once
        fig.set_layout_engine("none")          # ...kept for both files
    paths = [save_figure(fig, stem.with_suffix(suffix), tight=not laid_out) for suffix in (".png", ".svg")]
    plt.close(fig)
    return paths


# A variant (``akf:tuned``) keeps its method's hue, shaded by its name, so paper and tuned rows pair up by eye.
VARIANT_SHADES = {"paper": 0.55, "tuned": 1.0}


def _style(method):
    if method in METHOD_STYLE:
        return METHOD_STYLE[method]
    base, _, variant = method.partition(":")
    color, marker = METHOD_STYLE.get(base, (EXTRA_COLOURS[zlib.crc32(base.encode()) % len(EXTRA_COLOURS)], "x"))
    if not variant:
        return color, marker
    rgb = np.array(matplotlib.colors.to_rgb(color))
    shade = VARIANT_SHADES.get(variant, 0.4 + 0.1 * (zlib.crc32(variant.encode()) % 5))
    # below 1 darken towards black, else lighten halfway towards white
    rgb = rgb * shade if shade < 1 else rgb + 0.45 * (1 - rgb)
    return matplotlib.colors.to_hex(rgb), marker


# where a name may go, in points from its marker: right/left × just above/below, then a line further out each time
PLACES = [(dx, dy) for k in range(4) for dy in (3 + 9 * k, -11 - 9 * k) for dx in (5, -5)]


def label_points(ax, points, fontsize: float = 7.0) -> None:
    """Name each point ``(x, y, text[, alpha])`` of ``ax`` beside it where the name overlaps no name placed
    before it nor another point: of sixteen places around the marker (right/left × above/below, a line further
    out each time) the first free one, else the least crowded. The names' sizes are the renderer's own text
    extents. Call it once the axes' scales and data are set; a layout engine that moves the axes afterwards
    moves every name with its point. Greedy, left to right (no layout library is kept for a dozen names)."""
    if not points:
        return
    ax.autoscale_view()
    renderer = ax.figure.canvas.get_renderer()
    px = ax.figure.dpi / 72.0                              # pixels per point
    xy = ax.transData.transform([(p[0], p[1]) for p in points])
    marks = [(u - 4 * px, v - 4 * px, u + 4 * px, v + 4 * px) for u, v in xy]
    boxes: list[tuple[float, float, float, float]] = []

    def hits(b, own):
        return sum(b[0] < c[2] and c[0] < b[2] and b[1] < c[3] and c[1] < b[3]
                   for k, c in enumerate(boxes + marks) if k != len(boxes) + own)

    for i in np.argsort(xy[:, 0], kind="stable"):
        x, y, text, *rest = points[i]
        ann = ax.annotate(text, (x, y), textcoords="offset points", xytext=(5, 3), fontsize=fontsize,
                          alpha=rest[0] if rest else 1.0)
        best = None
        for dx, dy in PLACES:
            ann.set_position((dx, dy))
            ann.set_horizontalalignment("right" if dx < 0 else "left")
            e = ann.get_window_extent(renderer)
            n = hits((e.x0, e.y0, e.x1, e.y1), i)
            if best is None or n < best[0]:
                best = (n, dx, dy, (e.x0, e.y0, e.x1, e.y1))
            if n == 0:
                break
        _, dx, dy, box = best
        ann.set_position((dx, dy))
        ann.set_horizontalalignment("right" if dx < 0 else "left")
        boxes.append(box)


def _line(method) -> str:
    return "-." if ":" in method else "-"


def rmse_against(summary: pd.DataFrame, stem: Path, *, x: str, fixed: str, fixed_value) -> list[Path]:
    """RMSE against ``x`` (noise_ug or n_samples) at ``fixed`` = ``fixed_value``; CRLB dashed; the posterior
    mean's RMSE (the Bayesian yardstick, where the grid has one) grey dash-dot."""
    sub = summary[summary[fixed] == fixed_value]
    modes = sorted(sub["mode"].unique())
    fig, axes = plt.subplots(1, len(modes), figsize=(4.2 * len(modes), 3.8), squeeze=False)
    for ax, mode in zip(axes[0], modes, strict=True):
        sm = sub[sub["mode"] == mode].sort_values(x)
        for method, g in sm.groupby("method", sort=True):
            ok = g["failure_rate"] <= MAX_FAILURE_RATE
            color, marker = _style(method)
            ax.plot(g.loc[ok, x], g.loc[ok, "rmse_rad_s"], marker=marker, color=color, label=method, lw=1.4,
                    ls=_line(method))
        crlb = sm.drop_duplicates(x)
        ax.plot(crlb[x], crlb["crlb_std_rad_s"], "k--", lw=1.2, label="CRLB")
        ax.plot(crlb[x], crlb["crlb_offset_std_rad_s"], "k:", lw=1.2, label="CRLB, offset unknown")
        if "posterior_mean_rmse_rad_s" in crlb.columns and crlb["posterior_mean_rmse_rad_s"].notna().any():
            ax.plot(crlb[x], crlb["posterior_mean_rmse_rad_s"], color="0.35", ls=(0, (6, 2, 1, 2)), lw=2.2,
                    marker="o", ms=3, label="posterior mean")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"mode {mode} ({sm['true_rad_s'].iloc[0]:.2f} rad/s)")
        ax.set_xlabel("noise 1σ (µg)" if x == "noise_ug" else "record length (samples)")
        ax.grid(True, which="both", alpha=0.3)
        if x == "n_samples":
            ax.set_xticks(sorted(sm[x].unique()))
            ax.get_xaxis().set_major_formatter(matplotlib.ticker.ScalarFormatter())
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    axes[0][0].set_ylabel("RMSE of frequency (rad/s)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8)
    what = f"{fixed_value:g} µg" if fixed == "noise_ug" else f"{fixed_value} samples"
    fig.suptitle(f"RMSE against {'noise' if x == 'noise_ug' else 'record length'} at {what} "
                 f"(methods failing > {MAX_FAILURE_RATE:.0%} of replicates not drawn)")
    fig.tight_layout(rect=(0, 0, 0.88 if "posterior mean" in labels else 0.9, 1))
    return _save(fig, stem)


def _cell_axes(ax, noises, lengths, *, ylabel: bool = True):
    ax.set_xticks(range(len(lengths)), [str(n) for n in lengths], rotation=90 if len(lengths) > 5 else 0,
                  fontsize=8 if len(lengths) > 5 else None)
    ax.set_yticks(range(len(noises)), [f"{v:g}" for v in noises] if ylabel else [])
    ax.set_xlabel("record length (samples)")
    if ylabel:
        ax.set_ylabel("noise 1σ (µg)")


def _dark(color) -> bool:
    """Whether black text would be hard to read on ``color`` (its relative luminance below 0.3)."""
    r, g, b = matplotlib.colors.to_rgb(color)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b < 0.3


def winner_map(summary: pd.DataFrame, stem: Path) -> list[Path]:
    """Per mode and cell: the method with the lowest RMSE among those failing ≤ 10 %, RMSE/CRLB written in."""
    methods = sorted(summary["method"].unique())
    noises = sorted(summary["noise_ug"].unique())
    lengths = sorted(summary["n_samples"].unique())
    modes = sorted(summary["mode"].unique())
    cmap = ListedColormap(["white"] + [_style(m)[0] for m in methods])
    norm = BoundaryNorm(np.arange(-0.5, len(methods) + 1.5), cmap.N)
    fig, axes = plt.subplots(1, len(modes), figsize=(3.6 * len(modes), 0.5 * len(noises) + 2.4),
                             squeeze=False)
    for ax, mode in zip(axes[0], modes, strict=True):
        grid = np.zeros((len(noises), len(lengths)))
        for i, noise in enumerate(noises):
            for j, n in enumerate(lengths):
                cell = summary[(summary["mode"] == mode) & (summary["noise_ug"] == noise)
                               & (summary["n_samples"] == n) & (summary["failure_rate"] <= 0.1)]
                cell = cell.dropna(subset=["rmse_rad_s"])
                if cell.empty:
                    continue
                best = cell.loc[cell["rmse_rad_s"].idxmin()]
                grid[i, j] = methods.index(best["method"]) + 1
                bayes = best.get("rmse_over_posterior_mean", np.nan)
                ink = "white" if _dark(_style(best["method"])[0]) else "black"
                if np.isfinite(bayes):
                    # where the CRLB is loose: against the Bayesian yardstick (the posterior mean's RMSE)
                    ax.text(j, i, f"{bayes:.2f}", ha="center", va="center", fontsize=7, style="italic",
                            fontweight="bold", color=ink)
                    continue
                ratio = best["rmse_over_crlb"]
                label = f"{ratio:.1f}" if ratio < 100 else f"{ratio:.0e}".replace("e+0", "e")
                ax.text(j, i, label if best["identifiable"] else f"({label})", ha="center", va="center",
                        fontsize=7, color=ink if best["identifiable"] else "black")
                if not best["identifiable"]:      # a "win" where the bound says nothing can be identified
                    ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fc="white", alpha=0.6, ec="none"))
        ax.imshow(grid, cmap=cmap, norm=norm, aspect="auto", origin="lower")
        _cell_axes(ax, noises, lengths, ylabel=ax is axes[0][0])
        ax.set_title(f"mode {mode}")
    handles = [plt.Rectangle((0, 0), 1, 1, color=_style(m)[0]) for m in methods]
    fig.legend(handles + [plt.Rectangle((0, 0), 1, 1, fc="white", ec="k")], methods + ["none ≤ 10 % fail"],
               loc="lower center", ncol=min(len(methods) + 1, 7), fontsize=8)
    bayes = "rmse_over_posterior_mean" in summary.columns and summary["rmse_over_posterior_mean"].notna().any()
    fig.suptitle("Best method per cell (lowest RMSE among methods failing ≤ 10 %); number = its RMSE/CRLB; "
                 "pale, in brackets: the mode is not identifiable there (CRLB > 1 % of ω or > 10 % of the spacing)"
                 + ("\nbold italic: a cell where some mode's CRLB > 0.1 × the prior's 1σ: RMSE / the RMSE of the "
                    "posterior mean on the same records (the Bayesian yardstick; < 1: closer than that estimator)"
                    if bayes else ""), fontsize=9)
    legend_rows = -(-(len(methods) + 1) // 7)
    fig.tight_layout(rect=(0, 0.04 + 0.05 * legend_rows, 1, 0.93 if bayes else 0.95))
    return _save(fig, stem)


def failure_map(summary: pd.DataFrame, stem: Path) -> list[Path]:
    """Failure rate per method and cell (worst mode), in percent."""
    methods = sorted(summary["method"].unique())
    noises = sorted(summary["noise_ug"].unique())
    lengths = sorted(summary["n_samples"].unique())
    worst = summary.groupby(["method", "noise_ug", "n_samples"])["failure_rate"].max()
    # Up to five panels a row; constrained layout keeps the suptitle above the panel titles and makes room
    # for the colour bar.
    ncols = min(len(methods), 5)
    nrows = -(-len(methods) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.4 * ncols, (0.5 * len(noises) + 2.0) * nrows + 0.4),
                             squeeze=False, layout="constrained")
    im = None
    for k, ax in enumerate(axes.flat):
        if k >= len(methods):
            ax.set_axis_off()
            continue
        method = methods[k]
        grid = np.full((len(noises), len(lengths)), np.nan)
        for i, noise in enumerate(noises):
            for j, n in enumerate(lengths):
                if (method, noise, n) in worst.index:
                    grid[i, j] = 100 * worst[(method, noise, n)]
                    ax.text(j, i, f"{grid[i, j]:.0f}", ha="center", va="center", fontsize=7,
                            color="white" if grid[i, j] > 60 else "black")
        im = ax.imshow(grid, cmap="Reds", vmin=0, vmax=100, aspect="auto", origin="lower")
        _cell_axes(ax, noises, lengths, ylabel=k % ncols == 0)
        ax.set_title(method)
    fig.colorbar(im, ax=axes.ravel().tolist(), label="failure rate, worst mode (%)", shrink=0.8)
    fig.suptitle("Failure rate (not converged / no estimate), percent of replicates", wrap=True)
    return _save(fig, stem)


def coverage(summary: pd.DataFrame, table: pd.DataFrame, stem: Path) -> list[Path]:
    """How honest each method's std is: pooled ±1σ/±2σ coverage and median |error|/σ per identifiable cell."""
    pooled = table[(table["cells"] == "identifiable")].set_index("method")
    with_std = [m for m in pooled.index if table[(table["method"] == m)]["n_with_std"].max() > 0]
    without = [m for m in pooled.index if m not in with_std]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    x = np.arange(len(with_std))
    for k, (col, label) in enumerate((("coverage_1std", "within ±1σ"), ("coverage_2std", "within ±2σ"))):
        vals = [100 * pooled.loc[m, col] for m in with_std]
        colors = [_style(m)[0] for m in with_std]
        ax1.bar(x + (k - 0.5) * 0.38, np.nan_to_num(vals), 0.36, color=colors, alpha=1.0 if k == 0 else 0.45,
                edgecolor="k")
        ax1.bar([0], [0], 0, color="0.3", alpha=1.0 if k == 0 else 0.45, edgecolor="k", label=label)
        for xi, v in zip(x, vals, strict=True):
            ax1.text(xi + (k - 0.5) * 0.38, (0 if np.isnan(v) else v) + 1.5,
                     "no data" if np.isnan(v) else f"{v:.0f}", ha="center", fontsize=7,
                     rotation=90 if np.isnan(v) else 0)
    ax1.axhline(100 * IDEAL_1STD, color="k", ls="--", lw=1, label="ideal ±1σ (68.3 %)")
    ax1.axhline(100 * IDEAL_2STD, color="k", ls=":", lw=1, label="ideal ±2σ (95.4 %)")
    ax1.set_xticks(x, [f"{m}\n(n = {int(pooled.loc[m, 'n_with_std'])})" for m in with_std])
    ax1.set_ylim(0, 130)
    ax1.set_yticks(range(0, 101, 20))
    ax1.set_ylabel("share of errors within ±kσ (%)")
    ax1.set_title("coverage, pooled over identifiable (mode, cell) pairs", fontsize=10)
    ax1.legend(fontsize=7, loc="upper center", ncol=4, handlelength=1.5, columnspacing=1)
    ident = summary[summary["identifiable"].astype(bool) & (summary["n_with_std"] > 0)]
    rng = np.random.default_rng(0)      # jitter only, for legibility
    for i, m in enumerate(with_std):
        z = ident.loc[ident["method"] == m, "median_abs_err_over_std"].to_numpy(float)
        color, marker = _style(m)
        ax2.plot(i + rng.uniform(-0.15, 0.15, z.size), z, marker, color=color, ms=5, alpha=0.8, ls="none")
    ax2.axhline(IDEAL_MEDIAN_Z, color="k", ls="--", lw=1, label="ideal 0.67")
    ax2.set_yscale("log")
    ax2.set_xticks(range(len(with_std)), with_std)
    ax2.set_xlim(-0.6, len(with_std) - 0.4)
    ax2.set_ylabel("median |error| / reported σ")
    ax2.set_title("per identifiable (mode, cell) pair", fontsize=10)
    ax2.grid(True, which="both", axis="y", alpha=0.3)
    ax2.legend(fontsize=7)
    note = f" ({', '.join(without)}: no std reported)" if without else ""
    fig.suptitle(f"Is each method's reported std honest?{note}", fontsize=11)
    fig.tight_layout()
    return _save(fig, stem)
