"""``rpem_ambient``'s recursions per mode on the unseen white-force records — a development table, not a test
(pytest does not collect it).

    python tests/methods/tracking/dev/_unseen_white_dev.py SEED [--replicates 2] [--extra "+opt=value"]
        [--rows window,reported] [--cache DIR] [--per-record]

On ``tracking_unseen``'s three white-force records (``AMBIENT_CELLS`` without slosh; design seeds only), per record
and per recursion: the window recursion (``rpem_ambient:frequency_model=trend+pair_peaks=true``, the recursion
``recursions="two"`` runs beside the whole-record one, which does not feed back into it), the reported one
(``rpem_ambient:two``'s options before it took ``rate_test``) and, with ``--extra``, the reported one with those
options added. Per record and row: the benchmark's × bound (median |e| over time and modes after 30 s over the
unknown-force bound's), each mode's median |e| over that mode's bound median 1σ after 30 s and its median signed
error (%), the re-convergence after a step; with ``next_era`` among ``--rows`` (put it first) each later row's
median |e| after 30 s over next_era's on the same replicate (× next_era; medians skip the times a
tracker leaves a mode undetermined, as the benchmarks' do); ``--per-record`` adds each mode's error (%) at
20…120 s and the resets.
``--cache`` keeps the simulated cells (with their bounds) as pickles, so that a second call does not simulate them
again.
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import print_marks, white_cells  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.report.tracking_metrics import score_track  # noqa: E402

TWO = "rpem_ambient:frequency_model=trend+recursions=two+score_reset=true+pair_peaks=true"
ROWS = {"window": "rpem_ambient:frequency_model=trend+pair_peaks=true", "reported": TWO, "next_era": "next_era"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("--replicates", type=int, default=2)
    ap.add_argument("--extra", default="")
    ap.add_argument("--rows", default="window,reported")
    ap.add_argument("--cache", default=None)
    ap.add_argument("--per-record", action="store_true")
    args = ap.parse_args()
    rows = {k: ROWS[k] for k in args.rows.split(",") if k}
    if args.extra:
        rows["variant"] = TWO + args.extra
    for label, _, cell in white_cells("unseen", args.seed, args.replicates, args.cache):
        dt, st, truth = float(cell["dt_s"]), float(cell["step_time_s"]), cell["truth_freq_rad_s"]
        print(f"## {args.seed} | {label}")
        for r in range(args.replicates):
            bound = cell["pcrb_unknown_force_std_rad_s"][r]
            base = None                                   # next_era's median |e| after 30 s on this replicate
            for row, spec in rows.items():
                name, opts = parse_row(spec)
                tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
                k = np.round(tr.t_s / dt).astype(int)
                e = (tr.frequencies - truth[k]) / truth[k]
                b = bound[k] / truth[k]
                late = tr.t_s >= 30.0
                med = float(np.nanmedian(np.abs(e[late])))
                xb = med / np.median(b[late])
                per = np.nanmedian(np.abs(e[late]), axis=0) / np.median(b[late], axis=0)
                sgn = 100 * np.nanmedian(e[late], axis=0)
                if row == "next_era":
                    base = med
                xn = f" | × next_era {med / base:.2f}" if base is not None and row != "next_era" else ""
                rc = ""
                if np.isfinite(st):
                    v = score_track(tr.t_s, tr.frequencies, np.ones(tr.frequencies.shape, bool), 1.0, truth, dt,
                                    step_time_s=st)["t_reconverge_s"]
                    rc = f" | re-conv. {v:.1f} s"
                print(f"r{r} {row:8s} × bound {xb:.2f} | per mode " + "/".join(f"{x:.1f}" for x in per)
                      + " | signed % " + "/".join(f"{x:+.2f}" for x in sgn) + xn + rc, flush=True)
                if args.per_record:
                    print_marks(tr, e, b, "σ_B", clamp=False)


if __name__ == "__main__":
    main()
