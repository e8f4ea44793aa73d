"""CPU time per sample of every tracker (``methods.track``), and whether it would fly.

    python -m experiments.benchmarks.tracking_cpu [--samples 3000] [--repeats 3] [--trackers akf,pem,...]

A row of ``--trackers`` is a tracker name or a variant ``name:key=value+key=value`` (``pem:predictor=kalman``).

Record: the truth plant's free decay (Table 2's release, Table 3's frequencies) re-excited by a thruster
pulse every 10 s — the superposition of the same decay started at each pulse, with an amplitude drawn per
pulse — plus 100 µg of white noise, at Δt = 0.02 s; Table 3's priors; each tracker's default options (the
windowed ones: a 512-sample window every 50 samples). A stand-in for the tracking scenarios: a tracker's cost
depends on the record's length and its own settings, little on the schedule.

Per tracker: the median over ``--repeats`` runs of ``Track.runtime_s`` (``time.process_time`` of the whole
call), divided by the samples; ×100 answers the on-board question "fits in 20 ms per sample on a processor
100× slower?" (CPU/sample × 100 ≤ 20 ms). A tracker whose first run takes over ``--budget-s`` is not
repeated. The machine is shared: the figures are noisy (the load average is printed with them).
Writes results/bench/tracking_cpu.md.
"""

from __future__ import annotations

import argparse
import os
import statistics
from pathlib import Path

import numpy as np

import methods
from experiments.benchmarks import blas_threads_now, run_tracker_command
from experiments.io import atomic_write_text
from experiments.simulate.datasets import UG
from experiments.simulate.plant import build_plant
from experiments.tracker_variants import variant_options

__all__ = ["PRIOR", "DT_S", "PULSE_EVERY_S", "NOISE_UG", "ON_BOARD_BUDGET_S", "SLOWDOWN", "OUT", "pulsed_record",
           "parse_row", "default_rows", "measure", "markdown", "main"]

PRIOR = [3.80, 16.00, 26.00, 46.00]      # Table 3
DT_S = 0.02
PULSE_EVERY_S = 10.0
NOISE_UG = 100.0
ON_BOARD_BUDGET_S = 0.020                 # per sample, on a processor SLOWDOWN× slower
SLOWDOWN = 100.0
OUT = Path("results/bench/tracking_cpu.md")


def pulsed_record(n: int, seed: int = 0) -> np.ndarray:
    """The plant's free decay restarted by a pulse every PULSE_EVERY_S, random amplitudes, + noise."""
    rng = np.random.default_rng(seed)
    decay = build_plant().tip_acceleration(n, DT_S)
    y = np.zeros(n)
    for start in range(0, n, int(round(PULSE_EVERY_S / DT_S))):
        y[start:] += rng.uniform(0.3, 1.0) * rng.choice([-1.0, 1.0]) * decay[: n - start]
    return y + NOISE_UG * UG * rng.standard_normal(n)


def parse_row(spec: str) -> tuple[str, dict]:
    """``name``, ``name:key=value+...`` (those options over the tracker's defaults) or ``name:variant`` (the
    options of ``configs/tracker/<name>_<variant>.yaml``, ``experiments.tracker_variants``)."""
    name, _, rest = spec.partition(":")
    if rest and "=" not in rest:
        return name, variant_options(spec)
    options = {}
    for item in filter(None, rest.split("+")):
        key, _, value = item.partition("=")
        for cast in (int, float):
            try:
                value = cast(value)
                break
            except ValueError:
                pass
        options[key] = {"true": True, "false": False}.get(value, value) if isinstance(value, str) else value
    return name, options


def default_rows() -> list[str]:
    """Every tracker with its defaults, and pem with its second predictor (the innovation form, eq. 31)."""
    rows = methods.track_names()
    return rows[: rows.index("pem") + 1] + ["pem:predictor=kalman"] + rows[rows.index("pem") + 1:]


def measure(specs, y: np.ndarray, repeats: int, budget_s: float) -> list[dict]:
    rows = []
    for spec in specs:
        name, options = parse_row(spec)
        times, track = [], None
        for _ in range(repeats):
            track = methods.track(name, y, DT_S, PRIOR, **options)
            times.append(track.runtime_s)
            if track.runtime_s > budget_s:
                break
        cpu = statistics.median(times)
        per_sample = cpu / y.size
        rows.append({"tracker": spec, "runs": len(times), "cpu_s": cpu, "us_per_sample": 1e6 * per_sample,
                     "ms_per_sample_100x": 1e3 * SLOWDOWN * per_sample,
                     "fits": SLOWDOWN * per_sample <= ON_BOARD_BUDGET_S, "estimates": track.t_s.size,
                     "converged": float(track.converged.mean())})
        r = rows[-1]
        print(f"{spec:>20} {r['runs']:>4} {cpu:>8.3f} {r['us_per_sample']:>10.1f} {r['ms_per_sample_100x']:>10.2f} "
              f"{'yes' if r['fits'] else 'no':>5} {r['estimates']:>6} {r['converged']:>6.2f}", flush=True)
    return rows


def markdown(rows: list[dict], n: int, load: float) -> str:
    lines = [
        "# CPU time per sample of each tracker",
        "",
        f"`python -m experiments.benchmarks.tracking_cpu`: a {n}-sample record (Δt = {DT_S} s, thruster pulse "
        f"every {PULSE_EVERY_S:g} s, {NOISE_UG:g} µg noise), Table 3 priors, default options; median of "
        f"`Track.runtime_s` (process CPU time) over the runs. Load average at the start: {load:.1f} "
        "(shared machine: noisy figures).",
        "",
        f"Fits on board: CPU/sample × {SLOWDOWN:g} ≤ {1e3 * ON_BOARD_BUDGET_S:g} ms (a processor "
        f"{SLOWDOWN:g}× slower).",
        "",
        "| tracker | runs | CPU s | µs / sample | ms / sample at 100× slower | fits 20 ms? | estimates "
        "| share converged |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['tracker']} | {r['runs']} | {r['cpu_s']:.3f} | {r['us_per_sample']:.1f} | "
                     f"{r['ms_per_sample_100x']:.2f} | {'yes' if r['fits'] else 'no'} | {r['estimates']} | "
                     f"{r['converged']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--budget-s", type=float, default=30.0, help="a first run longer than this is not repeated")
    parser.add_argument("--trackers", default=",".join(default_rows()),
                        help="comma-separated rows: a tracker name, or name:key=value+key=value for a variant "
                             "(default: every tracker, and pem:predictor=kalman)")
    parser.add_argument("--out", default=str(OUT))
    args = parser.parse_args(argv)
    specs = [n for n in args.trackers.split(",") if n]
    for spec in specs:
        name, options = parse_row(spec)
        methods.check_track_options(name, PRIOR, DT_S, options, n_samples=args.samples)
    load = os.getloadavg()[0]
    y = pulsed_record(args.samples)
    print(f"trackers on {args.samples} samples, dt = {DT_S} s; load average {load:.1f}; "
          f"BLAS threads {blas_threads_now()}")
    print(f"{'tracker':>20} {'runs':>4} {'CPU s':>8} {'us/sample':>10} {'ms@100x':>10} {'fits':>5} {'K':>6} "
          f"{'conv':>6}")
    rows = measure(specs, y, args.repeats, args.budget_s)
    path = atomic_write_text(args.out, markdown(rows, args.samples, load))
    print(f"wrote {path}")


if __name__ == "__main__":
    run_tracker_command(main)
