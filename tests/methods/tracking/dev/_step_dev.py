"""``rpem_ambient``'s reported recursion after a step, per record — a development table, not a test (pytest does
not collect it).

    python tests/methods/tracking/dev/_step_dev.py SEED [--extra "+pair_peaks=true"] [--cells step,−7]

On ``tracking_ambient``'s cells whose label holds one of ``--cells`` (its configs, 2 replicates), the row
``rpem_ambient:frequency_model=trend+recursions=two+score_reset=true`` plus ``--extra``: per cell the median
over the replicates of × bound (median |e| after 30 s over the unknown-force bound's median 1σ; % of ω where
the cell has no bound), each replicate's re-convergence (s after the step until every mode holds 1 % for 2 s,
— never) and mode 3's median |e| 5–20 s after the step (%); for a replicate that takes longer than 20 s, the
share of the time from 10 s after the step to its re-convergence that each mode is beyond 1 %, and the
whole-record recursion's resets (s/mode).
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_ambient import configs  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.report.tracking_metrics import score_track  # noqa: E402
from experiments.simulate.tracking_data import make_cell  # noqa: E402

ROW = "rpem_ambient:frequency_model=trend+recursions=two+score_reset=true"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("--extra", default="")
    ap.add_argument("--cells", default="step, white,−7")
    ap.add_argument("--replicates", type=int, default=2)
    args = ap.parse_args()
    name, opts = parse_row(ROW + args.extra)
    for label, cfg in configs(args.seed, args.replicates).items():
        if not any(c in label for c in args.cells.split(",")):
            continue
        cell = make_cell(cfg)
        dt, st, truth = float(cell["dt_s"]), float(cell["step_time_s"]), cell["truth_freq_rad_s"]
        bound = cell.get("pcrb_unknown_force_std_rad_s")
        xs, rcs, m3 = [], [], []
        for r in range(args.replicates):
            tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
            k = np.round(tr.t_s / dt).astype(int)
            e = (tr.frequencies - truth[k]) / truth[k]
            late = tr.t_s >= 30.0
            if bound is not None and np.all(np.isfinite(bound[r])):
                xs.append(np.median(np.abs(e[late])) / np.median(bound[r][k][late] / truth[k][late]))
            else:
                xs.append(100 * np.median(np.abs(e[late])))
            if not np.isfinite(st):
                continue
            rc = score_track(tr.t_s, tr.frequencies, np.ones(tr.frequencies.shape, bool), 1.0, truth, dt,
                             step_time_s=st)["t_reconverge_s"]
            rcs.append(rc)
            m3.append(100 * np.median(np.abs(e[(tr.t_s >= st + 5) & (tr.t_s < st + 20), 2])))
            if not rc <= 20:
                end = st + rc if np.isfinite(rc) else tr.t_s[-1]
                h = (tr.t_s >= st + 10) & (tr.t_s < end)
                print(f"   replicate {r}, re-conv. {rc:.1f} s: share beyond 1 % per mode "
                      + "/".join(f"{v:.2f}" for v in np.mean(np.abs(e[h]) > 0.01, axis=0)) + "; resets "
                      + " ".join(f"{a:.1f}/m{i + 1}" for a, i in tr.extra["reset_times_s"]))
        tail = ""
        if rcs:
            tail = (" | re-conv. " + "/".join("—" if np.isnan(x) else f"{x:.1f}" for x in rcs) + " s | mode 3 |e| "
                    "5–20 s " + "/".join(f"{x:.2f}" for x in m3) + " %")
        print(f"{args.seed} | {label} | × bound {np.median(xs):.2f} (" + "/".join(f"{x:.2f}" for x in xs) + ")" + tail,
              flush=True)


if __name__ == "__main__":
    main()
