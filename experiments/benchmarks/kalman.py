"""Time of the augmented (akf) and frequency-weighted (wkf) Kalman filters: median wall time per record.

    python -m experiments.benchmarks.kalman [--repeats 21]

Records: the truth plant's tip acceleration + 10 µg noise at Δt = 0.02 s, Table 3 priors, the paper's
tuning (methods defaults), for both measurement models. Target: ≲ 20 ms per 256-sample record per filter
(the full grid: 100 replicates × up to 2048 samples per cell on 2 cores).

BLAS threads: the filters multiply 15×15–17×17 matrices every sample; OpenBLAS runs such products on
several threads, which on a busy 2-core machine makes them 3–5× slower. This benchmark therefore runs
with ``OPENBLAS_NUM_THREADS=1`` unless the variable is already set (``OPENBLAS_NUM_THREADS=2 python -m
experiments.benchmarks.kalman`` shows the difference); the grid jobs should set it to 1 too.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS; see the docstring

import argparse  # noqa: E402
from functools import partial  # noqa: E402

import numpy as np  # noqa: E402

from experiments.benchmarks import median_seconds  # noqa: E402
from experiments.simulate.datasets import UG  # noqa: E402
from experiments.simulate.plant import build_plant  # noqa: E402
from methods import akf, wkf  # noqa: E402

PRIOR = [3.80, 16.00, 26.00, 46.00]     # Table 3
DT_S = 0.02
TARGET_S = 0.020                         # per 256-sample record and filter


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=21)
    args = parser.parse_args(argv)
    plant = build_plant()
    rng = np.random.default_rng(1)
    print(f"Kalman filters, 4 modes, dt = {DT_S} s, 10 ug noise, median of {args.repeats} runs, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')}")
    print(f"{'samples':>8} {'measurement':>13} {'akf ms':>8} {'wkf ms':>8} {'wkf/akf':>8} "
          f"{'akf us/sample':>14} {'wkf us/sample':>14}")
    at_256 = {}
    for n in (256, 2048):
        y = plant.tip_acceleration(n, DT_S) + 10 * UG * rng.standard_normal(n)
        for measurement in ("position", "acceleration"):
            for _ in range(3):                                              # warm-up (imports, caches)
                akf.identify(y, DT_S, PRIOR, measurement=measurement)
            ta = median_seconds(partial(akf.identify, y, DT_S, PRIOR, measurement=measurement), args.repeats)
            tw = median_seconds(partial(wkf.identify, y, DT_S, PRIOR, measurement=measurement), args.repeats)
            ran = [mod.identify(y, DT_S, PRIOR, measurement=measurement).iterations for mod in (akf, wkf)]
            note = "" if min(ran) == n else f"  (filtered {ran[0]} / {ran[1]} samples before divergence)"
            print(f"{n:>8} {measurement:>13} {1e3 * ta:>8.2f} {1e3 * tw:>8.2f} {tw / ta:>8.2f} "
                  f"{1e6 * ta / ran[0]:>14.1f} {1e6 * tw / ran[1]:>14.1f}{note}")
            if n == 256:
                at_256[measurement] = (ta, tw)
    ta, tw = at_256["position"]
    print(f"256 samples, paper default (position): akf {1e3 * ta:.1f} ms = {ta / TARGET_S:.2f} x, "
          f"wkf {1e3 * tw:.1f} ms = {tw / TARGET_S:.2f} x the {1e3 * TARGET_S:.0f} ms target")


if __name__ == "__main__":
    main()
