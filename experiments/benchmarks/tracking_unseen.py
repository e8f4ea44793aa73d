"""Does ``gated_pencil`` still halve the naive NExT-ERA tracker's error on records unlike the grid's?

    python -m experiments.benchmarks.tracking_unseen [--seed 4711] [--replicates 2] [--trackers next_era,gated_pencil]
        [--records all|pulses|ambient]
    python -m experiments.benchmarks.tracking_unseen --set other-rates --trackers all   # every tracker as shipped
    python -m experiments.benchmarks.tracking_unseen --trackers next_era,gated_pencil,gated_pencil:trend_memory=1

Nine cells that no tracker option was chosen on: drifts of other sizes and signs and over other spans,
steps on other modes and at other times, pulses of other torques and rates (at random times every 3.3–15 s
on average, or periodic every 7 s), noise
100–1000 µg, and two other plants (target frequencies 2.5/14/17/45 and 4/25/28/70 rad/s, other damping),
120 s records from ``experiments.simulate.tracking_data`` (seed ``--seed``; not a grid's scoring seed).
Scores as ``tracking_beats`` (its ``score_record``, ``summary``): the median over replicates of the error
after the first convergence (% of ω), the re-convergence after a step, and the ratio to next_era ("halves" =
ratio ≤ 0.5 and, on a step, re-converged within 20 s; nan where next_era never held every mode within 1 %),
the late error (median over the record's second half, converged or not) and the share of replicates that
never converged. A step's re-convergence is also given in periods of the record's slowest mode (the slowest
truth frequency over the record), the unit in which a re-convergence of "10 periods" is stated. Writes
results/bench/tracking_unseen.md.

``--set other-rates`` (:data:`OTHER_RATE_CELLS`, fixed on 2026-11-26 before their first score): records at
other sample intervals and numbers of modes — Δt = 1 ms with one mode and with six, 4 ms with two, 0.1 s with
six, plants built for those frequencies (``PlantConfig`` with that many cantilever shapes, calibrated) —
and two laboratory-like records (:mod:`experiments.simulate.laboratory`, settings other than the grids':
dwells 0.4–2.5 s, 25–45 Hz, decimated to 250 and 500 Hz). Their convergence is held for
``SETTLE_PERIODS`` (10) periods of the slowest mode instead of 2 s (no posterior bound is computed for
them), and a step's re-convergence is also given in those periods ("halves" there: ratio ≤ 0.5 and
re-converged within 10 periods); the laboratory records are scored per dwell
(``tracking_metrics.score_dwells``). ``--set all`` runs both sets. A tracker that refuses a record (its
defaults do not fit it) is a row "refused" with its one-line reason.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

import methods
from experiments.benchmarks.tracking_beats import score_record, summary
from experiments.benchmarks.tracking_cpu import parse_row
from experiments.io import atomic_write_text
from experiments.report import tracking_metrics
from experiments.simulate.laboratory import LaboratoryCellConfig, check_laboratory, make_lab_cell
from experiments.simulate.plant import PlantConfig
from experiments.simulate.tracking_data import TrackingCellConfig, check_cell_config, make_cell

__all__ = ["AMBIENT_CELLS", "CELLS", "RECORDS", "OTHER_RATE_CELLS", "LAB_CELLS", "SETS", "configs", "other_configs",
           "run", "main"]

OUT = Path("results/bench/tracking_unseen.md")
_PLANT_A = {"target_freq_rad_s": [2.5, 14.0, 17.0, 45.0], "damping": [0.01, 0.004, 0.006, 0.003]}
_PLANT_B = {"target_freq_rad_s": [4.0, 25.0, 28.0, 70.0]}
CELLS = {
    "drift -20/-10/+15/+20 % in 200 s, 60 N·m every 3.3 s, 300 µg":
        ({"drift": [-0.2, -0.1, 0.15, 0.2], "ramp_end_s": 200.0}, (60.0, 0.3), 300.0, {}),
    "drift +30/+20/+20/+10 % in 300 s, pulses every 10 s, 300 µg":
        ({"drift": [0.3, 0.2, 0.2, 0.1], "ramp_end_s": 300.0}, (100.0, 0.1), 300.0, {}),
    "drift, other plant A, 1000 µg":
        ({"drift": [0.25, 0.15, 0.25, 0.1], "ramp_end_s": 400.0}, (100.0, 0.2), 1000.0, _PLANT_A),
    "step +5/−5/0/+8 % at 40 s, 150 N·m every 10 s, 700 µg":
        ({"step": [0.05, -0.05, 0.0, 0.08], "step_time_s": 40.0}, (150.0, 0.1), 700.0, {}),
    "step +5/−5/0/+8 % at 40 s, 150 N·m every 5 s, 700 µg":
        ({"step": [0.05, -0.05, 0.0, 0.08], "step_time_s": 40.0}, (150.0, 0.2), 700.0, {}),
    "step 0/+7/−3/0 % at 70 s, other plant B, 100 µg":
        ({"step": [0.0, 0.07, -0.03, 0.0], "step_time_s": 70.0}, (80.0, 0.25), 100.0, _PLANT_B),
    "step +3/0/+6/−4 % at 90 s, 100 N·m every 4 s, 1000 µg":
        ({"step": [0.03, 0.0, 0.06, -0.04], "step_time_s": 90.0}, (100.0, 0.25), 1000.0, {}),
    "step −6/−4/+5/0 % at 50 s, 120 N·m periodic every 7 s, 500 µg":
        ({"step": [-0.06, -0.04, 0.05, 0.0], "step_time_s": 50.0}, (120.0, 7.0), 500.0, {}),
    "drift −15/−10/+10/+25 % in 250 s, 80 N·m every 15 s, 800 µg":
        ({"drift": [-0.15, -0.1, 0.1, 0.25], "ramp_end_s": 250.0}, (80.0, 1 / 15), 800.0, {}),
}



# Under continuing random excitation (a white force on the body, N per sample, alone or with sparse pulses)
# and sloshing: schedule, excitation (tracking_data.ExcitationConfig), noise µg, plant. Fixed on 2026-11-26
# before their first score; other forces, drifts, steps, slosh amplitudes and rates than the grid's.
AMBIENT_CELLS = {
    "white force 4 N, drift −10/+8/+12/−6 % in 200 s, 1000 µg":
        ({"drift": [-0.1, 0.08, 0.12, -0.06], "ramp_end_s": 200.0}, {"disturbance_force_n": 4.0}, 1000.0, {}),
    "white force 6 N, step 0/−5/+4/+3 % at 50 s, 100 µg":
        ({"step": [0.0, -0.05, 0.04, 0.03], "step_time_s": 50.0}, {"disturbance_force_n": 6.0}, 100.0, {}),
    "white force 3 N, drift, other plant A, 300 µg":
        ({"drift": [0.15, 0.1, 0.12, 0.08], "ramp_end_s": 250.0}, {"disturbance_force_n": 3.0}, 300.0, _PLANT_A),
    "slosh 4 % at 0.08 Hz on a +8 % drift, white force 5 N, pulses every 15 s, 300 µg":
        ({"slosh": 0.04, "slosh_hz": 0.08, "drift": 0.08, "ramp_end_s": 120.0},
         {"disturbance_force_n": 5.0, "thruster_torque_n_m": 80.0, "thruster_rate_hz": 1 / 15}, 300.0, {}),
    "slosh 2 % at 0.1 Hz, white force 3 N, 1000 µg":
        ({"slosh": 0.02, "slosh_hz": 0.1, "slosh_phase_rad": 1.0}, {"disturbance_force_n": 3.0}, 1000.0, {}),
    "slosh 5 % at 0.06 Hz, other plant B, white force 5 N, 100 µg":
        ({"slosh": 0.05, "slosh_hz": 0.06}, {"disturbance_force_n": 5.0}, 100.0, _PLANT_B),
}

RECORDS = ("all", "pulses", "ambient")


def _plant(w: list[float], zeta: float = 0.005) -> dict:
    """A plant of len(w) flexible modes at w (rad/s): the first len(w) cantilever shapes, calibrated."""
    n = len(w)
    return {"shape_modes": list(range(1, n + 1)), "modified_modes": [], "target_freq_rad_s": w,
            "damping": [zeta] * n, "initial_displacement_m": [0.01] * n}


# label -> TrackingCellConfig settings (fixed before their first score; the seed is --seed)
OTHER_RATE_CELLS = {
    "step −8 % at 6 s, Δt = 1 ms, 1 mode (250 rad/s), pulses every 0.5 s, 300 µg":
        {"dt_s": 0.001, "duration_s": 12.0, "plant": _plant([250.0]), "noise_ug": 300.0,
         "schedule": {"step": [-0.08], "step_time_s": 6.0},
         "excitation": {"thruster_torque_n_m": 100.0, "thruster_rate_hz": 2.0, "pulse_samples": 5}},
    "step ±4–6 % at 5 s, Δt = 1 ms, 6 modes (60–410 rad/s), pulses every 0.5 s, 300 µg":
        {"dt_s": 0.001, "duration_s": 10.0, "plant": _plant([60.0, 110.0, 170.0, 240.0, 320.0, 410.0]),
         "noise_ug": 300.0, "schedule": {"step": [0.06, -0.04, 0.05, 0.0, -0.05, 0.04], "step_time_s": 5.0},
         "excitation": {"thruster_torque_n_m": 100.0, "thruster_rate_hz": 2.0, "pulse_samples": 5}},
    "drift +15/+10 % in 40 s, Δt = 4 ms, 2 modes (60, 95 rad/s), pulses every 1 s, 500 µg":
        {"dt_s": 0.004, "duration_s": 30.0, "plant": _plant([60.0, 95.0]), "noise_ug": 500.0,
         "schedule": {"drift": [0.15, 0.1], "ramp_end_s": 40.0},
         "excitation": {"thruster_torque_n_m": 100.0, "thruster_rate_hz": 1.0, "pulse_samples": 5}},
    "step +3–5 % at 300 s, Δt = 0.1 s, 6 modes (0.8–5.5 rad/s), pulses every 20 s, 300 µg":
        {"dt_s": 0.1, "duration_s": 600.0, "plant": _plant([0.8, 1.3, 2.0, 2.9, 4.1, 5.5]), "noise_ug": 300.0,
         "schedule": {"step": [0.05, 0.05, 0.04, 0.04, 0.03, 0.03], "step_time_s": 300.0},
         "excitation": {"thruster_torque_n_m": 100.0, "thruster_rate_hz": 0.05}},
}
# label -> LaboratoryCellConfig settings: the kind of record, with settings the grids do not use
LAB_CELLS = {
    "laboratory, 1 mode 25–45 Hz, dwells 0.4–2.5 s, 250 Hz after ÷20, 500 µg":
        {"lab": {"n_modes": 1, "band_hz": [25.0, 45.0], "dwell_s": [0.4, 2.5], "offset_v": 0.12, "decimate": 20},
         "noise_ug": 500.0, "duration_s": 15.0},
    "laboratory, 2 modes, dwells 0.4–2.5 s, 500 Hz after ÷10, 200 µg":
        {"lab": {"n_modes": 2, "band_hz": [22.0, 60.0], "mode_ratio": [1.5, 1.8], "dwell_s": [0.4, 2.5],
                 "damping": [0.002, 0.006], "offset_v": -0.08, "decimate": 10},
         "noise_ug": 200.0, "duration_s": 15.0},
}
SETS = ("grid-rate", "other-rates", "all")


def other_configs(seed: int, replicates: int) -> dict:
    """The other-rate and laboratory cells' configs, each checked before any cell is simulated."""
    out = {}
    for label, c in OTHER_RATE_CELLS.items():
        out[label] = TrackingCellConfig(**{**c, "plant": PlantConfig(**c["plant"])}, replicates=replicates, seed=seed)
        check_cell_config(out[label])
    for label, c in LAB_CELLS.items():
        out[label] = LaboratoryCellConfig(**c, replicates=replicates, seed=seed)
        check_laboratory(out[label])
    return out


