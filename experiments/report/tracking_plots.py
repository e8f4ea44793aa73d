"""The tracking grid's figures (matplotlib): estimates against the truth, error against time, re-convergence
against noise, accuracy against CPU per sample. Each function takes plain arrays/tables and a file stem and
writes ``<stem>.png`` and ``<stem>.svg`` (experiments.io.save_figure)."""

from __future__ import annotations

import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from experiments.report.plots import _save, _style  # noqa: E402
from experiments.report.tracking_metrics import ONBOARD_BUDGET_S, ONBOARD_SLOWDOWN  # noqa: E402

__all__ = ["BOUND_STYLES", "HALF_NORMAL_MEDIAN", "accuracy_vs_cpu", "error_vs_time", "estimates_vs_truth",
           "nan_percentiles", "reconvergence_vs_noise"]

HALF_NORMAL_MEDIAN = 0.6745      # median of |e| for e ~ N(0, σ²), in σ


def nan_percentiles(a: np.ndarray, qs) -> list[np.ndarray]:
    """``np.nanpercentile(a, q, axis=0)`` for each q of ``qs`` (its default, linear interpolation between the
    sorted values at rank (n − 1)·q/100 of the n non-NaN ones; NaN where a column has none), for an array of
    many short columns. Written here because numpy's nanpercentile calls a Python function per column
    (``apply_along_axis``): 3.6 s for the (3, 6000, 4) estimates of one tracker, 2/3 of a grid report's time."""
    a = np.asarray(a, dtype=float)
    ranked = np.sort(a, axis=0)                          # NaN sort last
    n = np.sum(~np.isnan(a), axis=0)
    out = []
    for q in qs:
        pos = np.maximum(n - 1, 0) * (q / 100.0)
        below = np.floor(pos).astype(int)
        above = np.minimum(below + 1, np.maximum(n - 1, 0))
        lo = np.take_along_axis(ranked, below[None], axis=0)[0]
        hi = np.take_along_axis(ranked, above[None], axis=0)[0]
        t = pos - below
        diff = hi - lo
        # numpy's _lerp: from the nearer end, so that t = 1 gives hi exactly
        value = np.where(t >= 0.5, hi - diff * (1.0 - t), lo + diff * t)
        out.append(np.where(n > 0, value, np.nan))
    return out


def estimates_vs_truth(tracks: dict[str, dict], t_s: np.ndarray, truth: np.ndarray, title: str,
                       stem: Path) -> list[Path]:
    """One row per tracker, one column per mode: the median estimate over replicates with its 10–90 % band,
    and the truth (black). ``tracks``: tracker -> {"t_s": (K,), "frequencies": (R, K, m)}."""
    names = list(tracks)
    m = truth.shape[1]
    fig, axes = plt.subplots(len(names), m, figsize=(3.2 * m, 1.6 * len(names) + 0.8), sharex=True,
                             squeeze=False, layout="constrained")
    for row, name in enumerate(names):
        tr = tracks[name]
        f = tr["frequencies"]
        color = _style(name)[0]
        lo, med, hi = nan_percentiles(f, (10, 50, 90))
        for i in range(m):
            ax = axes[row, i]
            ax.plot(t_s, truth[:, i], color="k", lw=1.0)
            ax.fill_between(tr["t_s"], lo[:, i], hi[:, i], color=color, alpha=0.3, lw=0)
            ax.plot(tr["t_s"], med[:, i], color=color, lw=0.9)
            span = np.ptp(truth[:, i])
            pad = max(0.05 * truth[:, i].mean(), 0.5 * span)
            ax.set_ylim(truth[:, i].min() - pad, truth[:, i].max() + pad)
            ax.tick_params(labelsize=7)
            if row == 0:
                ax.set_title(f"mode {i + 1}", fontsize=9)
            if i == 0:
                ax.set_ylabel(f"{name}\nrad/s", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)", fontsize=8)
    fig.suptitle(f"{title}: estimate (median, 10–90 % band over replicates) against the truth (black)",
                 fontsize=10, wrap=True)         # wrapped to the figure: one mode's column is narrower than it
    return _save(fig, stem)



BOUND_STYLES = {"unknown-force bound": {"color": "0.55", "ls": "-", "lw": 1.2},
                "rate-unknown bound": {"color": "0.3", "ls": "-.", "lw": 1.2},
                "genie bound": {"color": "0.45", "ls": ":", "lw": 1.4}}
