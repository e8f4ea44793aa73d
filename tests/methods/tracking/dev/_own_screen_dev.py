"""Whether ``own_windows``' screen (``_gated_pencil.OWN_SCREEN_STD``) leaves every track as it is — a development
script, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_own_screen_dev.py {unseen-grid,unseen-other,beats,beats-thr,anyrate} SEEDS R

Every record of the set (``_trend_restart_ab.records``) tracked by ``gated_pencil:own_windows=true`` with the
screen off (``None``: every watched short window fitted) and on (1.0); prints the records whose tracks differ,
the count of identical ones and the CPU of each.
"""

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parent), str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _trend_restart_ab import records  # noqa: E402

import methods  # noqa: E402
from methods.tracking import _gated_pencil as gp  # noqa: E402


def main(argv=None):
    which, seeds, replicates = (argv or sys.argv[1:])[:3]
    seeds = [int(s) for s in seeds.split(",")]
    n = same = 0
    cpu = [0.0, 0.0]
    for seed in seeds:
        for cell, r, y, dt, prior, _ in records(which, seed, int(replicates)):
            tracks = []
            for k, screen in enumerate((None, 1.0)):
                gp.OWN_SCREEN_STD = screen
                t0 = time.process_time()
                tracks.append(methods.track("gated_pencil", y, dt, prior, own_windows=True))
                cpu[k] += time.process_time() - t0
            n += 1
            if np.array_equal(tracks[0].frequencies, tracks[1].frequencies, equal_nan=True):
                same += 1
            else:
                rel = np.nanmax(np.abs(tracks[1].frequencies / tracks[0].frequencies - 1))
                print(f"differs: {cell} ({seed}/{r}), largest relative difference {rel:.2e}")
    print(f"{which} {seeds}: {same} of {n} tracks identical; CPU {cpu[0]:.1f} s -> {cpu[1]:.1f} s")


if __name__ == "__main__":
    main()
