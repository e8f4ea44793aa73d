"""The tracker's latency after a step on a pulsed cell of ``tracking_unseen``: per replicate and mode, the first
pulse after the step, the earliest time the record allows the mode (the piecewise Cramér–Rao bound of the
window [step, step + h) first under ``--target`` 2σ/ω), when the track holds the mode within 1 % for 2 s
(the scorer's rule, per mode) and the difference — a development script, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_latency_dev.py SEEDS [--cell "step +5/−5/0/+8 % at 40 s, 150 N·m every 10 s"]
        [--set unseen-grid] [--replicates 2] [--trackers gated_pencil,gated_pencil:key=value] [--target 0.01]

``--set unseen-grid``: every step cell of that set. "Periods" are of the slowest mode after the step. A mode
whose bound never falls under the target within 40 s after the step reads "—". The latency of a replicate is
that of the mode that holds its re-convergence (the last one in): its time in minus its earliest time.
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[2]), str(Path(__file__).resolve().parent),
                str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _close_modes_crlb import piecewise_crlb  # noqa: E402
from _pulse_cell_dev import step_cell  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks import tracking_unseen as tu  # noqa: E402
from experiments.benchmarks.tracking_cpu import parse_row  # noqa: E402
from experiments.report import tracking_metrics  # noqa: E402
from methods.tracking import _segments  # noqa: E402

CELL = "step +5/−5/0/+8 % at 40 s, 150 N·m every 10 s, 700 µg"
HORIZON_S = 40.0
STEP_S = 0.25


def earliest(cell: dict, r: int, target: float) -> np.ndarray:
    """Per mode, the first horizon h (s after the step, every ``STEP_S``) at which the piecewise bound of the
    window [step + 1, step + h] gives 2σ/ω ≤ ``target`` (inf: not within ``HORIZON_S``)."""
    dt = float(cell["dt_s"])
    truth = cell["truth_freq_rad_s"]
    s = int(round(float(cell["step_time_s"]) / dt))
    w = truth[s]
    m = w.size
    pulses = np.flatnonzero(np.any(cell["inputs"][r] != 0, axis=1))
    out = np.full(m, np.inf)
    for h in np.arange(STEP_S, HORIZON_S + STEP_S / 2, STEP_S):
        stop = min(truth.shape[0], s + 1 + int(round(h / dt)))
        flags = np.zeros(stop - s - 1, dtype=bool)
        flags[pulses[(pulses > s) & (pulses < stop)] - s - 1] = True
        runs = [(a + s + 1, b + s + 1) for a, b in _segments.segments(flags, 2 * (2 * m + 1))]
        if not runs:
            continue
        sd = piecewise_crlb(cell["accel_clean_m_s2"][r], dt, w, np.asarray(cell["truth_damping"]), runs,
                            float(cell["noise_std_m_s2"]))
        out = np.where(np.isinf(out) & (2 * sd / w <= target), h, out)
        if np.isfinite(out).all():
            break
    return out


def per_mode_in(tr, cell: dict) -> np.ndarray:
    """Per mode, the first time after the step (s) from which the track holds it within 1 % for 2 s."""
    dt = float(cell["dt_s"])
    truth = cell["truth_freq_rad_s"]
    k = np.round(tr.t_s / dt).astype(int)
    ok = np.abs(tr.frequencies / truth[k] - 1) <= tracking_metrics.TOL
    st = float(cell["step_time_s"])
    return np.array([tracking_metrics.converged_from(tr.t_s, ok[:, i], st) - st for i in range(truth.shape[1])])


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("seeds")
    parser.add_argument("--cell", default=CELL)
    parser.add_argument("--set", default="")
    parser.add_argument("--replicates", type=int, default=2)
    parser.add_argument("--trackers", default="gated_pencil")
    parser.add_argument("--target", type=float, default=0.01)
    args = parser.parse_args(argv)
    from threadpoolctl import threadpool_limits
    specs = [t for t in args.trackers.split(",") if t]
    rows = {spec: [] for spec in specs}
    with threadpool_limits(limits=1):
        for seed in (int(s) for s in args.seeds.split(",")):
            cfgs = tu.configs(seed, args.replicates, records="pulses")
            labels = ([k for k in cfgs if k.startswith("step")] if args.set == "unseen-grid"
                      else [next(k for k in cfgs if k.startswith(args.cell))])
            for label in labels:
                cell, dt, st, w_after, period = step_cell(cfgs[label])
                for r in range(args.replicates):
                    pulses = np.flatnonzero(np.any(cell["inputs"][r] != 0, axis=1)) * dt - st
                    before = pulses[pulses <= 0]
                    after = pulses[pulses > 0]
                    first = after[0] if after.size else np.inf
                    t_min = earliest(cell, r, args.target)
                    print(f"{label[:44]} seed {seed}/{r}: ω {np.round(w_after, 1)}, last pulse "
                          f"{before[-1] if before.size else -np.inf:.1f} s, next {np.round(after[:3], 1)} s; "
                          f"earliest per mode {t_min} s", flush=True)
                    for spec in specs:
                        name, opts = parse_row(spec)
                        tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
                        sc = tracking_metrics.score_record(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s,
                                                           cell, r)
                        t_in = per_mode_in(tr, cell)
                        last = int(np.nanargmax(np.where(np.isfinite(t_in), t_in, 1e9)))
                        lat = t_in[last] - t_min[last]
                        rows[spec].append((f"{seed}/{r} {label[:30]}", sc["t_reconverge_s"] / period, last + 1,
                                           first, t_min[last], t_in[last], lat, lat / (2 * np.pi / w_after[last]),
                                           100 * sc["err_rel_median"]))
                        print(f"  {spec}: re-conv {sc['t_reconverge_s'] / period:.1f} periods, error "
                              f"{100 * sc['err_rel_median']:.3f} %; per mode in at {np.round(t_in, 1)} s; last mode "
                              f"{last + 1}: earliest {t_min[last]:.2f} s, latency {lat:.2f} s", flush=True)
    for spec, v in rows.items():
        per = np.array([x[1] for x in v])
        print(f"\n{spec}: median {np.nanmedian(per):.2f} periods, over 10: {int(np.sum(~(per <= 10)))} of {per.size}")
        print("| replicate | periods | last mode | first pulse s | earliest s | in s | latency s | latency, "
              "its periods | error % |")
        for x in v:
            if not x[1] <= 8:
                print(f"| {x[0]} | {x[1]:.1f} | {x[2]} | {x[3]:.1f} | {x[4]:.2f} | {x[5]:.2f} | {x[6]:.2f} | "
                      f"{x[7]:.0f} | {x[8]:.3f} |")


if __name__ == "__main__":
    main()
