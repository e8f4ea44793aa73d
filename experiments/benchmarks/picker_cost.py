"""What the mode picker's confirmation by the record costs each peer: median time per fit with and without it.

    python -m experiments.benchmarks.picker_cost                    # writes results/bench/picker_cost.md
    python -m experiments.benchmarks.picker_cost --n-samples 32 256 --repeats 11 --methods era lsce

The paper plant's tip acceleration (PHYSICS.md §3) at ``--noise-ug`` (1000) µg, Δt = 0.02 s, each peer's config
prior (Table 3's a-priori frequencies); per N one record (seed ``--seed``, 3). Each peer identifies it with
``confirm`` true and false, the two calls interleaved in every round
(:func:`experiments.benchmarks.interleaved_medians`), and the table gives both medians, their ratio and how many
modes each call determines. The check is step 4 of the picker (methods/peers/README.md); its effect on which
modes are determined is measured by ``experiments.benchmarks.basin``.
"""

from __future__ import annotations

import argparse
import functools
import sys

import numpy as np
import yaml

import methods
from experiments.benchmarks import interleaved_medians
from experiments.benchmarks.basin import METHOD_DIR, method_options
from experiments.simulate.plant import PlantConfig, build_plant

__all__ = ["PEERS", "main"]

PEERS = ["era", "hdmd", "n4sid", "ssi_cov", "ssi_data", "lsce", "bopdmd"]
DT_S = 0.02
UG = 9.80665e-6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--methods", nargs="+", default=PEERS)
    ap.add_argument("--n-samples", type=int, nargs="+", default=[32, 256, 1024])
    ap.add_argument("--noise-ug", type=float, default=1000.0)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args(argv)
    bad = [m for m in args.methods if m not in PEERS]
    if bad or args.repeats < 1 or min(args.n_samples) < 8 or args.noise_ug < 0:
        print(f"error: methods {bad or args.methods} must be peers ({', '.join(PEERS)}); --repeats ≥ 1, "
              f"--n-samples ≥ 8 and --noise-ug ≥ 0 are required", file=sys.stderr)
        return 2
    plant = build_plant(PlantConfig())
    print("| method | N | with check, ms | without, ms | ratio | modes determined (with / without) |")
    print("|---|---|---|---|---|---|")
    for n in args.n_samples:
        rng = np.random.default_rng([args.seed, n])
        y = plant.tip_acceleration(n, DT_S) + args.noise_ug * UG * rng.standard_normal(n)
        for name in args.methods:
            identify, options = methods.get(name), method_options(name)
            prior = yaml.safe_load((METHOD_DIR / f"{name}.yaml").read_text())["prior_rad_s"]
            runs = {on: functools.partial(identify, y, DT_S, prior, **options | {"confirm": on})
                    for on in (True, False)}
            med = interleaved_medians(runs, args.repeats)
            det = {on: int(np.sum(runs[on]().converged_per_mode)) for on in runs}
            print(f"| {name} | {n} | {1e3 * med[True]:.2f} | {1e3 * med[False]:.2f} | "
                  f"{med[True] / med[False]:.2f} | {det[True]} / {det[False]} |")
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import one_blas_thread, run_with_page

    with one_blas_thread():
        raise SystemExit(run_with_page(main, "picker_cost"))   # prints, and writes results/bench/picker_cost.md
