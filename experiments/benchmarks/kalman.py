"""Time of the augmented (akf) and frequency-weighted (wkf) Kalman filters: median wall time per record,
one record at a time (filterpy's EKF) and a cell's records in lock-step (``identify_batch``), side by side.

    python -m experiments.benchmarks.kalman [--repeats 21] [--replicates 100]

Records: the truth plant's tip acceleration + 10 µg noise at Δt = 0.02 s, Table 3 priors, the paper's
tuning (methods defaults), for both measurement models. Target: ≲ 20 ms per 256-sample record per filter
(the full grid: 100 replicates × up to 2048 samples per cell on 2 cores).

BLAS threads: the filters multiply 15×15–17×17 matrices every sample; OpenBLAS runs such products on
several threads, which on a busy 2-core machine makes them 3–5× slower. This benchmark therefore runs
with ``OPENBLAS_NUM_THREADS=1`` unless the variable is already set (``OPENBLAS_NUM_THREADS=2 python -m
experiments.benchmarks.kalman`` shows the difference); the grid jobs should set it to 1 too.
"""

from __future__ import annotations

import argparse
import os
from functools import partial

import numpy as np

from experiments.benchmarks import blas_threads_now, median_seconds
from experiments.simulate.datasets import UG
from experiments.simulate.plant import build_plant
from methods.kalman import akf, wkf

__all__ = ["PRIOR", "DT_S", "TARGET_S", "REPLICATES", "main"]

PRIOR = [3.80, 16.00, 26.00, 46.00]     # Table 3
DT_S = 0.02
TARGET_S = 0.020                         # per 256-sample record and filter


REPLICATES = 100                         # a grid cell's records, run in lock-step by identify_batch


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--replicates", type=int, default=REPLICATES,
                        help="records of the lock-step batch (a cell's replicates)")
    args = parser.parse_args(argv)
    plant = build_plant()
    print(f"Kalman filters, 4 modes, dt = {DT_S} s, 10 ug noise, BLAS threads "
          f"{blas_threads_now()}, load average {os.getloadavg()[0]:.1f}")
    print(f"one record: filterpy's EKF per record (median of {args.repeats}); lock-step: identify_batch on "
          f"{args.replicates} records (noise seeds 0..{args.replicates - 1}; median of 3), its time per record")
    print(f"{'samples':>8} {'measurement':>13} {'method':>7} {'one ms':>8} {'lock-step ms':>13} {'speed-up':>9} "
          f"{'us/sample':>10}")
    at_256 = {}
    for n in (256, 2048):
        clean = plant.tip_acceleration(n, DT_S)
        ys = clean + 10 * UG * np.array([np.random.default_rng(i).standard_normal(n)
                                         for i in range(args.replicates)])
        for measurement in ("position", "acceleration"):
            for mod in (akf, wkf):
                one = partial(mod.identify, ys[0], DT_S, PRIOR, measurement=measurement)
                for _ in range(3):                                              # warm-up (imports, caches)
                    one()
                t_one = median_seconds(one, args.repeats)
                t_batch = median_seconds(partial(mod.identify_batch, ys, DT_S, PRIOR, measurement=measurement),
                                         3) / args.replicates
                ran = one().iterations
                note = "" if ran == n else f"  (record 0: {ran} samples before divergence)"
                name = mod.__name__.rsplit(".", 1)[1]
                print(f"{n:>8} {measurement:>13} {name:>7} {1e3 * t_one:>8.2f} {1e3 * t_batch:>13.3f} "
                      f"{t_one / t_batch:>9.1f} {1e6 * t_one / ran:>10.1f}{note}")
                if n == 256 and measurement == "position":
                    at_256[name] = (t_one, t_batch)
    for name, (t_one, t_batch) in at_256.items():
        print(f"256 samples, paper default (position), {name}: {1e3 * t_one:.1f} ms one at a time = "
              f"{t_one / TARGET_S:.2f} x the {1e3 * TARGET_S:.0f} ms target; {1e3 * t_batch:.2f} ms per record "
              f"in lock-step")


if __name__ == "__main__":
    from experiments.benchmarks import one_blas_thread, run_with_page

    with one_blas_thread():
        raise SystemExit(run_with_page(main, "kalman"))   # prints, and writes results/bench/kalman.md
