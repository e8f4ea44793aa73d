"""How fast the samples allow a white-force step to be re-converged, by the unknown-force bound — a development
table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_step_bound_dev.py SEED [--set ambient|unseen] [--replicates 2]
        [--cells "step"] [--cache DIR]

On the white-force step cells of ``tracking_ambient`` (``--set ambient``) or ``tracking_unseen``'s white-force step
(``--set unseen``) whose label holds one of ``--cells``, per replicate and mode, from the cell's unknown-force
posterior Cramér–Rao bound (``pcrb_unknown_force_std_rad_s``: the force unknown, the frequencies a walk matched to the
schedule, so a step's walk jumps at the step's sample — the bound knows when the step is, not where to):

* the first time after the step from which 2σ/ω ≤ 1 % holds to 30 s after it (the rule ``_latency_dev.py`` applies to
  the thruster cells' piecewise bound: an efficient unbiased tracker is then within 1 % about 95 % of the time);
  the largest over the modes is the bound's own re-convergence ("—": not within 30 s);
* the expected share of 10–30 s after the step in which an efficient unbiased Gaussian tracker with that σ is
  beyond 1 % (2Φ(−1 %/σ), averaged), per mode;
* an efficient tracker told the step's time, drawn ``--draws`` times: per mode the error of a scalar Kalman filter
  whose posterior information is the bound's and whose walk is the bound's (so that its variance is the bound's
  and its errors are correlated in time as an estimate's are; the four modes independent); its re-convergence by
  ``score_track``'s rule on ω(1 + e): the median over the draws and the share of draws later than 20 s ("—" in the
  median: never within the record);
* ``rpem_ambient:two``'s re-convergence (every mode within 1 % for 2 s, ``score_track``) and each mode's own.
"""

import os
import sys
import zlib
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
import scipy.stats  # noqa: E402
from _cells import VARIANT_TWO as TWO  # noqa: E402
from _cells import fmt_times, reconvergence_s, step_parser, white_step_cells  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.simulate.pcrb import matched_walk_q  # noqa: E402

HORIZON_S = 30.0
TARGET_S = 20.0


def efficient_draws(rel: np.ndarray, truth: np.ndarray, t: np.ndarray, dt: float, st: float, draws: int,
                    rng: np.random.Generator) -> np.ndarray:
    """Re-convergence times (s, inf: never within the record) of ``draws`` efficient trackers: per mode the scalar
    Kalman error recursion whose posterior information is the bound's, I = (σ/ω)⁻², and whose walk is the bound's
    matched walk q (relative): e⁻ = e − w (w ~ N(0, q)), I⁻ = (1/I + q)⁻¹, e = (I⁻ e⁻ + √(I − I⁻) z)/I, z ~ N(0, 1)."""
    info = rel ** -2.0
    q = matched_walk_q(truth) / truth ** 2
    e = rng.standard_normal((draws, info.shape[1])) / np.sqrt(info[0])
    err = np.empty((info.shape[0], draws, info.shape[1]))
    err[0] = e
    for k in range(1, info.shape[0]):
        e = e - np.sqrt(q[k - 1]) * rng.standard_normal(e.shape)
        pre = 1.0 / (1.0 / info[k - 1] + q[k - 1])
        gain = np.maximum(info[k] - pre, 0.0)
        e = (pre * e + np.sqrt(gain) * rng.standard_normal(e.shape)) / np.maximum(info[k], pre)
        err[k] = e
    out = np.array([reconvergence_s(t, truth * (1 + err[:, d]), truth, dt, st) for d in range(draws)])
    return np.where(np.isnan(out), np.inf, out)


def bound_times(rel: np.ndarray, t: np.ndarray, st: float) -> list[float]:
    """Per mode, the first time after the step (s) from which 2σ/ω ≤ 1 % holds until ``HORIZON_S`` after it."""
    win = (t > st) & (t <= st + HORIZON_S)
    out = []
    for i in range(rel.shape[1]):
        bad = np.flatnonzero(2 * rel[win, i] > 0.01)
        if bad.size == 0:
            out.append(t[win][0] - st)
        elif bad[-1] == win.sum() - 1:
            out.append(np.inf)
        else:
            out.append(t[win][bad[-1] + 1] - st)
    return out


def main() -> None:
    ap = step_parser(__doc__, cells="step")
    ap.add_argument("--cache", default=None)
    ap.add_argument("--draws", type=int, default=100)
    args = ap.parse_args()
    name, opts = parse_row(TWO)
    for label, _, cell in white_step_cells(args, prefix="bound_"):
        st = float(cell["step_time_s"])
        dt, truth, t = float(cell["dt_s"]), cell["truth_freq_rad_s"], cell["t_s"]
        late = (t >= st + 10) & (t <= st + HORIZON_S)
        for r in range(cell["accel_m_s2"].shape[0]):
            rel = cell["pcrb_unknown_force_std_rad_s"][r] / truth
            tb = bound_times(rel, t, st)
            beyond = np.mean(2 * scipy.stats.norm.sf(0.01 / rel[late]), axis=0)
            rng = np.random.default_rng([zlib.crc32(label.encode()), args.seed, r])   # the same draws in any selection
            eff = efficient_draws(rel, truth, t, dt, st, args.draws, rng)
            med = np.median(eff)
            tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
            own = [reconvergence_s(tr.t_s, tr.frequencies[:, [i]], truth[:, [i]], dt, st)
                   for i in range(truth.shape[1])]
            rc = reconvergence_s(tr.t_s, tr.frequencies, truth, dt, st)
            print(f"{args.seed} | {label} | r{r} | bound: 2σ ≤ 1 % from {fmt_times(tb)} s (all {fmt_times([max(tb)])}),"
                  f" beyond 1 % 10–30 s " + "/".join(f"{100 * b:.0f}" for b in beyond) + " % | "
                  f"efficient back in {fmt_times([med])} s (later than {TARGET_S:g} s: "
                  f"{100 * np.mean(eff > TARGET_S):.0f} %) | "
                  f"tracker back in {fmt_times([rc])} s, per mode {fmt_times(own)}", flush=True)


if __name__ == "__main__":
    main()
