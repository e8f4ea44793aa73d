"""A blind one-force noise model, fitted well, and what it finds after a white-force step — a development table,
not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_noise_search_dev.py SEED [--set ambient|unseen] [--replicates R]
        [--cells "white force"] [--cache DIR] [--fit-s 30] [--kalman-grid | --search]

The noise model of :func:`_ml_oracle_dev.force_model`: one white force through every mode (gains bᵢ, zero-order
held), a direct term d and white sensor noise v, at (ω, ζ) held. Its likelihood has a local optimum per sign
pattern of the gains (each pattern puts the spectrum's zeros between modes elsewhere), so it is fitted from every
pattern: first by the Whittle likelihood of the periodogram, Σ ln S + I/S with S = |Σ bᵢHᵢ + d|² + v (Hᵢ the
zero-order-held transfer from the force to the tip through mode i, linear in (b, d); analytic gradient,
``scipy.optimize.minimize`` L-BFGS-B), each gain started at the height of the periodogram's peak next to its
mode; then each pattern's optimum polished by the exact likelihood of the steady Kalman predictor
(:func:`_ml_oracle_dev.kalman_nll`, L-BFGS-B), the best kept.

* Default: on the white-force step records whose label holds one of ``--cells``, per replicate, the negative
  log-likelihood of the ``--fit-s`` seconds before the step under the genie's model (the simulated force, its
  gains, direct term and sensor noise) and under the blind fit, at the truth's (ω, ζ) and at the tracker's there,
  and under ``_ml_oracle_dev.fit_force_model``'s (Nelder–Mead from two starts) at the truth's.
* ``--kalman-grid``: the closest prior pair searched on [step, step + T) for T = 5, 10 s (33 × 33 grid ±12 % about
  the tracker's estimate before the step, the other modes held there; ``_ml_oracle_dev.kalman_grid``), its
  likelihood that of the steady Kalman predictor of each hypothesis under the genie's noise model, the blind fit at
  the truth's (ω, ζ) and the blind fit at the tracker's (ω, ζ) before the step (no genie): the pair's larger error.
* ``--search``: what the tracker could do with that model, blind: at the first look after the step at which
  ``rpem_ambient:two``'s reset gate opens (Λ_W > 8 nats), the noise model fitted on the ``--fit-s`` seconds before
  that look's window at the whole-record recursion's (ω, ζ) there; then 4–10 s after the opening, the modes searched
  on the samples since it (the pair on a 2-D grid ±12 % about the recursion's, coarse then fine, each other mode
  with 8 periods or more in those samples on a 1-D one, twice over), beside the recursion at the same look; error
  of modes 2…m (mode 1 has too few periods in those seconds to be searched). With ``--from-step`` the search is
  told the step instead (a genie of the change time): the noise model fitted on the ``--fit-s`` seconds before
  the step at the recursion's (ω, ζ) at its last look before it, the search on the samples since the step,
  5–15 s after it. With ``--genie-noise`` the search's noise model is the genie's (the simulated force, its
  gains, direct term, sensor noise and ζ) instead of the blind fit. With ``--hold`` (and ``--from-step``) the
  search at every second 4–25 s after the step, and for it and the tracker's reported track the first look from
  which every later one has modes 2…m within 1 % (the benchmark's re-convergence, on those modes and looks).
"""

import itertools
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
import scipy.optimize  # noqa: E402
from _cells import VARIANT_TWO as TWO  # noqa: E402
from _cells import reconvergence_s, step_parser, white_step_cells  # noqa: E402
from _ml_oracle_dev import (  # noqa: E402
    fit_force_model,
    force_model,
    genie_model,
    kalman_grid,
    kalman_nll,
    pct,
    recursion_looks,  # noqa: E402
)

from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.simulate.timevarying import oscillator_transition  # noqa: E402
from methods.tracking import _rpem  # noqa: E402


