"""A look sized from the prior's closest gap: does a long window place the close pair better than
``rpem_ambient:two`` does by then? — a development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_pair_window_dev.py SEED[,SEED…] [--bins 4,6,8] [--cache DIR]

On the white-force records (no slosh, no pulses) of ``tracking_ambient`` and ``tracking_unseen``, 2 replicates:
for each replicate the window T = c·2π/g (g the smallest gap between neighbouring priors, c of ``--bins``: the
pair c bins apart) from the record's start, its Hann periodogram peaks (``_ambient.periodogram_look``, the
pair rule on) against the truth at the window's middle, beside ``rpem_ambient:two``'s error at T, on the two
modes of that closest prior pair. Per c: how many replicates the long look places the pair better (its larger
|error| at least 0.5 % of ω smaller than the tracker's), worse (0.5 % larger, or no peak), or alike.
"""

import argparse
import math
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import VARIANT_TWO as TWO  # noqa: E402
from _cells import white_cells  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from methods.tracking import _ambient  # noqa: E402

MARGIN = 0.5    # % of ω
REPLICATES = 2


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seeds")
    ap.add_argument("--bins", default="4,6,8")
    ap.add_argument("--cache", default=None)
    args = ap.parse_args()
    bins = [int(c) for c in args.bins.split(",")]
    name, opts = parse_row(TWO)
    tally = {c: [0, 0, 0] for c in bins}
    for which in ("ambient", "unseen"):
        for seed in (int(s) for s in args.seeds.split(",")):
            for label, _, cell in white_cells(which, seed, REPLICATES, args.cache):
                dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
                for r in range(cell["accel_m_s2"].shape[0]):
                    y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
                    i = int(np.argmin(np.diff(prior)))
                    pair = [i, i + 1]
                    tr = methods.track(name, y, dt, prior, **opts)
                    row = []
                    for c in bins:
                        n = int(round(c * 2 * math.pi / (prior[i + 1] - prior[i]) / dt))
                        if n > y.size:
                            row.append(f"c{c} longer than the record")
                            continue
                        peak, *_ = _ambient.periodogram_look(y[:n], dt, prior, 0.1, 0.005, pair_edges=True)
                        e_look = 100 * (peak[pair] / truth[n // 2, pair] - 1)
                        j = min(np.searchsorted(tr.t_s, n * dt), tr.t_s.size - 1)
                        e_trk = 100 * (tr.frequencies[j, pair] / truth[n - 1, pair] - 1)
                        a, b = np.max(np.abs(e_look)), np.max(np.abs(e_trk))
                        k = 0 if a < b - MARGIN else 1 if (not np.isfinite(a) or a > b + MARGIN) else 2
                        tally[c][k] += 1
                        row.append(f"c{c} T {n * dt:5.1f} s look " + "/".join(f"{x:+.1f}" for x in e_look)
                                   + " tracker " + "/".join(f"{x:+.1f}" for x in e_trk))
                    print(f"{which[:3]} {seed} {label[:40]:40s} r{r} modes {i + 1},{i + 2} | " + " | ".join(row),
                          flush=True)
    for c in bins:
        print(f"c = {c}: the long look better on {tally[c][0]}, worse on {tally[c][1]}, alike on {tally[c][2]}")


if __name__ == "__main__":
    main()