def _slowest_period_s(cell: dict) -> float:
    """The period of the record's slowest mode (its slowest truth frequency over the record), s."""
    return 2 * np.pi / float(cell["truth_freq_rad_s"].min())


def _score_other(tr, cell: dict, r: int) -> dict:
    """An other-rate record's scores: held for SETTLE_PERIODS periods of its slowest mode; a laboratory
    record per dwell."""
    if "step_times_s" in cell:
        return tracking_metrics.score_record(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, cell, r)
    truth = cell["truth_freq_rad_s"]
    period = _slowest_period_s(cell)
    st, span = float(cell["step_time_s"]), cell["drift_span_s"]
    out = tracking_metrics.score_track(
        tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, truth, float(cell["dt_s"]),
        bound=None, step_time_s=st if np.isfinite(st) else None,
        drift_span_s=span if np.all(np.isfinite(span)) else None,
        hold_s=tracking_metrics.SETTLE_PERIODS * period)
    out["reconverge_periods"] = out["t_reconverge_s"] / period
    return out


def configs(seed: int, replicates: int, *, records: str = "all") -> dict[str, TrackingCellConfig]:
    """The configs of ``records`` (all cells, only the thruster-pulse ones of ``CELLS``, or only
    ``AMBIENT_CELLS``), each checked (``check_cell_config``) before any cell is simulated."""
    out = {}
    for label, (schedule, (torque, rate), noise, plant) in (CELLS.items() if records != "ambient" else ()):
        pulses = {"thruster_period_s": rate} if rate > 1 else {"thruster_rate_hz": rate}   # > 1: a period (s)
        out[label] = TrackingCellConfig(
            schedule=schedule, excitation={"thruster_torque_n_m": torque, **pulses}, noise_ug=noise,
            duration_s=120.0, replicates=replicates, seed=seed, plant=PlantConfig(**plant))
        check_cell_config(out[label])
    for label, (schedule, excitation, noise, plant) in (AMBIENT_CELLS.items() if records != "pulses" else ()):
        out[label] = TrackingCellConfig(schedule=schedule, excitation=excitation, noise_ug=noise, duration_s=120.0,
                                        replicates=replicates, seed=seed, plant=PlantConfig(**plant))
        check_cell_config(out[label])
    return out