def transfer_basis(w, z, dt, n: int) -> np.ndarray:
    """(K, m + 1) complex: column i the zero-order-held transfer from the force to y through mode i (bᵢ = 1),
    C(zI − Φᵢ)⁻¹γᵢ with C = [−ωᵢ², −2ζᵢωᵢ], the last column 1 (the direct term), at the Fourier frequencies 2πk/n,
    k = 1 … n/2 − 1."""
    m = w.size
    phi, gamma = oscillator_transition(w[None, :], z[None, :], dt)
    zz = np.exp(2j * np.pi * np.arange(1, n // 2) / n)
    A = np.ones((zz.size, m + 1), complex)
    for i in range(m):
        (a, b), (c, d) = phi[0, i]
        g = gamma[0, i, :, 1]
        det = (zz - a) * (zz - d) - b * c
        A[:, i] = (-w[i] ** 2 * ((zz - d) * g[0] + b * g[1]) - 2 * z[i] * w[i] * (c * g[0] + (zz - a) * g[1])) / det
    return A


def _polish(y, w, z, dt, theta):
    """θ = [b, d, ln v] refined by the exact likelihood (L-BFGS-B, numerical gradient, in y's unit scale)."""
    m, sd = w.size, float(np.std(y))
    unit = np.concatenate([np.full(m + 1, sd), [0.0]])
    shift = np.concatenate([np.zeros(m + 1), [2 * math.log(sd)]])

    def cost(x):
        try:
            return kalman_nll(y, *force_model(w, z, dt, x * np.where(unit > 0, unit, 1) + shift))
        except (ValueError, np.linalg.LinAlgError):
            return 1e12

    x0 = (theta - shift) / np.where(unit > 0, unit, 1)
    res = scipy.optimize.minimize(cost, x0, method="L-BFGS-B", options={"maxiter": 60})
    return res.x * np.where(unit > 0, unit, 1) + shift, float(res.fun)


def fit_one_force(y, w, z, dt) -> tuple[np.ndarray, float]:
    """The one-force noise model's θ = [b₁…bₘ, d, ln v] at (ω, ζ) held (module docstring) and its negative
    log-likelihood."""
    m, n = w.size, y.size
    sd = float(np.std(y))
    u = (y - y.mean()) / sd
    per = np.abs(np.fft.fft(u)[1:n // 2]) ** 2 / n
    A = transfer_basis(w, z, dt, n)
    freqs = 2 * np.pi * np.arange(1, n // 2) / (n * dt)
    height = np.empty(m)
    for i in range(m):      # each gain from the periodogram's peak within a bin (or 1 %) of its mode
        near = np.flatnonzero(np.abs(freqs - w[i]) <= max(2 * np.pi / (n * dt), 0.01 * w[i]))
        near = near if near.size else np.array([int(np.argmin(np.abs(freqs - w[i])))])
        kb = near[int(np.argmax(per[near]))]
        height[i] = math.sqrt(per[kb]) / max(abs(A[kb, i]), 1e-30)

    def whittle(x):
        T = A @ x[:m + 1]
        v = math.exp(x[m + 1])
        S = np.abs(T) ** 2 + v
        r = (1 - per / S) / S
        grad_b = (2 * np.real(np.conj(T)[:, None] * A) * r[:, None]).sum(0)
        return float(np.sum(np.log(S) + per / S)), np.concatenate([grad_b, [float(np.sum(r * v))]])

    best = (math.inf, None)
    v0 = math.log(max(float(np.median(per)), 1e-6) * 0.1)
    for signs in itertools.product((1.0, -1.0), repeat=m - 1):
        x0 = np.concatenate([np.concatenate([[1.0], signs]) * height, [0.0, v0]])
        # ln v bounded (y scaled to unit variance): a step far out would overflow the exponential
        bounds = [(None, None)] * (m + 1) + [(-50.0, 10.0)]
        x = scipy.optimize.minimize(whittle, x0, jac=True, method="L-BFGS-B", bounds=bounds).x
        theta = np.concatenate([x[:m + 1] * sd, [x[m + 1] + 2 * math.log(sd)]])
        theta, f = _polish(y, w, z, dt, theta)
        if f < best[0]:
            best = (f, theta)
    return best[1], best[0]


def _grid_search(y, w0, model, dt, span: float = 0.12) -> np.ndarray:
    """The modes on ``y`` by the likelihood of the steady Kalman predictor of ``model(ω)`` → (Φ, C, Q, S, R): the
    closest pair of ``w0`` on a 2-D grid
    (17 × 17 ±``span``, then 9 × 9 ±two coarse steps), each other mode with 8 periods or more in ``y`` on a 1-D grid
    (25, then 9), twice over (the second round ±``span``/4)."""
    m = w0.size
    skip = min(y.size // 4, int(round(2 * 2 * math.pi / float(np.min(w0)) / dt)))
    memo: dict = {}

    def cost(w):
        key = tuple(np.round(w, 12))
        if key not in memo:
            try:
                memo[key] = kalman_nll(y, *model(w), skip=skip)
            except (ValueError, np.linalg.LinAlgError):
                memo[key] = math.inf
        return memo[key]

    def best_of(cands):
        return min(cands, key=cost)

    i0 = int(np.argmin(np.diff(w0)))
    w = w0.copy()
    others = [k for k in range(m) if k not in (i0, i0 + 1) and w0[k] * y.size * dt / (2 * math.pi) >= 8]
    for rnd in range(2):
        sp = span if rnd == 0 else span / 4
        for n_g, h in ((17, sp), (9, 2 * sp / 16)):
            grid = np.linspace(-h, h, n_g)
            cands = []
            for a, b in itertools.product(grid, grid):
                ww = w.copy()
                ww[i0], ww[i0 + 1] = w[i0] * (1 + a), w[i0 + 1] * (1 + b)
                if ww[i0 + 1] > ww[i0]:
                    cands.append(ww)
            w = best_of(cands)
        for i in others:
            for n_g, h in ((25, sp), (9, 2 * sp / 24)):
                cands = []
                for a in np.linspace(-h, h, n_g):
                    ww = w.copy()
                    ww[i] = w[i] * (1 + a)
                    if (i == 0 or ww[i] > ww[i - 1]) and (i + 1 == m or ww[i] < ww[i + 1]):
                        cands.append(ww)
                w = best_of(cands)
    return w


def _held_from(times, ok) -> float:
    """The first of ``times`` from which every later one is ``ok`` (inf if the last is not)."""
    if not ok[-1]:
        return math.inf
    bad = np.flatnonzero(~ok)
    return float(times[0] if bad.size == 0 else times[bad[-1] + 1])


def _record(cfg, cell, r: int, name, opts) -> dict:
    """One replicate of a step cell and ``rpem_ambient:two`` on it, with its looks."""
    st, dt = float(cell["step_time_s"]), float(cell["dt_s"])
    y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
    tr, W_len, hop, kl, looks = recursion_looks(name, opts, y, dt, prior)
    return {"cfg": cfg, "cell": cell, "r": r, "y": y, "prior": prior, "m": prior.size, "dt": dt, "st": st,
            "k0": int(round(st / dt)), "truth": cell["truth_freq_rad_s"],
            "zeta": np.asarray(cell["truth_damping"], float), "tr": tr, "W_len": W_len, "kl": kl, "looks": looks}


def _before_step(args, rec):
    """The ``--fit-s`` seconds before the step, the tracker's ω and ζ at its last sample before it, and the blind fit
    (θ, NLL) of that stretch at the truth's (ω, ζ) and at the tracker's."""
    y, dt, k0, truth, zeta, tr, st = (rec[k] for k in ("y", "dt", "k0", "truth", "zeta", "tr", "st"))
    seg = y[k0 - int(round(args.fit_s / dt)):k0]
    j = np.searchsorted(tr.t_s, st - dt / 2) - 1
    pre, z_pre = tr.frequencies[j], tr.extra["damping"][j]
    return seg, pre, z_pre, fit_one_force(seg, truth[k0 - 1], zeta, dt), fit_one_force(seg, pre, z_pre, dt)


def fit_quality(args, rec, tally) -> None:
    """The default table: the blind fits' likelihood before the step against the genie's and Nelder–Mead's."""
    dt, k0, truth, zeta = (rec[k] for k in ("dt", "k0", "truth", "zeta"))
    seg, _, _, (_, f_true), (_, f_trk) = _before_step(args, rec)
    f_genie = kalman_nll(seg, *genie_model(rec["cfg"], rec["cell"], truth[k0 - 1]))
    f_nm = kalman_nll(seg, *force_model(truth[k0 - 1], zeta, dt, fit_force_model(seg, truth[k0 - 1], zeta, dt)))
    print(f"  r{rec['r']} NLL of {args.fit_s:g} s before the step: genie {f_genie:.1f} | blind at the truth's "
          f"(ω, ζ) {f_true:.1f} (Nelder–Mead from two starts, as _ml_oracle_dev: {f_nm:.1f}) | blind at "
          f"the tracker's {f_trk:.1f}", flush=True)
    tally.setdefault("fit", []).append((f_true - f_genie, f_trk - f_genie, f_nm - f_genie))


def grid_after_step(args, rec, tally) -> None:
    """``--kalman-grid``: the pair's grid after the step under the genie's and the blind noise models."""
    y, dt, k0, truth, zeta, tr, st = (rec[k] for k in ("y", "dt", "k0", "truth", "zeta", "tr", "st"))
    cfg, cell = rec["cfg"], rec["cell"]
    _, pre, z_pre, (th_true, _), (th_trk, _) = _before_step(args, rec)
    i = int(np.argmin(np.diff(rec["prior"])))
    models = {"genie": lambda w: genie_model(cfg, cell, w),
              "blind at the truth's (ω, ζ)": lambda w: force_model(w, zeta, dt, th_true),
              "blind at the tracker's": lambda w: force_model(w, z_pre, dt, th_trk)}
    for T in (5.0, 10.0):
        k1 = k0 + int(round(T / dt))
        row = []
        for key, model in models.items():
            w_k = kalman_grid(y[k0:k1], pre, (i, i + 1), model)
            e = float(np.max(np.abs(w_k[[i, i + 1]] / truth[k1 - 1, [i, i + 1]] - 1))) * 100
            tally.setdefault((T, key), []).append(e)
            row.append(f"{key} {e:.2f}")
        w_t = tr.frequencies[np.searchsorted(tr.t_s, st + T - dt / 2) - 1]
        e_t = float(np.max(np.abs(w_t[[i, i + 1]] / truth[k1 - 1, [i, i + 1]] - 1))) * 100
        tally.setdefault((T, "tracker"), []).append(e_t)
        print(f"  r{rec['r']} T {T:.0f} s, the pair's larger error %: " + " | ".join(row) + f" | tracker {e_t:.2f}",
              flush=True)


def search_after(args, rec, tally) -> None:
    """``--search``: the modes searched after the gate's opening (or the step) beside the recursion."""
    y, dt, k0, truth, tr, st, m = (rec[k] for k in ("y", "dt", "k0", "truth", "tr", "st", "m"))
    W_len, kl, looks, r = rec["W_len"], rec["kl"], rec["looks"], rec["r"]
    gate = 0.5 * _rpem.Options().restart_gate ** 2
    after = [j for j in range(len(looks)) if kl[j] >= k0 and looks[j][0] > gate]
    if not after:
        print(f"  r{r}: the gate does not open after the step")
        return
    kg = kl[after[0]] + 1
    fit_end = kg - W_len
    if args.from_step:     # told the step: the samples since it, the noise fitted before it
        kg = fit_end = k0
    th_b = looks[int(np.searchsorted(kl, fit_end)) - 1][1]
    c0 = time.process_time()
    theta, _ = fit_one_force(y[max(W_len, fit_end - int(round(args.fit_s / dt))):fit_end], th_b[:m], th_b[m:2 * m],
                             dt)
    rc = reconvergence_s(tr.t_s, tr.frequencies, truth, dt, st)
    print(f"  r{r}: tracker back in {rc:.1f} s, the search from {kg * dt - st:.1f} s after the step, "
          f"noise fit {time.process_time() - c0:.1f} s CPU", flush=True)
    if args.genie_noise:
        def model(w):
            return genie_model(rec["cfg"], rec["cell"], w)
    else:
        def model(w):
            return force_model(w, th_b[m:2 * m], dt, theta)
    if args.hold:
        extras = tuple(float(t) for t in range(4, 26))
    else:
        extras = (5.0, 10.0, 15.0) if args.from_step else (4.0, 6.0, 8.0, 10.0)
    held = []
    for extra in extras:
        k1 = kg + int(round(extra / dt))
        w_t = looks[min(int(np.searchsorted(kl, k1 - 1)), len(looks) - 1)][1][:m]
        w_s = _grid_search(y[kg:k1 + 1], w_t, model, dt)
        e_s = float(np.max(np.abs(w_s[1:] / truth[k1, 1:] - 1))) * 100
        if args.hold:    # the reported track at that look, as the benchmark scores it
            w_r = tr.frequencies[np.searchsorted(tr.t_s, k1 * dt - dt / 2)]
            held.append((extra, e_s, float(np.max(np.abs(w_r[1:] / truth[k1, 1:] - 1))) * 100))
            continue
        e_t = float(np.max(np.abs(w_t[1:] / truth[k1, 1:] - 1))) * 100
        # is the search's optimum the likelihood's? its NLL against the truth's (mode 1 at the search's: it is not
        # searched)
        w_true = truth[k1].copy()
        w_true[0] = w_s[0]
        skip = min((k1 + 1 - kg) // 4, int(round(2 * 2 * math.pi / float(np.min(w_t)) / dt)))
        seg = y[kg:k1 + 1]
        d_nll = kalman_nll(seg, *model(w_s), skip=skip) - kalman_nll(seg, *model(w_true), skip=skip)
        tally.setdefault(("nll", extra), []).append(d_nll)
        tally.setdefault(extra, []).append((e_s, e_t))
        print(f"    +{extra:.0f} s ({k1 * dt - st:.1f} s after the step) e %: search "
              f"{pct(w_s, truth[k1])} (NLL {d_nll:+.1f} nats from the truth's) | recursion "
              f"{pct(w_t, truth[k1])}", flush=True)
    if args.hold:        # from which look on every later look (to 25 s) is within 1 %
        h = np.array(held)
        since = [_held_from(h[:, 0], h[:, c] <= 1) for c in (1, 2)]
        tally.setdefault("hold", []).append(since)
        print(f"    modes 2…m within 1 % at every look to 25 s from: search {since[0]:.0f} s, tracker "
              f"(reported) {since[1]:.0f} s after the step", flush=True)


def _summary(args, tally) -> None:
    for key, v in tally.items():
        v = np.asarray(v)
        if key == "hold":
            print(f"held within 1 % from ≤ 20 s after the step (modes 2…m, looks 4–25 s each 1 s): search "
                  f"{int(np.sum(v[:, 0] <= 20))}/{len(v)}, tracker {int(np.sum(v[:, 1] <= 20))}/{len(v)}")
        elif isinstance(key, tuple) and key[0] == "nll":
            print(f"+{key[1]:.0f} s: the search's NLL less the truth's: median {np.median(v):+.1f} nats, below 0 on "
                  f"{int(np.sum(v < 0))}/{v.size}")
        elif key == "fit":
            print(f"blind NLL − genie's: at the truth's (ω, ζ) median {np.median(v[:, 0]):+.1f} "
                  f"(max {v[:, 0].max():+.1f}), at the tracker's median {np.median(v[:, 1]):+.1f} "
                  f"(max {v[:, 1].max():+.1f}) nats; Nelder–Mead at the truth's median {np.median(v[:, 2]):+.1f} "
                  f"(max {v[:, 2].max():+.1f})")
        elif isinstance(key, float):
            since = "step" if args.from_step else "opening"
            print(f"+{key:.0f} s after the {since}: modes 2…m within 1 %: search {int(np.sum(v[:, 0] <= 1))}/{len(v)} "
                  f"(median {np.median(v[:, 0]):.2f} %), recursion {int(np.sum(v[:, 1] <= 1))}/{len(v)} "
                  f"(median {np.median(v[:, 1]):.2f} %)")
        else:
            print(f"T {key[0]:.0f} s {key[1]}: within 1.1 % {int(np.sum(v <= 1.1))}/{v.size}, "
                  f"median {np.median(v):.2f} %")


def main() -> None:
    ap = step_parser(__doc__, cells="white force")
    ap.add_argument("--cache", default=None)
    ap.add_argument("--fit-s", type=float, default=30.0)
    ap.add_argument("--kalman-grid", action="store_true")
    ap.add_argument("--search", action="store_true")
    ap.add_argument("--from-step", action="store_true")
    ap.add_argument("--genie-noise", action="store_true")
    ap.add_argument("--hold", action="store_true")
    args = ap.parse_args()
    name, opts = parse_row(TWO)
    run = search_after if args.search else grid_after_step if args.kalman_grid else fit_quality
    tally: dict = {}
    for label, cfg, cell in white_step_cells(args):
        print(label, flush=True)
        for r in range(cell["accel_m_s2"].shape[0]):
            run(args, _record(cfg, cell, r, name, opts), tally)
    _summary(args, tally)


if __name__ == "__main__":
    main()
