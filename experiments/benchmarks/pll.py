"""Time of the four-loop PLL bank: median wall time per record and per sample.

    python -m experiments.benchmarks.pll [--repeats 21]

Records: the truth plant's tip acceleration + 1000 µg noise at Δt = 0.02 s, with the paper's settings
(the options of configs/method/pll.yaml: Table 6, input filters). Also the bank without input filters, to show what the
filters (scipy.signal.sosfilt, outside the per-sample loop) cost. Target: ≲ 50 ms per 2048-sample record.
"""

from __future__ import annotations

import argparse
from functools import partial

import numpy as np
from omegaconf import OmegaConf

from experiments import paths
from experiments.benchmarks import median_seconds
from experiments.simulate.datasets import UG
from experiments.simulate.plant import build_plant
from methods import pll

__all__ = ["PRIOR", "PAPER_OPTIONS", "DT_S", "TARGET_S", "main"]

_CONFIG = OmegaConf.load(paths.METHOD_CONFIGS / "pll.yaml")
PRIOR = list(_CONFIG.prior_rad_s)                     # Table 6
PAPER_OPTIONS = OmegaConf.to_container(_CONFIG.options)
DT_S = 0.02
TARGET_S = 0.050                         # per 2048-sample record, for the 100-replicate grid on 2 cores


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=21)
    args = parser.parse_args(argv)
    plant = build_plant()
    rng = np.random.default_rng(1)
    print(f"PLL bank, {len(PRIOR)} loops, dt = {DT_S} s, median of {args.repeats} runs")
    print(f"{'samples':>8} {'filters':>8} {'ms/record':>10} {'us/sample':>10} {'us/sample/loop':>15}")
    for n in (256, 2048):
        y = plant.tip_acceleration(n, DT_S) + 1000 * UG * rng.standard_normal(n)
        pll.identify(y, DT_S, PRIOR, **PAPER_OPTIONS)       # warm-up (imports, caches)
        for filters in (True, False):
            t = median_seconds(partial(pll.identify, y, DT_S, PRIOR, **(PAPER_OPTIONS | {"input_filter": filters})),
                               args.repeats)
            print(f"{n:>8} {str(filters):>8} {1e3 * t:>10.2f} {1e6 * t / n:>10.2f} "
                  f"{1e6 * t / n / len(PRIOR):>15.2f}")
            if n == 2048 and filters:
                full = t
    print(f"2048-sample record with filters: {1e3 * full:.1f} ms = {full / TARGET_S:.2f} x the "
          f"{1e3 * TARGET_S:.0f} ms target")


if __name__ == "__main__":
    from experiments.benchmarks import run_with_page

    raise SystemExit(run_with_page(main, "pll"))   # prints, and writes results/bench/pll.md
