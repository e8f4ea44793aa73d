"""``rpem_ambient:two``'s close pair (modes 2 and 3) on the white-force drift records — a development table, not a
test (pytest does not collect it).

    python tests/methods/tracking/dev/_close_pair_dev.py SEED [--set ambient|unseen] [--replicates 2]
        [--rows base,+opt=value,...] [--match TEXT] [--cache DIR] [--marks] [--switch NAME=VALUE,...]
        [--oracle-start] [--slosh]

On ``tracking_ambient``'s (``--set ambient``) or ``tracking_unseen``'s (``--set unseen``) white-force drift records
(those whose label contains ``--match``), per replicate and row (``base`` = ``rpem_ambient:two`` as
configs/tracker/rpem_ambient_two.yaml; ``+opt=value…`` = it with those options; ``window`` = its window recursion
alone): × the unknown-rate bound (median |e| after 30 s over the bound's median 1σ after 30 s) and per mode;
``--marks`` adds each mode's signed error (%) at 20…120 s, the bound's 1σ there and the resets.
``--slosh`` takes the slosh records instead (× the unknown-force bound: they have no rate-unknown one; the
column still says "line"). ``--oracle-start`` starts both recursions at the true ω (the first look's peaks
replaced by the truth).
``--cache`` keeps the simulated cells (with their bounds) as pickles. ``--switch`` sets module switches of
``methods.tracking._rpem`` (the diagnosis's one-factor switches, at the commit that had them).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import VARIANT_TWO as BASE  # noqa: E402
from _cells import cached_cell, print_marks, record_parser, white_force_drift  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks import tracking_ambient, tracking_unseen  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from methods.tracking import _ambient, _rpem  # noqa: E402

WINDOW = "rpem_ambient:frequency_model=trend+pair_peaks=true"
LOOK = _ambient.periodogram_look


def _oracle_first_look(truth: np.ndarray):
    """``--oracle-start``: the tracker's first look (its start) returns the true ω at the window's end as its peaks;
    every later look is the tracker's own. A diagnosis (the truth is the simulator's), never a method."""
    calls = []

    def look(seg, dt, ref, band, zeta, **kw):
        out = LOOK(seg, dt, ref, band, zeta, **kw)
        calls.append(1)
        return (truth[seg.size - 1].copy(),) + tuple(out[1:]) if len(calls) == 1 else out
    return look


def cells(which: str, seed: int, replicates: int, match: str, cache: str | None, slosh: bool = False):
    cfgs = (tracking_ambient.configs(seed, replicates) if which == "ambient"
            else tracking_unseen.configs(seed, replicates, records="ambient"))
    for i, (label, cfg) in enumerate(cfgs.items()):
        if not (bool(cfg.schedule.slosh) if slosh else white_force_drift(cfg)) or match not in label:
            continue
        yield label, cached_cell(cfg, cache, f"{which}_{seed}_{replicates}_{i}")


def main() -> None:
    ap = record_parser(__doc__)
    ap.add_argument("--rows", default="base")
    ap.add_argument("--match", default="")
    ap.add_argument("--marks", action="store_true")
    ap.add_argument("--switch", default="", help="NAME=VALUE,…: module switches of methods.tracking._rpem (diagnosis)")
    ap.add_argument("--slosh", action="store_true",
                    help="the slosh records instead, × the unknown-force bound (no rate-unknown bound there)")
    ap.add_argument("--oracle-start", action="store_true", help="the first look's peaks are the true ω (diagnosis)")
    args = ap.parse_args()
    for item in filter(None, args.switch.split(",")):
        key, value = item.split("=")
        old = getattr(_rpem, key)
        setattr(_rpem, key, type(old)(value))
    rows = {}
    for spec in args.rows.split(","):
        rows[spec] = BASE if spec == "base" else WINDOW if spec == "window" else BASE + spec
    key = "pcrb_unknown_force_std_rad_s" if args.slosh else "pcrb_unknown_rate_std_rad_s"
    for label, cell in cells(args.set, args.seed, args.replicates, args.match, args.cache, args.slosh):
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        print(f"## {args.seed} | {label}", flush=True)
        for row, spec in rows.items():
            name, opts = parse_row(spec)
            xs, per = [], []
            for r in range(args.replicates):
                if args.oracle_start:
                    _ambient.periodogram_look = _oracle_first_look(truth)
                try:
                    tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
                finally:
                    _ambient.periodogram_look = LOOK
                k = np.round(tr.t_s / dt).astype(int)
                e = (tr.frequencies - truth[k]) / truth[k]
                b = cell[key][r][k] / truth[k]
                on = tr.t_s >= 30.0
                xs.append(np.nanmedian(np.abs(e[on])) / np.median(b[on]))
                per.append(np.nanmedian(np.abs(e[on]), axis=0) / np.median(b[on], axis=0))
                if args.marks:
                    print(f"   r{r} {row}: × line {xs[-1]:.2f} | per mode " + "/".join(f"{x:.1f}" for x in per[-1]))
                    print_marks(tr, e, b, "σ_line", clamp=True)
            print(f"   {row:40s} × line {np.median(xs):.2f} (" + "/".join(f"{x:.2f}" for x in xs) + ") | per mode "
                  + "/".join(f"{x:.1f}" for x in np.median(per, axis=0)) + " | r: "
                  + " ; ".join("/".join(f"{x:.1f}" for x in p) for p in per), flush=True)


if __name__ == "__main__":
    main()
