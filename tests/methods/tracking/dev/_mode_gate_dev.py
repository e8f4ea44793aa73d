"""``rpem_ambient:two`` after a step, look by look — a development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_mode_gate_dev.py SEED [--set ambient|unseen] [--cells "issue: −7"]
        [--replicates 2] [--extra "+opt=value"] [--trace MODE]

On the step cells of ``tracking_ambient`` (``--set ambient``) or ``tracking_unseen``'s white-force step (``--set
unseen``) whose label holds one of ``--cells``, per replicate, for the row ``rpem_ambient:two`` (its options spelled
out) plus ``--extra``:

* the re-convergence (s after the step until every mode holds 1 % for 2 s, ``score_track``) and each mode's own
  (the same rule on that mode alone): the largest is the mode that holds the record;
* what the record allows: the window (five periods of the slowest prior mode) and, per mode, the first look after
  the step from which three looks in a row (about 2 s) have their periodogram peak (``pair_peaks``, as the
  tracker's looks) within 1 % of the truth at the look;
* the window-memory recursion alone (``rpem_ambient:frequency_model=trend+pair_peaks=true``, the same arithmetic as
  the one beside the reported recursion): each mode's own re-convergence;
* the first look after the step at which the whole window's Λ_W opens the reset gate (> ``restart_gate``²/2);
* every reset after the step: time, mode, the error of the value it took (the window recursion's ω̂ᵢ', %);
* per mode, the share of the time beyond 1 % from 10 s after the step to the re-convergence (or 30 s), for the
  reported and the window recursion;
* ``--trace MODE``: that mode at each look 0–30 s after the step: Λ_W, the look's peak, the window recursion's
  and the whole-record recursion's error (%, before this look's reset) and the whole-record score zᵢ (σ).
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import VARIANT_TWO as TWO  # noqa: E402
from _cells import ambient_configs, fmt_times, reconvergence_s, step_cells, step_parser  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from methods.tracking import _ambient, _rpem  # noqa: E402

WINDOW = "rpem_ambient:frequency_model=trend+pair_peaks=true"


def _per_mode(t, f, truth, dt, st) -> list[float]:
    return [reconvergence_s(t, f[:, [i]], truth[:, [i]], dt, st) for i in range(f.shape[1])]


def main() -> None:
    ap = step_parser(__doc__)
    ap.add_argument("--extra", default="")
    ap.add_argument("--trace", type=int, default=0, help="a mode (1…m): its numbers at each look 0–30 s after the step")
    args = ap.parse_args()
    cfgs = ambient_configs(args.set, args.seed, args.replicates)
    name, opts = parse_row(TWO + args.extra)
    wname, wopts = parse_row(WINDOW)
    looks: list = []
    orig_look, orig_reset = _ambient.periodogram_look, _rpem._reset_from_window

    def look(seg, dt, ref, *a, **kw):
        out = orig_look(seg, dt, ref, *a, **kw)
        if seg.size > 8 and kw.get("pair_edges") is not None:
            looks.append({"peak": out[0].copy()})
        return out

    def reset(long, theta, P, iw, ia, gain, o, *a, **kw):
        looks[-1]["L"] = gain
        looks[-1]["w_win"] = theta[iw].copy()
        looks[-1]["w_long"] = long[0][iw].copy()
        looks[-1]["z"] = a[0].copy() if a and a[0] is not None else np.full(iw.size, np.nan)
        modes = orig_reset(long, theta, P, iw, ia, gain, o, *a, **kw)
        looks[-1]["reset"] = [(int(i), float(long[0][iw[i]])) for i in modes]
        return modes

    _ambient.periodogram_look, _rpem._reset_from_window = look, reset
    thr = 0.5 * 4.0 ** 2
    for label, cell, dt, st, truth in step_cells(cfgs, args.cells):
        for r in range(args.replicates):
            prior = cell["prior_rad_s"][r]
            W_len, hop = _ambient._window_samples(_rpem.Options(), dt, prior)
            looks.clear()
            tr = methods.track(name, cell["accel_m_s2"][r], dt, prior, **opts)
            trace = list(looks)
            looks.clear()
            tw = methods.track(wname, cell["accel_m_s2"][r], dt, prior, **wopts)
            rc = reconvergence_s(tr.t_s, tr.frequencies, truth, dt, st)
            own = _per_mode(tr.t_s, tr.frequencies, truth, dt, st)
            win = _per_mode(tw.t_s, tw.frequencies, truth, dt, st)
            # the looks after the start's: the j-th (from 0) ends at sample W − 1 + (j + 1)·hop
            kl = np.array([W_len - 1 + (j + 1) * hop for j in range(len(trace))])
            tl = kl * dt
            after = tl >= st
            m = truth.shape[1]
            peak_ok = []
            for i in range(m):      # three looks in a row within 1 % (about 2 s)
                ok = np.array([abs(trace[j]["peak"][i] / truth[kl[j], i] - 1) <= 0.01
                               for j in range(kl.size)]) & after
                run3 = np.flatnonzero(ok[:-2] & ok[1:-1] & ok[2:])
                peak_ok.append(tl[run3[0]] - st if run3.size else np.nan)
            L = np.array([trace[j].get("L", np.nan) for j in range(kl.size)])
            gate = np.flatnonzero(after & (L > thr))
            print(f"{args.seed} | {label} | r{r} | re-conv. {fmt_times([rc])} s, per mode {fmt_times(own)} | window "
                  f"{W_len * dt:.1f} s, peaks within 1 % from {fmt_times(peak_ok)} | window recursion "
                  f"{fmt_times(win)} | "
                  f"Λ_W open {fmt_times([tl[gate[0]] - st] if gate.size else [np.nan])}", flush=True)
            rs = []
            for j in np.flatnonzero(after):
                for i, w in trace[j].get("reset", []):
                    rs.append(f"{tl[j] - st:.1f}/m{i + 1} {100 * (w / truth[kl[j], i] - 1):+.1f}%")
            print("     resets (s after the step/mode, its new ω's error): " + " ".join(rs))
            for lab, t_, f_ in (("reported", tr.t_s, tr.frequencies), ("window recursion", tw.t_s, tw.frequencies)):
                kk = np.round(t_ / dt).astype(int)
                end = st + (rc if np.isfinite(rc) else 30.0)
                h = (t_ >= st + 10) & (t_ < max(end, st + 10.5))
                print(f"     {lab}: share beyond 1 % per mode from 10 s after the step to the re-convergence (or 30 s) "
                      + "/".join(f"{v:.2f}" for v in np.mean(np.abs(f_[h] / truth[kk[h]] - 1) > 0.01, axis=0)))
            print(f"     {tr.message}")
            if args.trace:
                i = args.trace - 1
                for j in np.flatnonzero(after & (tl < st + 30)):
                    c = trace[j]
                    tv = truth[kl[j], i]
                    print(f"     {tl[j] - st:5.1f} s Λ_W {c.get('L', np.nan):7.1f} | peak "
                          f"{100 * (c['peak'][i] / tv - 1):+6.2f} | window "
                          f"{100 * (c['w_win'][i] / tv - 1):+6.2f} | whole (before reset) "
                          f"{100 * (c['w_long'][i] / tv - 1):+6.2f} | z {c['z'][i]:+5.1f}"
                          + (" reset" if any(q == i for q, _ in c.get("reset", [])) else ""))
    _ambient.periodogram_look, _rpem._reset_from_window = orig_look, orig_reset


if __name__ == "__main__":
    main()
