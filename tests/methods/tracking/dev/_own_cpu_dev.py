"""CPU per sample of ``gated_pencil`` rows on a pulsed and a white-force record, side by side — a development
script, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_own_cpu_dev.py [--trackers gated_pencil,gated_pencil:own_windows=true]
        [--repeats 5] [--seed 7]

Records: ``tracking_cpu``'s (the truth plant re-excited by a thruster pulse every 10 s, 3000 samples) and
``tracking_beats``' white body force (schedule "drift", 100 µg, 120 s, replicate 0 of ``--seed``). The rows run
interleaved, one run of each per repeat, so that a change of the machine's load reaches them alike; per row and
record the median of ``Track.runtime_s`` over the repeats, per sample.
"""

import argparse
import os
import statistics
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import EXCITATIONS, SCHEDULES  # noqa: E402
from experiments.benchmarks.tracking_cpu import DT_S, PRIOR, parse_row, pulsed_record  # noqa: E402
from experiments.simulate.tracking_data import TrackingCellConfig, make_cell  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--trackers", default="gated_pencil,gated_pencil:own_windows=true")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args(argv)
    cell = make_cell(TrackingCellConfig(schedule=SCHEDULES["drift"], excitation=EXCITATIONS["disturbance"],
                                        noise_ug=100.0, duration_s=120.0, replicates=1, seed=args.seed),
                     bounds=False)
    records = {"pulsed (tracking_cpu)": (pulsed_record(3000), DT_S, PRIOR),
               "white force (beats drift, 100 µg)": (cell["accel_m_s2"][0], 0.02, cell["prior_rad_s"][0])}
    specs = [s for s in args.trackers.split(",") if s]
    times = {(rec, s): [] for rec in records for s in specs}
    for _ in range(args.repeats):
        for rec, (y, dt, prior) in records.items():
            for spec in specs:
                name, opts = parse_row(spec)
                times[(rec, spec)].append(methods.track(name, y, dt, prior, **opts).runtime_s / y.size)
    print(f"load average {os.getloadavg()[0]:.1f}; median of {args.repeats} interleaved runs, µs per sample")
    for (rec, spec), v in times.items():
        print(f"  {rec:36s} {spec:40s} {1e6 * statistics.median(v):7.1f}  (range {1e6 * min(v):.1f}–"
              f"{1e6 * max(v):.1f})")


if __name__ == "__main__":
    main()
