"""``gated_pencil``'s trend stage, main's ``trend_restart_rate="keep"`` against ``"freeze"``, on the benchmarks'
own records and scorers — a development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_trend_restart_ab.py {unseen-other,unseen-grid,beats,beats-thr,anyrate} SEEDS
        [--replicates 2] [--option key=value ...]

Sets: ``tracking_unseen --set other-rates`` / ``--set grid-rate --records pulses`` (scored as that benchmark
scores them), ``tracking_beats``' eight cells (``beats``; ``beats-thr`` its four thruster cells), the development
table's records (``_anyrate_table.py``). Per record the windows are computed once (``methods.track`` with the
default, or with ``--option``s): the trend stage does not feed back into them, so main's ``"keep"`` is replayed on
the same windows (``TrendBank`` as ``gated_pencil`` feeds it) and the two rows differ by the trend stage alone.
Rows: ``next_era``, ``gated_pencil`` (as given), ``keep`` and ``freeze`` (its windows, replayed).
"""

import argparse
import dataclasses
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[2]), str(Path(__file__).resolve().parent),
                str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import methods  # noqa: E402
from methods.tracking import _gated_pencil, _trend  # noqa: E402


def replay(tr, prior, dt: float, restart_rate: str, options: dict):
    """``tr`` with its trend stage run again on its own windows with ``restart_rate``."""
    opts = _gated_pencil.resolve(_gated_pencil.make_options(_gated_pencil.Options, options, "gated_pencil"),
                                 "gated_pencil", prior, dt)
    W, H = opts.window_samples, opts.hop_samples
    f, d, ws = tr.extra["window_frequencies"], tr.extra["window_converged"], tr.extra["window_std"]
    bank = _trend.TrendBank(f.shape[1], **_trend.settings(opts, prior), restart_rate=restart_rate)
    out, conv = np.full(f.shape, np.nan), np.zeros(f.shape, bool)
    span = (W - 1) * dt
    for j, e in enumerate(tr.extra["window_end_sample"]):
        meas = np.sqrt(opts.overlap_inflation * max(1.0, W / H)) * ws[j]
        out[j], _, conv[j], _ = bank.step(e * dt - span / 2, span / 2, f[j], d[j], meas, ws[j])
    return dataclasses.replace(tr, frequencies=out, converged=conv)


def rows_of(y, dt: float, prior, options: dict) -> dict:
    prior = np.asarray(prior, dtype=float)
    tr = methods.track("gated_pencil", y, dt, prior, **options)
    return {"next_era": methods.track("next_era", y, dt, prior), "gated_pencil": tr,
            **{rr: replay(tr, prior, dt, rr, options) for rr in ("keep", "freeze")}}


def records(which: str, seed: int, replicates: int):
    """(cell, replicate, y, Δt, prior, scorer) of a set; scorer(track) -> dict of scores."""
    # function-level imports: each set needs its own benchmark's modules (experiments/ is above tests' methods)
    if which in ("unseen-other", "unseen-grid"):
        from experiments.benchmarks import tracking_unseen as tu
        from experiments.report import tracking_metrics
        from experiments.simulate.laboratory import LaboratoryCellConfig, make_lab_cell
        from experiments.simulate.tracking_data import make_cell
        other = which == "unseen-other"
        cfgs = tu.other_configs(seed, replicates) if other else tu.configs(seed, replicates, records="pulses")
        for label, cfg in cfgs.items():
            cell = make_lab_cell(cfg) if isinstance(cfg, LaboratoryCellConfig) else make_cell(cfg, bounds=False)
            dt = float(cell["dt_s"])
            for r in range(replicates):
                def score(tr, cell=cell, r=r):
                    if other:
                        return tu._score_other(tr, cell, r)
                    out = tracking_metrics.score_record(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, cell, r)
                    out["reconverge_periods"] = out["t_reconverge_s"] * cell["truth_freq_rad_s"].min() / (2 * np.pi)
                    return out
                yield label, r, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], score
    elif which in ("beats", "beats-thr"):
        from experiments.benchmarks.tracking_beats import EXCITATIONS, NOISE_UG, SCHEDULES
        from experiments.report import tracking_metrics
        from experiments.simulate.tracking_data import TrackingCellConfig, make_cell
        for s, sched in SCHEDULES.items():
            for e, exc in EXCITATIONS.items():
                if which == "beats-thr" and e != "thrusters":
                    continue
                for noise in NOISE_UG:
                    cell = make_cell(TrackingCellConfig(schedule=sched, excitation=exc, noise_ug=noise,
                                                        duration_s=120.0, replicates=replicates, seed=seed),
                                     bounds=False)
                    for r in range(replicates):
                        def score(tr, cell=cell, r=r):
                            return tracking_metrics.score_record(tr.t_s, tr.frequencies, tr.converged,
                                                                 tr.runtime_s, cell, r)
                        yield f"{s}_{e}_{noise:g}ug", r, cell["accel_m_s2"][r], 0.02, cell["prior_rad_s"][r], score
    else:
        from _anyrate_table import records as anyrate
        from _tracking_signals import score_steps
        for cell, _, y, dt, truth, steps, prior in anyrate([seed]):
            def score(tr, truth=truth, dt=dt, steps=steps):
                return score_steps(tr.t_s, tr.frequencies, truth, dt, steps)
            yield cell, 0, y, dt, prior, score


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("set", choices=("unseen-other", "unseen-grid", "beats", "beats-thr", "anyrate"))
    parser.add_argument("seeds")
    parser.add_argument("--replicates", type=int, default=2)
    parser.add_argument("--option", action="append", default=[], help="key=value for gated_pencil's windows")
    args = parser.parse_args(argv)
    options = {}
    for kv in args.option:
        key, _, value = kv.partition("=")
        options[key] = value == "true" if value in ("true", "false") else float(value) if "." in value else value
    from threadpoolctl import threadpool_limits  # only the command sets the thread pool
    rows = []
    with threadpool_limits(limits=1):
        for seed in (int(s) for s in args.seeds.split(",")):
            for cell, r, y, dt, prior, score in records(args.set, seed, args.replicates):
                for name, tr in rows_of(y, dt, prior, options).items():
                    rows.append({"cell": f"{cell} (seed {seed})", "tracker": name, "r": r, **score(tr)})
    df = pd.DataFrame(rows)
    pd.set_option("display.width", 250)
    if args.set == "anyrate":
        print(df.pivot(index="cell", columns="tracker", values=["error", "within", "reconv_median"]).to_string())
        return
    from experiments.benchmarks.tracking_beats import summary  # the benchmarks' medians over replicates
    cols = ["cell", "tracker", "err_rel_median", "ratio", "err_rel_median_late", "share_within_1pct",
            "t_reconverge_s", "reconverge_periods", "never_converged_rate"]
    s = summary(df)
    print(s[[c for c in cols if c in s]].to_string())


if __name__ == "__main__":
    main()