def run(trackers: list[str], seed: int, replicates: int, which: str = "grid-rate", *,
        records: str = "all") -> pd.DataFrame:
    rows, refused = [], {}
    cfgs = {**(configs(seed, replicates, records=records) if which != "other-rates" else {}),
            **(other_configs(seed, replicates) if which != "grid-rate" else {})}
    for label, cfg in cfgs.items():
        other = label not in CELLS and label not in AMBIENT_CELLS
        # the other rates' table shows no error × bound: their bounds (minutes of CPU at 10⁴ samples) are skipped
        cell = make_lab_cell(cfg) if isinstance(cfg, LaboratoryCellConfig) else make_cell(cfg, bounds=not other)
        dt = float(cell["dt_s"])
        for r in range(replicates):
            for name in trackers:
                tracker, options = parse_row(name)   # a row: a tracker, or name:key=value+... (its options)
                try:
                    tr = methods.track(tracker, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **options)
                except ValueError as exc:          # the tracker's defaults do not fit this record
                    refused[(label, name)] = " ".join(str(exc).split())
                    continue
                if other:
                    score = _score_other(tr, cell, r)
                else:       # held for 2 s, as the grid scores; the re-convergence also in periods of the slowest mode
                    score = score_record(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, cell, r)
                    score["reconverge_periods"] = score["t_reconverge_s"] / _slowest_period_s(cell)
                rows.append({"cell": label, "tracker": name, "r": r, **score})
        print(f"{label}: done", flush=True)
    s = summary(pd.DataFrame(rows)).rename(columns={"beats": "halves"})
    other = ~s.cell.isin(list(CELLS) + list(AMBIENT_CELLS))
    if other.any():                                   # none in --set grid-rate: an empty division fails
        steps = s.cell.str.startswith("step") | s.cell.str.startswith("laboratory")
        base = s[s.tracker == "next_era"].set_index("cell")["err_rel_median"]
        s.loc[other, "ratio"] = s.loc[other, "err_rel_median"] / s.loc[other, "cell"].map(base)
        s.loc[other, "halves"] = (s.loc[other, "ratio"] <= 0.5) & (
            ~steps[other] | (s.loc[other, "reconverge_periods"] <= tracking_metrics.SETTLE_PERIODS))
    for (label, name), why in refused.items():
        s = pd.concat([s, pd.DataFrame([{"cell": label, "tracker": name, "refused": why}])], ignore_index=True)
    return s


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=4711)
    parser.add_argument("--replicates", type=int, default=2)
    parser.add_argument("--trackers", default="next_era,gated_pencil")
    parser.add_argument("--set", default="grid-rate", choices=SETS,
                        help="the nine cells at Δt = 0.02 s, the other rates and laboratory records, or both")
    parser.add_argument("--records", choices=RECORDS, default="all",
                        help="of the Δt = 0.02 s set: all, only the thruster-pulse ones, or only the ambient ones")
    parser.add_argument("--out", default=None, help="default results/bench/tracking_unseen[_<set>].md")
    args = parser.parse_args(argv)
    trackers = methods.track_names() if args.trackers == "all" else [t for t in args.trackers.split(",") if t]
    unknown = [t for t in trackers if parse_row(t)[0] not in methods.track_names()]
    if args.replicates < 1 or "next_era" not in trackers or unknown:
        parser.exit(2, f"error: --replicates = {args.replicates} must be at least 1 and --trackers = "
                       f"{args.trackers} must name known trackers, next_era among them\n")
    try:
        configs(args.seed, args.replicates)
        other_configs(args.seed, args.replicates)
    except ValueError as exc:                  # a cell the simulator refuses: one line, before any work
        parser.exit(2, f"error: {exc}\n")
    from threadpoolctl import threadpool_limits  # only the command sets the thread pool

    # One BLAS thread (OPENBLAS_NUM_THREADS set here would come too late under `python -m`: the package's
    # __init__ has imported numpy by then); as the grid's jobs, experiments/jobs/track_job.py
    with threadpool_limits(limits=1):
        s = run(trackers, args.seed, args.replicates, args.set, records=args.records)
    command = (f"python -m experiments.benchmarks.tracking_unseen --seed {args.seed} --replicates {args.replicates}"
               + (f" --set {args.set}" if args.set != "grid-rate" else "")
               + (f" --records {args.records}" if args.records != "all" else "")
               + (f" --trackers {args.trackers}" if args.trackers != "next_era,gated_pencil" else ""))
    text = markdown(s, command)
    print(text)
    out = args.out or (OUT if args.set == "grid-rate" else OUT.with_name(f"tracking_unseen_{args.set}.md"))
    atomic_write_text(Path(out), text)