SHADED_BOUND = "unknown-force bound"      # drawn as a grey floor: no tracker can be expected below it


BOLD = 3                        # error_vs_time: the panel's most accurate trackers drawn bold
BASELINE = "next_era"           # and the naive baseline


def _best(curves: dict[str, tuple[np.ndarray, np.ndarray]], k: int) -> list[str]:
    """The ``k`` names whose curve (t, error) has the smallest median over the second half of its time span."""
    def late(item):
        t, curve = item[1]
        with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
            v = np.nanmedian(curve[t >= 0.5 * (t[0] + t[-1])]) if t.size else np.nan
        return v if np.isfinite(v) else np.inf
    return [name for name, _ in sorted(curves.items(), key=late)[:k]]


def _side_legend(fig, handles: dict) -> None:
    """One legend beside the panels, an entry per label of ``handles`` (label → artist), two columns past 18."""
    fig.legend(list(handles.values()), list(handles), fontsize=7, loc="outside right center",
               ncol=1 if len(handles) <= 18 else 2)


def _legend_line(line):
    """A legend entry in the line's colour and style, at full strength (the faint lines' alpha left out)."""
    return matplotlib.lines.Line2D([], [], color=line.get_color(), ls=line.get_linestyle(), lw=1.4)


def error_vs_time(panels: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]], stem: Path,
                  bounds: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] | None = None) -> list[Path]:
    """Relative error against time, one panel per schedule, one line per tracker (median over replicates
    and modes). ``panels``: title -> tracker -> (t_s, rel_err (R, K, m)); ``bounds``: title -> label
    (``BOUND_STYLES``) -> (t_s, bound std / ω (R, N, m)), drawn as the median over replicates and modes,
    scaled by 0.67 (the median of |error| of an efficient tracker: the half-normal's).

    Twenty trackers' lines cannot all be read: in each panel the ``BOLD`` trackers with the smallest median
    error over the record's second half, and the naive baseline ``BASELINE``, are drawn bold on top, the
    others thin and faint; the legend sits beside the panels, one entry per tracker."""
    titles = list(panels)
    ncols = min(2, len(titles))
    nrows = -(-len(titles) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(6.2 * ncols, 3.4 * nrows), squeeze=False, layout="constrained")
    handles: dict[str, object] = {}
    for ax, title in zip(axes.flat, titles, strict=False):
        curves = {}
        for name, (t, rel) in panels[title].items():
            with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
                curves[name] = (t, np.nanmedian(np.nanmedian(rel, axis=2), axis=0))
        bold = set(_best(curves, BOLD)) | ({BASELINE} & set(curves))
        for name, (t, curve) in curves.items():
            color, _ = _style(name)
            strong = name in bold
            line, = ax.plot(t, np.clip(curve, 1e-6, None), color=color, lw=1.6 if strong else 0.6,
                            alpha=1.0 if strong else 0.35, zorder=3 if strong else 2, label=name)
            handles.setdefault(name, line)
        shade = None
        for label, (t, rel) in (bounds or {}).get(title, {}).items():
            curve = np.clip(HALF_NORMAL_MEDIAN * np.median(np.median(rel, axis=2), axis=0), 1e-6, None)
            line, = ax.plot(t, curve, label=f"{label} (×0.67)", zorder=1, **BOUND_STYLES[label])
            handles.setdefault(f"{label} (×0.67)", line)
            if label == SHADED_BOUND:
                shade = (t, curve)
        ax.axhline(0.01, color="k", ls="--", lw=0.8)
        ax.set_yscale("log")
        if shade is not None:                       # down to the axis as the lines set it, no lower
            ax.relim()
            ax.autoscale_view()
            lo, hi = ax.get_ylim()
            ax.fill_between(*shade, lo, color="0.88", lw=0, zorder=0)
            ax.set_ylim(lo, hi)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time (s)")
        ax.set_ylabel(r"$|\hat\omega - \omega| / \omega$")
        ax.grid(True, which="major", alpha=0.3)
    for ax in axes.flat[len(titles):]:
        ax.set_axis_off()
    _side_legend(fig, {label: _legend_line(h) for label, h in handles.items()})
    bold_note = f"bold: each panel's {BOLD} most accurate over its second half and {BASELINE}"
    rate = any("rate-unknown bound" in b for b in (bounds or {}).values())
    head = f"Tracking error against time (median over replicates and modes; dashed: 1 %; {bold_note}"
    floor = ("; grey floor: the bound that does not know the force, "
             + ("dash-dot: the same not told a drift's rate, " if rate else "") + "dotted: the genie's)")
    fig.suptitle(head + (floor if bounds else ")"),
                 fontsize=10, wrap=True)
    return _save(fig, stem)


