"""``rpem_ambient:two``'s error after a step, per mode and time segment, against NExT-ERA and the bound — a
development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_rate_zero_dev.py SEED [--set ambient|unseen] [--replicates 2]
        [--rows "next_era,rpem_ambient:two"] [--cells "step"] [--cache DIR]

On the white-force step records of ``tracking_ambient`` (``--set ambient``: the grid steps and the issue's) or
``tracking_unseen`` (``--set unseen``) whose label holds one of ``--cells``, per replicate and row: each mode's median
|e| (%) before the step (30 s on), 0–20 s after it and later, beside the unknown-force bound's median 1σ (%) and
NExT-ERA's in the same segment; the benchmark's × bound and × NExT-ERA (median |e| over time and modes after 30 s)
and the re-convergence. A ``+opt=value`` tail on a row adds options to ``rpem_ambient:two``'s (spelled out here).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import VARIANT_TWO as TWO  # noqa: E402
from _cells import ambient_configs, cached_cell, reconvergence_s, record_parser  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402

SETTLE_S = 30.0


def _spec(row: str) -> str:
    return TWO + row[len("rpem_ambient:two"):] if row.startswith("rpem_ambient:two") else row


def main() -> None:
    ap = record_parser(__doc__)
    ap.add_argument("--rows", default="next_era,rpem_ambient:two")
    ap.add_argument("--cells", default="step")
    args = ap.parse_args()
    cfgs = ambient_configs(args.set, args.seed, args.replicates)
    rows = args.rows.split(",")
    for i, (label, cfg) in enumerate(cfgs.items()):
        if "white force" not in label or "slosh" in label or not any(c in label for c in args.cells.split(",")):
            continue
        cell = cached_cell(cfg, args.cache, f"{args.set}_{args.seed}_{args.replicates}_{i}")
        dt, st, truth = float(cell["dt_s"]), float(cell["step_time_s"]), cell["truth_freq_rad_s"]
        if not np.isfinite(st):
            continue
        print(f"## {args.seed} | {label}", flush=True)
        for r in range(args.replicates):
            bound = cell["pcrb_unknown_force_std_rad_s"][r]
            res = {}
            for row in rows:
                name, opts = parse_row(_spec(row))
                tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
                k = np.round(tr.t_s / dt).astype(int)
                e = np.abs(tr.frequencies - truth[k]) / truth[k]
                b = bound[k] / truth[k]
                segs = {"before": (tr.t_s >= SETTLE_S) & (tr.t_s < st), "0-20 s": (tr.t_s >= st) & (tr.t_s < st + 20),
                        "later": tr.t_s >= st + 20}
                late = tr.t_s >= SETTLE_S
                rc = reconvergence_s(tr.t_s, tr.frequencies, truth, dt, st)
                res[row] = (segs, e, b, float(np.nanmedian(e[late])), float(np.median(b[late])), rc)
            ne = res.get("next_era")
            for row, (segs, e, b, med, bmed, rc) in res.items():
                xn = f" | × NExT-ERA {med / ne[3]:.2f}" if ne else ""
                print(f"r{r} {row:42s} × bound {med / bmed:.2f}{xn} | re-conv. {rc:.1f} s", flush=True)
                for sname, s in segs.items():
                    if not s.any():
                        continue
                    eb = np.nanmedian(e[s], axis=0) / np.median(b[s], axis=0)
                    line = (f"     {sname:7s} |e| % " + "/".join(f"{100 * x:.2f}" for x in np.nanmedian(e[s], axis=0))
                            + " | σ_B % " + "/".join(f"{100 * x:.2f}" for x in np.median(b[s], axis=0))
                            + " | × σ_B " + "/".join(f"{x:.1f}" for x in eb))
                    if ne and row != "next_era":
                        se, ee = ne[0][sname], ne[1]
                        line += " | × NExT-ERA " + "/".join(
                            f"{x:.2f}" for x in np.nanmedian(e[s], axis=0) / np.nanmedian(ee[se], axis=0))
                    print(line, flush=True)


if __name__ == "__main__":
    main()
