"""The close pair's first look: the Hann periodogram's peaks against a parametric look (NExT + ERA, as
``next_era``) on the same window — a development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_era_look_dev.py SEED [--set ambient|unseen] [--replicates 2] [--cache DIR]

On every white-force record (no slosh, no thruster pulses) of ``tracking_ambient`` or ``tracking_unseen --records
ambient``, per replicate: the relative error (%) of each mode's estimate on the first window (W = five periods of
the slowest prior mode; the truth at the window's middle) from ``_ambient.periodogram_look`` (the start of
``rpem_ambient``) and from ``_next_era.era_look`` (NExT + ERA); on a step record also on the first window wholly
after the step (looks referenced to the truth before the step, as the tracker's estimate would be).
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import cached_cell  # noqa: E402

from experiments.benchmarks import tracking_ambient, tracking_unseen  # noqa: E402
from methods.tracking import _ambient, _next_era  # noqa: E402
from methods.tracking._rpem import Options as _rpem_options  # noqa: E402


def white(cfg) -> bool:
    return (not cfg.schedule.slosh and cfg.excitation.disturbance_force_n > 0
            and cfg.excitation.thruster_torque_n_m == 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("--set", default="ambient", choices=("ambient", "unseen"))
    ap.add_argument("--replicates", type=int, default=2)
    ap.add_argument("--cache", default=None)
    ap.add_argument("--extra-order", type=int, default=3)
    ap.add_argument("--lags-fraction", type=float, default=0.5)
    args = ap.parse_args()
    cfgs = (tracking_ambient.configs(args.seed, args.replicates) if args.set == "ambient"
            else tracking_unseen.configs(args.seed, args.replicates, records="ambient"))
    opts = _rpem_options()
    for i, (label, cfg) in enumerate(cfgs.items()):
        if not white(cfg):
            continue
        cell = cached_cell(cfg, args.cache, f"{args.set}_{args.seed}_{args.replicates}_{i}")
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        st = float(cell["step_time_s"])
        for r in range(args.replicates):
            y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
            W, _ = _ambient._window_samples(opts, dt, prior)
            starts = [(0, prior, "first")]
            if np.isfinite(st):
                k0 = int(np.ceil(st / dt)) + 1
                starts.append((k0, truth[k0 - 2], "step "))
            for k0, ref, what in starts:
                seg = y[k0:k0 + W]
                true = truth[k0 + W // 2]
                pk = _ambient.periodogram_look(seg, dt, ref, opts.band, opts.damping_ratio)[0]
                era = _next_era.era_look(seg, dt, ref, opts.band, extra_order=args.extra_order,
                                         lags_fraction=args.lags_fraction)
                ep, ee = 100 * (pk - true) / true, 100 * (era - true) / true
                print(f"{args.set} {args.seed} r{r} {what} | {label:42s} | per % "
                      + " ".join(f"{x:+6.2f}" for x in ep) + " | era % " + " ".join(f"{x:+6.2f}" for x in ee)
                      + " | ref % " + " ".join(f"{x:+6.2f}" for x in 100 * (ref - true) / true),
                      flush=True)


if __name__ == "__main__":
    main()
