"""The tracking grid's tables, figures and page, from the run step's outputs.

    python -m experiments.report.tracking_report --grid tracking --data results/tracking/data \
        --out results/tracking --page results/tracking/summary.md -- results/tracking/track/*

Reads every tracker folder's ``<cell>.csv`` (the scores per record) and ``<cell>.npz`` (the tracks) and
writes ``tables/tracking_records.csv`` (every record), ``tables/tracking_table.{csv,md,html}`` (per tracker
and cell: medians over replicates and rates, ``tracking_metrics.summarize_cell``),
``tables/tracking_trackers.{csv,html}`` (per tracker over all cells), the figures of
``experiments.report.tracking_plots`` with a caption ``<name>.rst`` beside each (category ``tracking``), and
the page. The verdict compares each tracker with the naive baseline ``next_era`` (NExT-ERA on a sliding
window) when the grid ran it: "beats" = half its median error or less, and re-converged within 20 s of the
step. A cell's leader is the most accurate tracker among those that held every mode within 1 % in at least
half their replicates.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from experiments.cli import ArgumentParser, cpu_line
from experiments.io import atomic_write_text, markdown_table, read_npz, write_table
from experiments.report import htmltables, tracking_plots
from experiments.report.aggregate import write_captions
from experiments.report.tracking_metrics import summarize_cell
from experiments.simulate.tracking_grid import load_grid

__all__ = ["BASELINE", "RECONVERGE_S", "TABLE_COLUMNS", "add_baseline_ratio", "main", "page", "per_tracker",
           "read_records",
           "summary_table", "verdict", "write_figures"]

BASELINE = "next_era"
RECONVERGE_S = 20.0
TABLE_COLUMNS = ["tracker", "schedule", "excitation", "noise_ug", "duration_s", "replicates", "err_rel_median",
                 "err_rel_p90", "err_ufbound_median", "err_rbound_median", "x_next_era", "err_bound_median",
                 "err_rel_median_late", "err_ufbound_median_late", "share_within_1pct", "t_converge_s",
                 "t_reconverge_s", "reconverge_periods", "reconverged_share", "lag_s", "never_converged_rate",
                 "never_reconverged_rate", "diverged_rate", "false_lock_rate", "cpu_per_sample_s", "onboard_ok"]


def read_records(folders: list[Path]) -> pd.DataFrame:
    frames = [pd.read_csv(f) for folder in folders for f in sorted(Path(folder).glob("*.csv"))]
    if not frames:
        raise ValueError(f"no tracking results in {', '.join(map(str, folders))}")
    return pd.concat(frames, ignore_index=True)


def summary_table(records: pd.DataFrame, steps: set[str]) -> pd.DataFrame:
    rows = []
    for (tracker, cell), group in records.groupby(["tracker", "cell"], sort=True):
        first = group.iloc[0]
        rows.append({"tracker": tracker, "cell": cell, "schedule": first["schedule"],
                     "excitation": first["excitation"], "noise_ug": first["noise_ug"],
                     "duration_s": first["duration_s"], **summarize_cell(group, has_step=first["schedule"] in steps)})
    out = pd.DataFrame(rows).sort_values(["tracker", "schedule", "excitation", "noise_ug", "duration_s"],
                                         ignore_index=True)
    return add_baseline_ratio(out)


def add_baseline_ratio(summary: pd.DataFrame) -> pd.DataFrame:
    """``x_next_era``: each row's median error after convergence over the baseline's in the same cell (NaN
    where the baseline did not run or never converged); "× bound" is ``err_ufbound_median``."""
    out = summary.copy()
    base = out[out["tracker"] == BASELINE].set_index("cell")["err_rel_median"] if "cell" in out else pd.Series()
    out["x_next_era"] = out["err_rel_median"] / out["cell"].map(base) if len(base) else np.nan
    return out


def per_tracker(summary: pd.DataFrame) -> pd.DataFrame:
    out = summary.groupby("tracker").agg(
        err_rel_median=("err_rel_median", "median"), err_rel_median_late=("err_rel_median_late", "median"),
        t_reconverge_s=("t_reconverge_s", "median"),
        share_within_1pct=("share_within_1pct", "median"), diverged_rate=("diverged_rate", "mean"),
        cpu_per_sample_s=("cpu_per_sample_s", "median")).reset_index()
    out["onboard_ok"] = out["cpu_per_sample_s"] * 100 <= 0.020
    return out


def verdict(summary: pd.DataFrame) -> list[str]:
    """Per (schedule, excitation, noise): the most accurate tracker and how it compares with the baseline."""
    lines = []
    for (sched, exc, noise), cell in summary.groupby(["schedule", "excitation", "noise_ug"], sort=True):
        # A tracker leads a cell only if it held every mode within 1 % in at least half its replicates: its
        # error after convergence is a median over the replicates that converged, and one lucky replicate of
        # three (a few windows of a whole-window hop) is no lead (the re-convergence figure's rule too).
        held = (cell["never_converged_rate"] <= 0.5 if "never_converged_rate" in cell
                else pd.Series(True, index=cell.index))
        ranked = cell[held].dropna(subset=["err_rel_median"]).sort_values("err_rel_median")
        if ranked.empty:
            late = cell.dropna(subset=["err_rel_median_late"]).sort_values("err_rel_median_late")
            lead = (f"; the smallest late error: {late.iloc[0]['tracker']}, "
                    f"{100 * late.iloc[0]['err_rel_median_late']:.3g} % of ω") if len(late) else ""
            most = " in most replicates" if cell["err_rel_median"].notna().any() else ""
            lines.append(f"- {sched} / {exc} / {noise:g} µg: no tracker held every mode within 1 %{most}{lead}.")
            continue
        best = ranked.iloc[0]
        text = (f"- {sched} / {exc} / {noise:g} µg: **{best['tracker']}**, median error "
                f"{100 * best['err_rel_median']:.3g} % of ω")
        if np.isfinite(best.get("err_ufbound_median", np.nan)):
            rate = best.get("err_rbound_median", np.nan)       # a drift's: the bound not told the rate
            text += (f" ({best['err_ufbound_median']:.2g}× the unknown-force bound"
                     + (f", {rate:.2g}× the one not told the drift's rate" if np.isfinite(rate) else "") + ")")
        if np.isfinite(best["t_reconverge_s"]):
            text += f", re-converged {best['t_reconverge_s']:.3g} s after the step"
            if np.isfinite(best.get("reconverge_periods", np.nan)):
                text += (f" (median over moves: {best['reconverge_periods']:.3g} periods of the slowest mode; "
                         f"{100 * best['reconverged_share']:.0f} % of moves within 10)")
        base = cell[cell["tracker"] == BASELINE]
        if len(base) and best["tracker"] != BASELINE:
            b = base.iloc[0]
            # the baseline's error after convergence, or its late error when it never converged
            col = "err_rel_median" if np.isfinite(b["err_rel_median"]) else "err_rel_median_late"
            ratio = best[col] / b[col]
            lab = np.isfinite(best.get("reconverged_share", np.nan))
            beats = ratio <= 0.5 and (not np.isfinite(best["never_reconverged_rate"])
                                      or (best["reconverged_share"] >= 1.0 if lab
                                          else best["t_reconverge_s"] <= RECONVERGE_S))
            which = "" if col == "err_rel_median" else " late (it never held every mode)"
            verdict_word = "beats it" if beats else "does not beat it"
            within = "10 periods of every move" if lab else "20 s of a step"
            text += (f"; {ratio:.2g}× the{which} error of the naive {BASELINE} ({verdict_word}: half its error "
                     f"or less, and re-converged within {within})")
        lines.append(text + ".")
    return lines


def _figure_cells(grid: dict) -> dict[str, str]:
    """Per schedule, the cell its figures show: the highest noise, the first excitation, the longest record."""
    out = {}
    for sched in [*grid["schedules"], *(grid.get("laboratory") or {})]:
        order = [*grid["excitations"], "laboratory"]
        cells = [(c["noise_ug"], c["duration_s"], -order.index(c["excitation"]), name)
                 for name, c in grid["cells"].items() if c["schedule"] == sched]
        out[sched] = max(cells)[3]
    return out


def _white_force_cells(grid: dict) -> dict[str, str]:
    """Per schedule, a cell under a white force (the first such excitation, the highest noise, the longest
    record), for the error figure of the ambient classes; empty if the grid has no white force."""
    white = [name for name, e in grid["excitations"].items() if (e or {}).get("disturbance_force_n", 0) > 0]
    out = {}
    for sched in grid["schedules"]:
        cells = [(c["noise_ug"], c["duration_s"], -white.index(c["excitation"]), name)
                 for name, c in grid["cells"].items() if c["schedule"] == sched and c["excitation"] in white]
        if cells:
            out[sched] = max(cells)[3]
    return out


def _errors(folders: list[Path], cell: str, truth: np.ndarray, dt: float) -> tuple[dict, dict]:
    tracks, errs = {}, {}
    for folder in folders:
        path = Path(folder) / f"{cell}.npz"
        if not path.is_file():
            continue
        tr = read_npz(path)
        name = Path(folder).name
        tracks[name] = {"t_s": tr["t_s"], "frequencies": tr["frequencies"]}
        k = np.round(tr["t_s"] / dt).astype(int)
        errs[name] = (tr["t_s"], np.abs(tr["frequencies"] - truth[k]) / truth[k])
    return tracks, errs


def _bounds(data: dict) -> dict:
    truth = data["truth_freq_rad_s"]
    return {label: (data["t_s"], data[key] / truth[None]) for label, key in
            (("unknown-force bound", "pcrb_unknown_force_std_rad_s"),
             ("rate-unknown bound", "pcrb_unknown_rate_std_rad_s"), ("genie bound", "pcrb_std_rad_s"))
            if key in data}


def write_figures(grid: dict, data_dir: Path, folders: list[Path], summary: pd.DataFrame, out: Path) -> None:
    figs = out / "figures"
    panels, bounds = {}, {}
    white_panels, white_bounds = {}, {}
    for cell in _white_force_cells(grid).values():
        data = read_npz(data_dir / f"{cell}.npz")
        _, errs = _errors(folders, cell, data["truth_freq_rad_s"], float(data["dt_s"]))
        if errs:
            white_panels[cell], white_bounds[cell] = errs, _bounds(data)
    if white_panels:
        tracking_plots.error_vs_time(white_panels, figs / "tracking_error_vs_time_white_force", white_bounds)
    for sched, cell in _figure_cells(grid).items():
        data = read_npz(data_dir / f"{cell}.npz")
        truth, t = data["truth_freq_rad_s"], data["t_s"]
        tracks, errs = _errors(folders, cell, truth, float(data["dt_s"]))
        if tracks:
            tracking_plots.estimates_vs_truth(tracks, t, truth, cell, figs / f"tracking_estimates_{sched}")
            panels[cell] = errs
            bounds[cell] = _bounds(data)
    if panels:
        tracking_plots.error_vs_time(panels, figs / "tracking_error_vs_time", bounds)
    if summary["never_reconverged_rate"].notna().any():
        tracking_plots.reconvergence_vs_noise(summary, figs / "tracking_reconvergence")
    tracking_plots.accuracy_vs_cpu(per_tracker(summary), figs / "tracking_accuracy_vs_cpu")


def page(grid: dict, summary: pd.DataFrame, trackers: pd.DataFrame, figures: list[str]) -> str:
    n_rep = int(summary["replicates"].max())
    short = summary[["tracker", "schedule", "excitation", "noise_ug", "err_rel_median", "err_ufbound_median",
                     "err_rbound_median", "x_next_era", "err_rel_p90", "err_rel_median_late", "err_ufbound_median_late",
                     "t_reconverge_s", "diverged_rate", "cpu_per_sample_s"]].copy()
    short["cpu_per_sample_s"] = short["cpu_per_sample_s"] * 1e6
    short = short.rename(columns={"cpu_per_sample_s": "cpu_us_per_sample", "err_ufbound_median": "x_bound",
                                  "err_rbound_median": "x_rate_bound", "err_ufbound_median_late": "x_bound_late"})
    noises = ", ".join(f"{v:g}" for v in grid["noise_ug"])
    durations = ", ".join(f"{v:g}" for v in grid["duration_s"])
    lines = [f"# Tracking results of the `{grid['name']}` grid", "",
             f"{summary['tracker'].nunique()} trackers × {len(grid['cells'])} cells (schedules "
             f"{', '.join(grid['schedules'])} × excitations {', '.join(grid['excitations'])} × noise "
             f"{noises} µg × {durations} s"
             + (f"; laboratory cells {', '.join(grid['laboratory'])}" if grid.get("laboratory") else "") + ")"
             f", {n_rep} replicates. Definitions: docs/tracking.md. Generated by "
             "`python -m experiments.report.tracking_report`; do not edit.", "",
             "## Verdict per cell", "", *verdict(summary), "",
             "## Per tracker (medians over cells)", "", markdown_table(trackers), "",
             "## Tracking table", "",
             "Errors relative to ω after the first convergence (median, 90th percentile over time, modes and "
             "replicates); x_bound: the median of |error| over the **unknown-force** PCRB's std (the white "
             "disturbance unknown, pulses known; an efficient tracker scores 0.67, the half-normal's median); "
             "x_rate_bound: the same over the **unknown-rate** PCRB's, on a drift over the whole record only (each "
             "frequency a line of unknown rate; under a white force the unknown-force bound's walk, matched to the "
             "schedule, acts as if told the rate, and this one is about twice it; under pulses it is the lower: "
             "docs/tracking.md §2); "
             "x_next_era: the median error over the naive NExT-ERA tracker's in the cell; the late error and "
             "x_bound_late over the record's second half, converged or not; re-convergence after "
             "the step (s), divergence rate, CPU per sample (µs, one noisy 2-core machine). The table's "
             "err_bound_median is × the **genie** bound (every input known). All columns in "
             "[tables/tracking_table.csv](tables/tracking_table.csv).", "",
             markdown_table(short), ""]
    for name in figures:
        lines += [f"![{name}](figures/{name}.png)", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", required=True)
    ap.add_argument("--data", required=True, type=Path)
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--page", type=Path)
    ap.add_argument("results", nargs="+", type=Path, help="the trackers' folders")
    args = ap.parse_args(argv)
    grid = load_grid(args.grid, check_cells=False)
    records = read_records(args.results)
    steps = {name for name, s in grid["schedules"].items() if (s or {}).get("step") is not None}
    steps |= set(grid.get("laboratory") or {})                      # a laboratory record moves every 0.4-2 s
    summary = summary_table(records, steps)
    trackers = per_tracker(summary)
    tables = args.out / "tables"
    tables.mkdir(parents=True, exist_ok=True)
    records.to_csv(tables / "tracking_records.csv", index=False)
    table = summary[[c for c in TABLE_COLUMNS if c in summary.columns]]
    write_table(table, tables / "tracking_table")
    trackers.to_csv(tables / "tracking_trackers.csv", index=False)
    htmltables.write(tables / "tracking_table.html", f"{grid['name']}: tracking table", [("", table)])
    htmltables.write(tables / "tracking_trackers.html", f"{grid['name']}: trackers", [("", trackers)])
    write_figures(grid, args.data, args.results, summary, args.out)
    figures = sorted(f.stem for f in (args.out / "figures").glob("tracking_*.png"))
    write_captions(args.out / "figures", "png", {"grid": grid["name"]})
    write_captions(tables, "html", {"grid": grid["name"]})
    if args.page:
        atomic_write_text(args.page, page(grid, summary, trackers, figures))
    print(f"tracking report of {grid['name']}: {len(summary)} (tracker, cell) rows, {len(figures)} figures")
    print(cpu_line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
