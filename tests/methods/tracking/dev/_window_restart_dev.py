"""The window-memory recursion's restarts after a step, look by look — a development table, not a test.

    python tests/methods/tracking/dev/_window_restart_dev.py SEED [--set ambient|unseen] [--cells "issue: −7"]
        [--replicates 2] [--extra "+opt=value"] [--trace 2,3]

On the step cells whose label holds one of ``--cells``, per replicate, the window-memory recursion
(``rpem_ambient:frequency_model=trend+pair_peaks=true`` plus ``--extra``, the arithmetic beside the reported
recursion of ``rpem_ambient:two``): each mode's own re-convergence, its restarts 0–25 s after the step (the
peak's error, σ, and the nearest true mode where it is a neighbour's), and for the ``--trace`` modes at each look
0–25 s after the step: the look's peak and the recursion's ω̂ (carried to the window's middle) as errors against
the truth at the look (%), the restart threshold max(restart_gate·sᵢ·ω̂, resolution) in %, the strikes, and a
restart with its running scale sᵢ (%; the 1σ it starts with).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import ambient_configs, fmt_times, reconvergence_s, step_cells, step_parser  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from methods.tracking import _ambient, _rpem  # noqa: E402

WINDOW = "rpem_ambient:frequency_model=trend+pair_peaks=true"


def main() -> None:
    ap = step_parser(__doc__)
    ap.add_argument("--only", type=int, default=-1, help="only this replicate")
    ap.add_argument("--extra", default="")
    ap.add_argument("--trace", default="", help="modes (1…m, comma-separated) to trace look by look")
    args = ap.parse_args()
    cfgs = ambient_configs(args.set, args.seed, args.replicates)
    name, opts = parse_row(WINDOW + args.extra)
    looks: list = []
    orig = _ambient.modes_to_restart

    def spy(modes, deviation, scale, floor, d_log, strikes, hist_d, o, *a, **kw):
        s = np.array([np.median(np.abs(h)) / 0.6745 if len(h) >= 3 else np.inf for h in hist_d])
        rec = {"dev": np.array(deviation, float).copy(), "mid": np.array(scale, float).copy(),
               "s": s, "floor": floor}
        out = orig(modes, deviation, scale, floor, d_log, strikes, hist_d, o, *a, **kw)
        rec["strikes"] = strikes.copy()
        rec["restarts"] = [(int(i), float(si)) for i, si in out]
        looks.append(rec)
        return out

    _ambient.modes_to_restart = spy
    _rpem._ambient.modes_to_restart = spy
    trace = [int(v) - 1 for v in args.trace.split(",") if v]
    try:
        for label, cell, dt, st, truth in step_cells(cfgs, args.cells):
            for r in range(args.replicates):
                if args.only >= 0 and r != args.only:
                    continue
                prior = cell["prior_rad_s"][r]
                W_len, hop = _ambient._window_samples(_rpem.Options(), dt, prior)
                looks.clear()
                tw = methods.track(name, cell["accel_m_s2"][r], dt, prior, **opts)
                m = truth.shape[1]
                win = [reconvergence_s(tw.t_s, tw.frequencies[:, [i]], truth[:, [i]], dt, st) for i in range(m)]
                print(f"{args.seed} | {label} | r{r} | window recursion per mode {fmt_times(win)} s | {tw.message}",
                      flush=True)
                kl = np.array([W_len - 1 + (j + 1) * hop for j in range(len(looks))])
                kmid = kl - (W_len - 1) // 2
                tl = kl * dt
                kk = np.round(tw.t_s / dt).astype(int)
                rs = []
                for j in np.flatnonzero((tl >= st) & (tl < st + 25)):
                    for i, si in looks[j]["restarts"]:
                        pk = looks[j]["mid"][i] + looks[j]["dev"][i]
                        own = truth[kmid[j], i]
                        now = truth[kl[j], i]
                        near = int(np.argmin(np.abs(truth[kl[j]] - pk)))
                        rs.append(f"{tl[j] - st:.1f}/m{i + 1} {100 * (pk / own - 1):+.1f}% "
                                  f"({100 * (pk / now - 1):+.1f}%) σ {100 * si:.2f}%"
                                  + (f" (nearest m{near + 1})" if near != i else ""))
                print("     restarts 0–25 s after the step (s/mode, the peak's error against the truth at the "
                      "window's middle (at the look), σ; the nearest true mode at the look if another): "
                      + ", ".join(rs))
                for i in trace:
                    for j in np.flatnonzero((tl >= st) & (tl < st + 25)):
                        c = looks[j]
                        tv = truth[kmid[j], i]
                        tl_ = truth[kl[j], i]
                        pk = c["mid"][i] + c["dev"][i]
                        before = max(np.searchsorted(kk, kl[j]) - 1, 0)
                        thr = max(4.0 * c["s"][i] * c["mid"][i], c["floor"])
                        rs = [si for q, si in c["restarts"] if q == i]
                        # the recursion right after the look (σ)
                        after = np.searchsorted(kk, kl[j] + 1)
                        after = min(after, kk.size - 1)
                        print(f"   m{i + 1} {tl[j] - st:5.1f} s | peak {100 * (pk / tv - 1):+6.2f} | rec(mid) "
                              f"{100 * (c['mid'][i] / tv - 1):+6.2f} | vs now: peak {100 * (pk / tl_ - 1):+6.2f} rec "
                              f"{100 * (tw.frequencies[before, i] / tl_ - 1):+6.2f} | "
                              f"thr {100 * thr / c['mid'][i]:5.2f} "
                              f"(4s {400 * c['s'][i]:5.2f}) | strikes {c['strikes'][i]} | after: "
                              f"{100 * (tw.frequencies[after, i] / truth[kk[after], i] - 1):+6.2f} "
                              f"σ {100 * tw.std[after, i] / tw.frequencies[after, i]:5.2f}"
                              + (f" RESTART σ {100 * rs[0]:.2f}" if rs else ""))
    finally:
        _ambient.modes_to_restart = orig


if __name__ == "__main__":
    main()
