"""The Bayesian yardstick of a grid's cells, one table (experiments.simulate.yardstick).

    python -m experiments.jobs.yardstick --prior-rad-s 2.65 16.73 17.32 52.91 \\
        --prior-std-rad-s 0.795 5.019 5.196 15.873 --out results/paper/yardstick.csv -- results/paper/data/*.npz

The workflow's ``yardstick`` rule runs it on a grid whose file names ``yardstick_prior`` (the prior is that
method config's ``prior_rad_s`` and ``options.prior_std_rad_s``); the aggregate step puts its columns into the
comparison table. Cells with a scenario axis (their own priors or plant) are skipped. Bad input: one line
``error: ...``, exit status 2, nothing written.

The rule starts it with glibc's malloc tunables, ``GLIBC_TUNABLES=glibc.malloc.mmap_threshold=33554432:
glibc.malloc.trim_threshold=268435456`` (glibc then keeps the SMC's freed arrays instead of returning them to the
kernel: ~15–20 % less CPU, the same bytes; docs/notes/sweep-cost.md, fifth pass); by hand, set them the same way.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from experiments.cli import ArgumentParser  # noqa: E402
from experiments.io import check_writable, read_npz, write_table  # noqa: E402
from experiments.simulate import yardstick  # noqa: E402

__all__ = ["REQUIRED", "main"]

REQUIRED = ("t_s", "accel_m_s2", "dt_s", "noise_ug", "noise_std_m_s2", "seed", "truth_freq_rad_s",
            "truth_damping", "truth_amplitude_m_s2", "truth_phase_rad", "crlb_std_rad_s")


def main(argv=None) -> int:
    ap = ArgumentParser(prog="experiments.jobs.yardstick", description=__doc__.splitlines()[0])
    ap.add_argument("--prior-rad-s", nargs="+", type=float, required=True, help="prior means, rad/s")
    ap.add_argument("--prior-std-rad-s", nargs="+", type=float, required=True, help="prior 1σ per mode, rad/s")
    ap.add_argument("--particles", type=int, default=yardstick.PARTICLES, help="particles per SMC run")
    ap.add_argument("--loose", type=float, default=yardstick.LOOSE,
                    help="the posterior mean is computed where CRLB > this × the prior's 1σ")
    ap.add_argument("--out", required=True, type=Path, help="the table to write (.csv; .md beside it)")
    ap.add_argument("cells", nargs="+", type=Path, help="dataset files of the cells (.npz)")
    args = ap.parse_args(argv)
    mu, s = np.asarray(args.prior_rad_s), np.asarray(args.prior_std_rad_s)
    try:
        if mu.size != s.size or not (np.all(np.isfinite(mu)) and np.all(mu > 0)):
            raise ValueError(f"--prior-rad-s {mu.tolist()} must be positive, one per mode of --prior-std-rad-s")
        if not (np.all(np.isfinite(s)) and np.all(s > 0)):
            raise ValueError(f"--prior-std-rad-s {s.tolist()} must be positive")
        if args.particles < 10:
            raise ValueError(f"--particles {args.particles} must be at least 10")
        if not (np.isfinite(args.loose) and args.loose > 0):
            raise ValueError(f"--loose {args.loose} must be positive")
        if args.out.suffix != ".csv":
            raise ValueError(f"--out {args.out} must be a .csv file")
        check_writable(args.out, "--out")
        cells = []
        for path in args.cells:
            cell = read_npz(path, required=REQUIRED)
            if "scenario_json" in cell:
                continue
            if cell["truth_freq_rad_s"].size != mu.size:
                raise ValueError(f"{path}: {cell['truth_freq_rad_s'].size} modes, the prior {mu.size}")
            cells.append(cell)
    except (OSError, ValueError) as exc:
        print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    rows = []
    for cell in cells:
        rows += yardstick.cell_rows(cell, mu, s, particles=args.particles, loose=args.loose)
    table = pd.DataFrame(rows, columns=yardstick.COLUMNS).sort_values(["noise_ug", "n_samples", "mode"])
    write_table(table, args.out.with_suffix(""))
    print(f"wrote {args.out}: {len(cells)} cells, {int(table['loose'].sum())} loose (cell, mode) pairs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
