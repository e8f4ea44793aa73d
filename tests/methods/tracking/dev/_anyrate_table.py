"""Every tracker as shipped (no option beyond the prior) on stepped records unlike the grid's: a development
table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_anyrate_table.py [--seeds 1001,1002] [--trackers next_era,gated_pencil,...]

Records (tests/methods/_tracking_signals.py): laboratory-like (1 or 2 modes at 20–60 Hz stepping ±5–20 %
after dwells of 0.4–2 s, 5 kHz 12-bit accelerometer with an offset, decimated to 250 Hz) and Δt = 1 ms,
4 ms, 0.1 s with 1, 2 and 6 modes (dwells 15–60 periods of the slowest mode). Scores: score_steps (error
from 10 periods after each step, time within 1 %, re-convergence in periods of the slowest mode).
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[2]), str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from _tracking_signals import anyrate_record, lab_record, score_steps  # noqa: E402

import methods  # noqa: E402


def records(seeds):
    for seed in seeds:
        for n_modes in (1, 2):
            y, dt, truth, steps, prior = lab_record(seed, n_modes=n_modes)
            yield f"lab_{n_modes}mode", seed, y, dt, truth, steps, prior
        for dt in (1e-3, 4e-3, 0.1):
            for m in (1, 2, 6):
                y, truth, steps, prior = anyrate_record(dt, m, seed, duration_periods=120.0)
                yield f"dt{dt:g}_{m}mode", seed, y, dt, truth, steps, prior


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", default="1001,1002")
    parser.add_argument("--trackers", default=",".join(methods.track_names()))
    parser.add_argument("--cells", default="")
    parser.add_argument("--out", default="")
    args = parser.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    rows = []
    for cell, seed, y, dt, truth, steps, prior in records(seeds):
        if args.cells and not any(c == cell for c in args.cells.split(",")):
            continue
        for spec in args.trackers.split(","):
            name, _, rest = spec.partition(":")
            opts = dict(kv.split("=") for kv in rest.split("+")) if rest else {}
            opts = {k: (v == "true" if v in ("true", "false") else float(v) if "." in v else int(v))
                    for k, v in opts.items()}
            try:
                tr = methods.track(name, y, dt, prior, **opts)
                sc = score_steps(tr.t_s, tr.frequencies, truth, dt, steps)
                sc["cpu_s"] = tr.runtime_s
            except ValueError as exc:
                sc = {"error": np.nan, "note": str(exc)[:80]}
            rows.append({"cell": cell, "seed": seed, "tracker": spec, "n": y.size, **sc})
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    med = df.groupby(["cell", "tracker"], sort=False)[["error", "within", "reconv_median", "reconv_worst",
                                                       "reconv_share", "cpu_s"]].median()
    base = med.xs("next_era", level="tracker")["error"] if "next_era" in df.tracker.values else None
    if base is not None:
        med["ratio"] = med["error"] / med.index.get_level_values("cell").map(base).to_numpy()
    text = med.to_string(float_format=lambda v: f"{v:.4g}")
    print(text)
    if args.out:
        df.to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
