"""One pulsed cell of ``tracking_unseen --set grid-rate --records pulses``, for chosen seeds: the piecewise
Cramér–Rao bound of the window after the step, ``gated_pencil``'s re-convergence and which mode holds it — a
development script, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_pulse_cell_dev.py SEEDS [--cell "step +5/−5/0/+8 % at 40 s, 150 N·m every 10 s"]
        [--replicates 2] [--trackers next_era,gated_pencil,gated_pencil:key=value] [--periods 5,10,20] [--trace]

    python tests/methods/tracking/dev/_pulse_cell_dev.py SEEDS --set {unseen-grid,unseen-other,beats,beats-thr,anyrate}
        --trackers next_era,gated_pencil,gated_pencil:key=value    # every record of a set, the rows side by side

The records are the benchmark's own (``tracking_unseen.configs``, ``make_cell`` without its bounds) and every
track is scored by its scorer (``tracking_metrics.score_record``); "periods" are of the slowest mode after the
step. The bound (``_close_modes_crlb.piecewise_crlb``): the window [step + 1, step + 1 + N), N samples = that
many periods of the slowest mode after the step, is between the record's pulses a free decay; ω and ζ shared by
the pulse-free runs (≥ 2(2m + 1) samples), each run its own amplitudes, phases and offset, the amplitudes those
of the noise-free record, σ the record's noise. Per mode it also prints when the track last left 1 % (the mode
that holds the re-convergence) and, with ``--trace``, the windows of that mode after the step.
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[2]), str(Path(__file__).resolve().parent),
                str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _close_modes_crlb import piecewise_crlb  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks import tracking_unseen as tu  # noqa: E402
from experiments.benchmarks.tracking_cpu import parse_row  # noqa: E402
from experiments.report import tracking_metrics  # noqa: E402
from experiments.simulate.tracking_data import make_cell  # noqa: E402
from methods.tracking import _segments  # noqa: E402

CELL = "step +5/−5/0/+8 % at 40 s, 150 N·m every 10 s, 700 µg"


def step_cell(cfg) -> tuple[dict, float, float, np.ndarray, float]:
    """A step cell of ``cfg`` without its bounds: the cell, Δt, the step's time, the frequencies just after the
    step and the slowest period there."""
    cell = make_cell(cfg, bounds=False)
    dt = float(cell["dt_s"])
    st = float(cell["step_time_s"])
    w_after = cell["truth_freq_rad_s"][int(round(st / dt))]
    return cell, dt, st, w_after, 2 * np.pi / w_after.min()


def bound(cell: dict, r: int, periods: float) -> np.ndarray:
    """2σ/ω of every mode from the window of ``periods`` periods after the step (module docstring)."""
    dt = float(cell["dt_s"])
    truth = cell["truth_freq_rad_s"]
    s = int(round(float(cell["step_time_s"]) / dt))
    w = truth[s]
    m = w.size
    n = truth.shape[0]
    stop = min(n, s + 1 + int(round(periods * 2 * np.pi / w.min() / dt)))
    pulses = np.flatnonzero(np.any(cell["inputs"][r] != 0, axis=1))
    flags = np.zeros(stop - s - 1, dtype=bool)
    inside = pulses[(pulses > s) & (pulses < stop)] - s - 1
    flags[inside] = True
    runs = [(a + s + 1, b + s + 1) for a, b in _segments.segments(flags, 2 * (2 * m + 1))]
    sd = piecewise_crlb(cell["accel_clean_m_s2"][r], dt, w, np.asarray(cell["truth_damping"]), runs,
                        float(cell["noise_std_m_s2"]))
    return 2 * sd / w, inside.size


def last_out(tr, cell: dict) -> np.ndarray:
    """Per mode, the time after the step from which the track stays within 1 % to the end (s; inf: never)."""
    dt = float(cell["dt_s"])
    truth = cell["truth_freq_rad_s"]
    k = np.round(tr.t_s / dt).astype(int)
    rel = np.abs(tr.frequencies / truth[k] - 1)
    st = float(cell["step_time_s"])
    after = tr.t_s >= st
    out = []
    for i in range(truth.shape[1]):
        bad = after & ~(rel[:, i] <= tracking_metrics.TOL)
        out.append(np.inf if bad[-1] else (tr.t_s[np.flatnonzero(bad)[-1] + 1] - st if bad.any() else 0.0))
    return np.asarray(out)


def trace(tr, cell: dict, mode: int, until_s: float) -> None:
    """The windows of ``mode`` from the step to ``until_s`` after it: raw estimate, std, determined, output."""
    dt = float(cell["dt_s"])
    truth = cell["truth_freq_rad_s"]
    st = float(cell["step_time_s"])
    ends = tr.extra["window_end_sample"]
    for j, e in enumerate(ends):
        t = e * dt
        if not st <= t <= st + until_s + 5:
            continue
        w = truth[e, mode]
        raw, sd = tr.extra["window_frequencies"][j, mode], tr.extra["window_std"][j, mode]
        print(f"    t-step {t - st:6.2f}  window {100 * (raw / w - 1):+7.3f} % ± {100 * sd / w:6.3f} %  "
              f"det {int(tr.extra['window_converged'][j, mode])}  out {100 * (tr.frequencies[j, mode] / w - 1):+7.3f} %"
              f"  kept {tr.extra['columns_kept'][j]:.2f}  span {tr.extra['window_span_s'][j]:.1f} s  others "
              f"{np.round(100 * (tr.extra['window_frequencies'][j] / truth[e] - 1), 2)}")


def compare(which: str, seeds: list[int], replicates: int, specs: list[str]) -> None:
    """Every record of a set (``_trend_restart_ab.records``: the benchmarks' records and scorers), each row of
    ``specs`` on it; the benchmarks' medians over replicates (anyrate: per record)."""
    import pandas as pd
    from _trend_restart_ab import records

    rows = []
    for seed in seeds:
        for cell, r, y, dt, prior, score in records(which, seed, replicates):
            for spec in specs:
                name, opts = parse_row(spec)
                rows.append({"cell": f"{cell[:48]} ({seed})", "tracker": spec, "r": r,
                             **score(methods.track(name, y, dt, prior, **opts))})
    df = pd.DataFrame(rows)
    pd.set_option("display.width", 250)
    pd.set_option("display.max_rows", 500)
    if which == "anyrate":
        print(df.pivot(index="cell", columns="tracker", values=["error", "within", "reconv_median"]).to_string())
        return
    from experiments.benchmarks.tracking_beats import summary
    s = summary(df)
    cols = ["cell", "tracker", "err_rel_median", "ratio", "err_rel_median_late", "share_within_1pct",
            "t_reconverge_s", "reconverge_periods", "never_converged_rate"]
    print(s[[c for c in cols if c in s]].to_string())


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--set", default="")
    parser.add_argument("seeds")
    parser.add_argument("--cell", default=CELL)
    parser.add_argument("--replicates", type=int, default=2)
    parser.add_argument("--trackers", default="next_era,gated_pencil")
    parser.add_argument("--periods", default="5,10,20")
    parser.add_argument("--no-bound", action="store_true")
    parser.add_argument("--trace", action="store_true")
    args = parser.parse_args(argv)
    periods = [float(p) for p in args.periods.split(",")]
    from threadpoolctl import threadpool_limits
    summary = {}
    if args.set:
        with threadpool_limits(limits=1):
            compare(args.set, [int(x) for x in args.seeds.split(",")], args.replicates,
                    [t for t in args.trackers.split(",") if t])
        return
    with threadpool_limits(limits=1):
        for seed in (int(s) for s in args.seeds.split(",")):
            cfgs = tu.configs(seed, args.replicates, records="pulses")
            label = next(k for k in cfgs if k.startswith(args.cell))
            cell, dt, st, w_after, period = step_cell(cfgs[label])
            for r in range(args.replicates):
                print(f"seed {seed}, replicate {r}: ω after the step {np.round(w_after, 2)}, prior "
                      f"{np.round(cell['prior_rad_s'][r], 2)}", flush=True)
                if not args.no_bound:
                    for p in periods:
                        rel, npulse = bound(cell, r, p)
                        print(f"  bound, {p:g} periods ({npulse} pulses): 2σ/ω % {np.round(100 * rel, 3)}")
                for spec in filter(None, args.trackers.split(",")):
                    name, opts = parse_row(spec)
                    tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
                    sc = tracking_metrics.score_record(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, cell, r)
                    lo = last_out(tr, cell)
                    summary.setdefault(spec, []).append(sc["t_reconverge_s"] / period)
                    print(f"  {spec}: error {100 * sc['err_rel_median']:.3f} %, re-converge "
                          f"{sc['t_reconverge_s']:.2f} s = {sc['t_reconverge_s'] / period:.1f} periods; per mode "
                          f"within 1 % from {np.round(lo, 1)} s", flush=True)
                    if args.trace and name == "gated_pencil" and np.isfinite(lo).any():
                        mode = int(np.argmax(np.where(np.isfinite(lo), lo, 1e9)))
                        trace(tr, cell, mode, float(min(lo[mode], 80.0)))
    for spec, v in summary.items():
        v = np.asarray(v)
        print(f"{spec}: periods per replicate {np.round(v, 1)}; median {np.nanmedian(v):.1f}, over 10: "
              f"{int(np.sum(~(v <= 10)))} of {v.size}")


if __name__ == "__main__":
    main()