def markdown(s: pd.DataFrame, command: str) -> str:
    """The table: per cell and tracker, the medians over replicates (a refused tracker: its reason)."""
    lines = [f"# Trackers on records unlike the grid's (`{command}`)", "",
             "error = median |ω̂ − ω|/ω after the first convergence (laboratory: over each dwell from 10 periods "
             "after the move); within 1 % = share of the track's times (laboratory: of the scored spans) with every "
             "mode within 1 %; re-converge: after the step, s, and in periods of the slowest mode (laboratory: "
             "median over the moves); × bound = the median of |error| over the unknown-force PCRB's std (white force "
             "unknown, pulses known; an efficient tracker scores 0.67; none for the other rates); × rate-unknown = the "
             "same over the unknown-rate PCRB's, on a drift over the whole record only (each frequency a line of "
             "unknown rate; under a white force about twice the unknown-force bound, whose walk matched to the "
             "schedule acts as if told the rate; docs/tracking.md §2).", "",
             "| cell | tracker | error % of ω | × bound | × rate-unknown | within 1 % | ratio to next_era | late % | "
             "never | re-converge s | periods | halves |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for _, r in s.iterrows():
        if isinstance(r.get("refused"), str):
            lines.append(f"| {r.cell} | {r.tracker} | refused: {r.refused} | | | | | | | | | |")
            continue
        periods = r.get("reconverge_periods", np.nan)
        halves = "yes" if pd.notna(r.halves) and bool(r.halves) else "no"
        ufb = r.get("err_ufbound_median", np.nan)
        rb = r.get("err_rbound_median", np.nan)
        lines.append(f"| {r.cell} | {r.tracker} | {100 * r.err_rel_median:.3f} | {ufb:.2f} | {rb:.2f} | "
                     f"{100 * r.share_within_1pct:.0f} % | "
                     f"{r.ratio:.2f} | {100 * r.err_rel_median_late:.3f} | {r.never_converged_rate:.2f} | "
                     f"{r.t_reconverge_s:.2f} | {periods:.1f} | {halves} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
