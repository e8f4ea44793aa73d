"""The capped design records (docs/measured/tracking_gated_pencil.md, ``capped_rows`` and ``capped_either``): the
unseen pulsed cell "step +5/−5/0/+8 % at 40 s, 150 N·m every 5 s" (``tracking_unseen.configs(seed, 2,
records="pulses")`` through ``make_cell`` without its bounds), both replicates, the prior as drawn but its
modes 2 and 3 moved to their mean × (1 ∓ g/2) — a prior pair the capped window cannot resolve — each track
scored by the benchmark's ``score_record``. A development script, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_capped_prior_dev.py SEEDS --trackers gated_pencil,gated_pencil:key=value
        [--gap 0.003]       # --gap 0: the prior as drawn

One JSON line per (seed, replicate, tracker): error, late error and within 1 % (%), re-convergence in periods of
the slowest mode after the step, per mode the time after the step from which the track stays within 1 % (s) and
the first window that determined it (s), and when the window first shortened (s); then per tracker the median
re-convergence, the replicates over 10 periods, and every replicate whose scores differ from the first tracker's.
"""

import argparse
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parent), str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _pulse_cell_dev import last_out  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks import tracking_unseen as tu  # noqa: E402
from experiments.benchmarks.tracking_cpu import parse_row  # noqa: E402
from experiments.report import tracking_metrics  # noqa: E402
from experiments.simulate.tracking_data import make_cell  # noqa: E402

CELL = "step +5/−5/0/+8 % at 40 s, 150 N·m every 5 s"
SCORES = ("err", "late", "within", "reconv")


def rows(seeds: list[int], specs: list[str], gap: float):
    for seed in seeds:
        cfgs = tu.configs(seed, 2, records="pulses")
        cell = make_cell(cfgs[next(k for k in cfgs if k.startswith(CELL))], bounds=False)
        dt, st = float(cell["dt_s"]), float(cell["step_time_s"])
        period = 2 * np.pi / cell["truth_freq_rad_s"][int(round(st / dt))].min()
        for r in range(2):
            prior = np.array(cell["prior_rad_s"][r], dtype=float)
            if gap > 0:
                mean = 0.5 * (prior[1] + prior[2])
                prior[1], prior[2] = mean * (1 - gap / 2), mean * (1 + gap / 2)
            for spec in specs:
                name, opts = parse_row(spec)
                tr = methods.track(name, cell["accel_m_s2"][r], dt, prior, **opts)
                sc = tracking_metrics.score_record(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, cell, r)
                wc, span = tr.extra["window_converged"], tr.extra["window_span_s"]
                first = [float(tr.t_s[np.flatnonzero(wc[:, i])[0]]) if wc[:, i].any() else np.inf
                         for i in range(wc.shape[1])]
                short = tr.t_s[span < 0.95 * np.nanmax(span)]
                yield {"seed": seed, "r": r, "spec": spec, "err": 100 * sc["err_rel_median"],
                       "late": 100 * sc["err_rel_median_late"], "within": 100 * sc["share_within_1pct"],
                       "reconv": sc["t_reconverge_s"] / period,
                       "within_from_s": np.round(last_out(tr, cell), 1).tolist(),
                       "first_determined_s": np.round(first, 1).tolist(),
                       "shortened_s": float(short[0]) if short.size else None}


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("seeds")
    parser.add_argument("--trackers", default="gated_pencil")
    parser.add_argument("--gap", type=float, default=0.003)
    args = parser.parse_args(argv)
    specs = [t for t in args.trackers.split(",") if t]
    from threadpoolctl import threadpool_limits
    out = []
    with threadpool_limits(limits=1):
        for row in rows([int(s) for s in args.seeds.split(",")], specs, args.gap):
            out.append(row)
            print(json.dumps(row), flush=True)
    first = {(d["seed"], d["r"]): d for d in out if d["spec"] == specs[0]}
    for spec in specs:
        mine = {(d["seed"], d["r"]): d for d in out if d["spec"] == spec}
        v = np.array([d["reconv"] for d in mine.values()])
        print(f"{spec}: re-convergence median {np.nanmedian(v):.2f} periods, over 10: {int(np.sum(~(v <= 10)))} "
              f"of {v.size}")
        for k, d in mine.items():
            if any(d[c] != first[k][c] for c in SCORES):
                print("  differs", k, {c: (round(first[k][c], 3), round(d[c], 3)) for c in SCORES})


if __name__ == "__main__":
    main()
