"""``rpem_ambient``'s slowest mode under a white force, per recursion — a development table, not a test (pytest
does not collect it).

    python tests/methods/tracking/dev/_mode1_dev.py SEED [--replicates 2] [--per-record]

On ``tracking_ambient``'s six white-force cells (its configs, no slosh, no thrusters), per record: the window
recursion (``rpem_ambient:frequency_model=trend``, the same recursion ``recursions="two"`` runs beside the
whole-record one, which does not feed back into it) and the reported one
(``…+recursions=two+score_reset=true``). Summary per recursion over the records: mode 1's first estimate, its
error at 20 s and 30 s, its median |e| after 30 s over the unknown-force bound's 1σ, its median signed error
(drift and step records apart, mean ± standard error), its share within 1 % after 30 s, each mode's median |e|;
per cell the benchmark's × bound (median over time and modes after 30 s over the bound's) and the
re-convergence of each replicate (— never). ``--per-record``: mode 1's error, 1σ and the bound's 1σ at
10…140 s, and the whole-record recursion's resets.
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_ambient import configs  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.report.tracking_metrics import score_track  # noqa: E402
from experiments.simulate.tracking_data import make_cell  # noqa: E402

ROWS = {"window": "rpem_ambient:frequency_model=trend",
        "reported": "rpem_ambient:frequency_model=trend+recursions=two+score_reset=true"}
MARKS = (10, 20, 30, 45, 60, 75, 90, 105, 120, 140)


def records(seed: int, replicates: int):
    """(cell, replicate, truth, bound, step time, {row: Track}) of the white-force cells."""
    for label, cfg in configs(seed, replicates).items():
        if "white force" not in label or "slosh" in label:
            continue
        cell = make_cell(cfg)
        dt = float(cell["dt_s"])
        for r in range(replicates):
            tracks = {}
            for row, spec in ROWS.items():
                name, opts = parse_row(spec)
                tracks[row] = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
            yield label, r, cell["truth_freq_rad_s"], cell["pcrb_unknown_force_std_rad_s"][r], \
                float(cell["step_time_s"]), dt, tracks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("--replicates", type=int, default=2)
    ap.add_argument("--per-record", action="store_true")
    args = ap.parse_args()
    acc = {row: {k: [] for k in ("start", "e20", "e30", "xb1", "drift", "step", "in1", "modes")} for row in ROWS}
    cells: dict = {}
    for label, r, truth, bound, st, dt, tracks in records(args.seed, args.replicates):
        for row, tr in tracks.items():
            t = tr.t_s
            k = np.round(t / dt).astype(int)
            e = (tr.frequencies - truth[k]) / truth[k]
            b = bound[k] / truth[k]
            late = t >= 30.0
            a = acc[row]
            at = {m: int(np.argmin(np.abs(t - m))) for m in MARKS if m <= t[-1]}
            a["start"].append(abs(e[0, 0]))
            a["e20"].append(abs(e[at[20], 0]))
            a["e30"].append(abs(e[at[30], 0]))
            a["xb1"].append(np.median(np.abs(e[late, 0]) / b[late, 0]))
            a["drift" if np.isnan(st) else "step"].append(np.median(e[late, 0]))
            a["in1"].append(np.mean(np.abs(e[late, 0]) <= 0.01))
            a["modes"].append(np.median(np.abs(e[late]), axis=0))
            xb = np.median(np.abs(e[late])) / np.median(b[late])
            re = np.nan
            if np.isfinite(st):
                re = score_track(t, tr.frequencies, np.ones(tr.frequencies.shape, bool), 1.0, truth, dt,
                                 step_time_s=st)["t_reconverge_s"]
            cells.setdefault((label, row), []).append((xb, re))
            if args.per_record:
                print(f"{label} | {r} | {row}: mode 1 e % "
                      + " ".join(f"{m}:{100 * e[i, 0]:+.1f}" for m, i in at.items())
                      + " | 1σ % " + " ".join(f"{m}:{100 * tr.std[i, 0] / truth[k[i], 0]:.1f}" for m, i in at.items())
                      + " | bound 1σ % " + " ".join(f"{m}:{100 * b[i, 0]:.2f}" for m, i in at.items())
                      + " | resets " + " ".join(f"{s:.1f}s/m{i + 1}" for s, i in tr.extra.get("reset_times_s", ())))
    for row, a in acc.items():
        modes = np.median(np.array(a["modes"]), axis=0)

        def mse(v):
            return f"{100 * np.mean(v):+.2f} ± {100 * np.std(v) / np.sqrt(len(v)):.2f}"
        print(f"{row}: mode 1 first estimate |e| median {100 * np.median(a['start']):.1f} % (max "
              f"{100 * max(a['start']):.1f}); at 20 s {100 * np.median(a['e20']):.1f} ({100 * max(a['e20']):.1f}); "
              f"at 30 s {100 * np.median(a['e30']):.1f} ({100 * max(a['e30']):.1f}); after 30 s |e|/bound 1σ "
              f"{np.median(a['xb1']):.2f} ({min(a['xb1']):.1f}–{max(a['xb1']):.1f}), signed: drifts {mse(a['drift'])} "
              f"%, steps {mse(a['step'])} %, within 1 % {np.median(a['in1']):.2f}; each mode's |e| "
              + "/".join(f"{100 * v:.2f}" for v in modes) + " %")
    for (label, row), v in cells.items():
        re = "/".join("—" if np.isnan(x) else f"{x:.1f}" for _, x in v)
        tail = f", re-conv. {re} s" if "step" in label else ""
        print(f"{label} | {row}: × bound {np.median([x for x, _ in v]):.2f}{tail}")


if __name__ == "__main__":
    main()