def reconvergence_vs_noise(summary: pd.DataFrame, stem: Path) -> list[Path]:
    """Median re-convergence time after the step against noise, one panel per excitation, each on its own
    scale; a tracker whose median re-convergence is never (∞: at least half its replicates never re-converged)
    is drawn as an open marker above the panel's longest time. The dashed 20 s line (the spacecraft cells'
    target) is drawn where it applies: not on the laboratory cells, whose steps come every 0.4–2 s."""
    steps = summary[summary["never_reconverged_rate"].notna()]
    excitations = sorted(steps["excitation"].unique())
    fig, axes = plt.subplots(1, max(1, len(excitations)), figsize=(5.2 * max(1, len(excitations)), 3.6),
                             squeeze=False, layout="constrained")
    for ax, exc in zip(axes.flat, excitations, strict=False):
        sub = steps[steps["excitation"] == exc]
        target = exc != "laboratory"
        held = sub["t_reconverge_s"].where(np.isfinite(sub["t_reconverge_s"]))   # ∞: the median never
        longest = float(np.nanmax(held)) if held.notna().any() else float(np.nanmax(sub["duration_s"])) / 2
        top = 1.15 * max(longest, 20.0 if target else 0.0)
        for name, rows in sub.groupby("tracker"):
            rows = rows.sort_values("noise_ug")
            color, marker = _style(name)
            y = rows["t_reconverge_s"].where(np.isfinite(rows["t_reconverge_s"]))
            ax.plot(rows["noise_ug"], y, marker=marker if marker != "x" else "o", color=color, label=name)
            miss = rows[~np.isfinite(rows["t_reconverge_s"])]
            ax.plot(miss["noise_ug"], np.full(len(miss), top), marker=marker if marker != "x" else "o", mfc="none",
                    color=color, ls="none", alpha=0.8)
        if target:
            ax.axhline(20.0, color="k", ls="--", lw=0.8)
        ax.set_ylim(0.0, 1.08 * top)
        ax.set_xscale("log")
        ax.set_xlabel("noise (µg, 1σ)")
        ax.set_ylabel("re-convergence after the step (s)")
        ax.set_title(f"excitation: {exc}", fontsize=9)
        ax.grid(True, alpha=0.3)
    handles = {}                                     # one entry per tracker, from every panel, beside them
    for ax in axes.flat:
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, h)
    _side_legend(fig, handles)
    fig.suptitle("Re-convergence time after the step (median over replicates; dashed: the 20 s target; open, "
                 "at the top: never in half the replicates or more)", fontsize=10, wrap=True)
    return _save(fig, stem)


def accuracy_vs_cpu(per_tracker: pd.DataFrame, stem: Path) -> list[Path]:
    """Median relative error after convergence (over every cell) against CPU time per sample, per tracker;
    the dotted line is the on-board budget (20 ms per sample on a processor 100× slower)."""
    fig, ax = plt.subplots(figsize=(9.6, 4.6), layout="constrained")
    for _, row in per_tracker.iterrows():
        color, marker = _style(row["tracker"])
        y = row["err_rel_median"] if np.isfinite(row["err_rel_median"]) else 1.0
        ax.plot(row["cpu_per_sample_s"] * 1e6, y, marker=marker if marker != "x" else "o", color=color, ms=8,
                mfc=color if np.isfinite(row["err_rel_median"]) else "none", ls="none", label=row["tracker"])
    ax.axvline(ONBOARD_BUDGET_S / ONBOARD_SLOWDOWN * 1e6, color="k", ls=":", lw=1,
               label="on-board budget (20 ms/sample at 1/100 speed)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU time per sample on this machine (µs)")
    ax.set_ylabel(r"median $|\hat\omega - \omega| / \omega$ after convergence")
    ax.grid(True, which="both", alpha=0.3)
    # a legend beside the axes, not names beside the points: a dozen trackers sit within 2x in both CPU and error
    fig.legend(fontsize=7, loc="outside right center", ncol=1 if len(per_tracker) <= 16 else 2)
    ax.set_title("Accuracy against cost (open marker at 1: never converged)", fontsize=10)
    return _save(fig, stem)
