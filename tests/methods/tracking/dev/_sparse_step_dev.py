"""``rpem_ambient:two`` after the grid's step under the white force with sparse pulses, per replicate — a
development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_sparse_step_dev.py SEED[,SEED…] [--extra "+pair_peaks=false"]
        [--noise 100,1000] [--no-pulses]

The tracking grid's "step" schedule (+6 % mode 3, −4 % mode 4 at 60 s) with its "sparse" excitation (the white
body force, 5 N, and a ±100 N·m thruster pulse at random, 0.05 per s), dicts copied from
configs/grid/tracking.yaml, 120 s, 3 replicates, at each ``--noise`` (µg). The row
``rpem_ambient:frequency_model=trend+recursions=two+score_reset=true+pair_peaks=true+rate_test=after_change``
(``rpem_ambient:two``) plus ``--extra``. Per replicate: the re-convergence after the step
(``tracking_metrics.score_track``, s; — never), the mode that holds it (the last to come within 1 % for good;
with "never", the modes beyond 1 % for more than half of the last 20 s), the pulse times after the step (s), the
whole-record recursion's resets (s/mode), the first look after the step at which the last window's likelihood
ratio opens the reset gate (Λ_W > ``restart_gate``²/2), the window recursion's restarts from 45 to 100 s whose
peak is more than 2.5 % from every true ω of its window ("P": a pulse lies in that window), and every mode's
signed error at 5 s marks after the step (%). Then per noise the median × bound (median |e| after 30 s over the
unknown-force bound's median 1σ) and how many of the look's windows (one a second) ``gated_pencil``'s pulse
detector flags, with and without a pulse in them. ``--no-pulses``: the same records (the same force, noise and
prior draws) without the pulses. The gate and the restarts are read by wrapping ``_rpem._reset_from_window``,
``_ambient.periodogram_look`` and ``_ambient.modes_to_restart`` (the tracker's arithmetic is unchanged).
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import VARIANT_TWO as ROW  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.report.tracking_metrics import score_track  # noqa: E402
from experiments.simulate.tracking_data import TrackingCellConfig, make_cell  # noqa: E402
from methods.tracking import _ambient, _rpem  # noqa: E402
from methods.tracking._defaults import pencil_sizes  # noqa: E402
from methods.tracking._gated_pencil import Options as GatedOptions  # noqa: E402
from methods.tracking._gated_pencil import pulse_flags  # noqa: E402

STEP = {"step": [0.0, 0.0, 0.06, -0.04], "step_time_s": 60.0}                         # configs/grid/tracking.yaml
SPARSE = {"disturbance_force_n": 5.0, "thruster_torque_n_m": 100.0, "thruster_rate_hz": 0.05}
SCORING = {20261121, 20261128, 20261129, 4723, 4733}


def _detector(y, pulse_k, W, m):
    """``gated_pencil``'s pulse detector (its robust AR predictor, its defaults) on the look's window every
    second: (windows with a pulse whose pulse is flagged within 3 samples, windows with a pulse, windows
    without a pulse with any sample flagged, windows without)."""
    _, ar_order, _ = pencil_sizes(W, m, 2 * m)
    hit = with_p = flagged = without = 0
    for k in range(W - 1, y.size, 50):
        seg = y[k + 1 - W:k + 1]
        f = pulse_flags(seg - seg.mean(), ar_order, GatedOptions.outlier_cut)
        at = pulse_k[(pulse_k > k + 1 - W + ar_order) & (pulse_k <= k - 3)] - (k + 1 - W)
        if at.size:
            with_p += 1
            hit += any(f[a:a + 3].any() for a in at)
        else:
            without += 1
            flagged += bool(f.any())
    return hit, with_p, flagged, without


def _instrumented(name, opts, y, dt, prior):
    """The track, and per look (in order): the gate's log-likelihood ratio, the look's peaks, the modes restarted."""
    gains, peaks, restarts = [], [], []
    orig = (_rpem._reset_from_window, _ambient.periodogram_look, _ambient.modes_to_restart)

    def reset(long, theta, P, iw, ia, gain, *a, **k):
        gains.append(gain)
        return orig[0](long, theta, P, iw, ia, gain, *a, **k)

    def look(*a, **k):
        out = orig[1](*a, **k)
        peaks.append(out[0].copy())
        return out

    def restart(*a, **k):
        out = list(orig[2](*a, **k))
        restarts.append([int(i) for i, _ in out])
        return out

    _rpem._reset_from_window, _ambient.periodogram_look, _ambient.modes_to_restart = reset, look, restart
    try:
        tr = methods.track(name, y, dt, prior, **opts)
    finally:
        _rpem._reset_from_window, _ambient.periodogram_look, _ambient.modes_to_restart = orig
    return tr, gains, peaks[1:], restarts        # peaks[0]: the start's look


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seeds")
    ap.add_argument("--extra", default="")
    ap.add_argument("--noise", default="100,1000")
    ap.add_argument("--replicates", type=int, default=3)
    ap.add_argument("--marks", default="5,10,15,20,30,40,50")
    ap.add_argument("--no-pulses", action="store_true", help="the same record without the pulses (same draws)")
    args = ap.parse_args()
    name, opts = parse_row(ROW + args.extra)
    opts_gate = opts.get("restart_gate", _rpem.Options.restart_gate)
    marks = [float(v) for v in args.marks.split(",")]
    for seed in (int(s) for s in args.seeds.split(",")):
        if seed in SCORING:
            raise SystemExit(f"seed {seed} is a scoring seed")
        for noise in (float(v) for v in args.noise.split(",")):
            ex = {**SPARSE, "thruster_torque_n_m": 0.0} if args.no_pulses else SPARSE
            cfg = TrackingCellConfig(schedule=STEP, excitation=ex, noise_ug=noise, duration_s=120.0,
                                     replicates=args.replicates, seed=seed)
            cell = make_cell(cfg)
            dt, st, truth = float(cell["dt_s"]), float(cell["step_time_s"]), cell["truth_freq_rad_s"]
            bound = cell["pcrb_unknown_force_std_rad_s"]
            xs, rcs, found = [], [], [0, 0, 0, 0]
            for r in range(args.replicates):
                prior = cell["prior_rad_s"][r]
                tr, gains, peaks, restarts = _instrumented(name, opts, cell["accel_m_s2"][r], dt, prior)
                W, hop = _ambient._window_samples(_rpem.check_options(name, prior, dt, opts), dt, prior)
                looks = W - 1 + hop * (1 + np.arange(len(gains)))        # the sample of each look
                pulse_k = np.flatnonzero(cell["inputs"][r, :, 0] != 0)
                gate = next((k * dt for k, g in zip(looks, gains, strict=True)
                             if k * dt >= st and g > 0.5 * opts_gate ** 2), np.nan)
                wrong = []
                for k, pk, rr in zip(looks, peaks, restarts, strict=True):
                    if not 45.0 <= k * dt <= 100.0:
                        continue
                    for i in rr:
                        tw = truth[k + 1 - W:k + 1, i]
                        d = 100 * (pk[i] - tw) / tw
                        d = d[np.argmin(np.abs(d))]
                        if abs(d) > 2.5:
                            p = " (P)" if np.any((pulse_k > k - W) & (pulse_k <= k)) else ""
                            wrong.append(f"m{i + 1} {d:+.0f} % at {k * dt:.0f} s{p}")
                det = _detector(cell["accel_m_s2"][r], pulse_k, W, len(prior))
                for a in range(4):
                    found[a] += det[a]
                k = np.round(tr.t_s / dt).astype(int)
                e = (tr.frequencies - truth[k]) / truth[k]
                late = tr.t_s >= 30.0
                xs.append(np.median(np.abs(e[late])) / np.median(bound[r][k][late] / truth[k][late]))
                rc = score_track(tr.t_s, tr.frequencies, np.ones(tr.frequencies.shape, bool), 1.0, truth, dt,
                                 step_time_s=st)["t_reconverge_s"]
                rcs.append(rc)
                after = tr.t_s >= st
                bad = np.abs(e) > 0.01
                if np.isfinite(rc):     # the last mode beyond 1 % before the re-convergence
                    h = after & (tr.t_s < st + rc)
                    last = [np.flatnonzero(bad[h, i])[-1] if bad[h, i].any() else -1 for i in range(e.shape[1])]
                    holder = f"mode {int(np.argmax(last)) + 1}"
                else:
                    h = tr.t_s >= tr.t_s[-1] - 20.0
                    holder = "modes " + ",".join(str(i + 1) for i in np.flatnonzero(bad[h].mean(axis=0) > 0.5))
                pulses = np.flatnonzero(cell["inputs"][r, :, 0] != 0) * dt if not args.no_pulses else np.zeros(0)
                at = [f"{p:.1f}" for p in pulses[pulses >= st - 20.0]]
                resets = " ".join(f"{a:.1f}/m{i + 1}" for a, i in tr.extra["reset_times_s"])
                errs = []
                for mk in marks:
                    j = np.searchsorted(tr.t_s, st + mk)
                    if j < tr.t_s.size:
                        errs.append(f"+{mk:g}: " + "/".join(f"{100 * v:+.1f}" for v in e[j]))
                print(f"{seed} | {noise:g} µg | r{r} | re-conv. {'—' if not np.isfinite(rc) else f'{rc:.1f}'} s "
                      f"({holder}) | × bound {xs[-1]:.2f} | pulses from st−20 s: {' '.join(at) or 'none'} | "
                      f"resets {resets or 'none'} | gate opens {'never' if np.isnan(gate) else f'{gate:.1f} s'} | "
                      f"wrong restarts {', '.join(wrong) or 'none'} | "
                      f"{tr.message}", flush=True)
                print("     errors % after the step: " + "; ".join(errs), flush=True)
            print(f"{seed} | {noise:g} µg | × bound median {np.median(xs):.2f} | re-conv. "
                  + "/".join("—" if not np.isfinite(x) else f"{x:.1f}" for x in rcs) + " s | gated_pencil's pulse "
                  f"detector, windows every second: {found[0]} of {found[1]} with a pulse flagged, {found[2]} of "
                  f"{found[3]} without", flush=True)


if __name__ == "__main__":
    main()
