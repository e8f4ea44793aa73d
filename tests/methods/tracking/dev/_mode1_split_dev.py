"""``rpem_ambient``'s whole-record recursion: what moves mode 1 after the other modes step — a development table,
not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_mode1_split_dev.py SEED --cell "grid step, white force, 100 µg" --replicate 1
        [--row rpem_ambient:two] [--extra "+key=value"] [--every 5] [--mode 1]

Runs the row (default the variant ``rpem_ambient:two``) on one record of ``tracking_ambient``'s cell and steps
its whole-record recursion one sample at a time (``_rpem._step_function``, the same arithmetic as the run).
Before each sample it recomputes in numpy ψ = Cᵀ-weighted W + ∂(Cx)/∂θ, P⁻ = F P Fᵀ + Q, e and S, and splits
the Gauss–Newton step of the mode's ω and rate, L e = P⁻ψ e/S, into the parameters' groups: the mode's own ω
(P⁻ᵢᵢψᵢ e/S), its own ζ and K, and each other mode's ω, ζ and K (the cross terms of P⁻). Per stretch of
``--every`` s: the mode's error (%), its rate (%/s of ω), its 1σ (%) and the change of ω over the stretch
(% of ω) split into the rate's drift (Σ Δt ω̇), its own gradient, its own ζ/K, and the other modes' terms; the
same split for the rate (the change of ω̇ in %/s); the whole-record recursion's resets; and the mode's own
zero-rate conditional ω̂ − (P_ωω̇/P_ω̇ω̇) ω̇ (its error, %) with its Savage–Dickey weight μ₀ (``rate_test="mode"``).
``--no-step``: the same record, the same force and noise draws, with the schedule's step set to 0.
Findings: docs/measured/tracking_ambient.md, "What moves mode 1 after a step".
"""

import argparse
import dataclasses
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_ambient import configs  # noqa: E402
from experiments.benchmarks.tracking_cpu import parse_row  # noqa: E402
from experiments.simulate.tracking_data import make_cell  # noqa: E402
from methods.tracking import _rpem  # noqa: E402

LOG: list = []


def _split_advance(orig):
    """``_rpem._advance`` that steps the whole-record recursion (the one whose ω walks over one sample:
    const[1] = rate²Δt, the smaller ν²) per sample and logs the split of each step; the window recursion as
    before."""
    state_of = {"nu2": None}

    def advance(m, est_z, trend, filt, y_seg, const):
        if state_of["nu2"] is None:
            state_of["nu2"] = const[1]          # the window recursion runs first: its ν²
        if const[1] >= state_of["nu2"] or not trend:
            return orig(m, est_z, trend, filt, y_seg, const)
        theta, P, x, Wm, lam = filt
        p = theta.size
        nz = m if est_z else 0
        iw, iz = np.arange(m), np.arange(m, m + nz)
        ia = np.arange(3 * m + nz, 4 * m + nz)
        dt, nu2, gate = const[0], const[1], const[3]
        q_fixed = const[5 + 2 * m:5 + 2 * m + p]
        step = _rpem._step_function(m, est_z, trend)
        F = np.eye(p)
        F[iw, ia] = dt
        outs = []
        state = np.concatenate([theta, P.ravel(), x, Wm.ravel(order="F"), [lam]])
        for yk in y_seg:
            th = state[:p]
            Pk = state[p:p + p * p].reshape(p, p)
            xk = state[p + p * p:p + p * p + 2 * m]
            Wk = state[p + p * p + 2 * m:-1].reshape((2 * m, p), order="F")
            lk = state[-1]
            w = th[iw]
            z = th[iz] if est_z else np.full(m, const[4])
            C = np.column_stack([-w * w, -2 * z * w]).ravel()
            dcx = np.zeros(p)
            dcx[iw] = -2 * w * xk[0::2] - 2 * z * xk[1::2]
            if est_z:
                dcx[iz] = -2 * w * xk[1::2]
            psi = Wk.T @ C + dcx
            q = np.concatenate([nu2 * dt * w * w, q_fixed[m:]])
            Pm = F @ Pk @ F.T + np.diag(q)
            e = yk - C @ xk
            S = psi @ Pm @ psi + lk
            ok = S > 0 and e * e <= gate * S
            contrib = np.zeros((2 * m, p))         # rows: each ω, then each rate; columns: the parameters
            if ok:
                contrib = Pm[np.r_[iw, ia]] * psi * e / S
            th_pred = F @ th
            state, out = step(state, yk, const)
            state = np.asarray(state).ravel()
            LOG.append((th_pred[iw] - th[iw], th, np.sqrt(np.diag(Pk)[iw]), contrib, state[iw] - th_pred[iw],
                        state[ia] - th_pred[ia], Pk[iw, ia], Pk[ia, ia]))
            outs.append(np.asarray(out).ravel())
        theta = state[:p].copy()
        P = state[p:p + p * p].reshape(p, p).copy()
        x = state[p + p * p:p + p * p + 2 * m].copy()
        Wm = state[p + p * p + 2 * m:-1].reshape((2 * m, p), order="F").copy()
        return theta, P, x, Wm, float(state[-1]), np.array(outs).T

    return advance


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("--cell", default="grid step, white force, 100 µg")
    ap.add_argument("--replicate", type=int, default=0)
    ap.add_argument("--row", default="rpem_ambient:two")
    ap.add_argument("--extra", default="")
    ap.add_argument("--every", type=float, default=5.0)
    ap.add_argument("--mode", type=int, default=1)
    ap.add_argument("--no-step", action="store_true",
                    help="the same record (force and noise draws) with the schedule's step set to 0")
    args = ap.parse_args()
    if args.seed in (20261121, 20261127, 20261128, 4711, 5, 4717, 4723, 4729):
        raise SystemExit(f"{args.seed} is a scoring seed")
    name, opts = parse_row(args.row)
    if args.extra:
        opts.update(parse_row("x:" + args.extra.lstrip("+"))[1])
    cfg = configs(args.seed, args.replicate + 1)[args.cell]
    if args.no_step:
        cfg = dataclasses.replace(cfg, schedule=dataclasses.replace(cfg.schedule, step=[0.0] * len(cfg.schedule.step)))
    cell = make_cell(cfg, bounds=True)
    dt = float(cell["dt_s"])
    truth = cell["truth_freq_rad_s"]
    bound = cell["pcrb_unknown_force_std_rad_s"][args.replicate]
    orig = _rpem._advance
    _rpem._advance = _split_advance(orig)
    try:
        tr = methods.track(name, cell["accel_m_s2"][args.replicate], dt, cell["prior_rad_s"][args.replicate], **opts)
    finally:
        _rpem._advance = orig
    i = args.mode - 1
    m = truth.shape[1]
    n0 = int(round(tr.t_s[0] / dt))        # the first sample the whole-record recursion steps
    rows = LOG
    nz = m if opts.get("estimate_damping", True) else 0
    groups = {"own ω": [i], "own ζ,K": ([m + i] if nz else []) + [m + nz + 2 * i, m + nz + 2 * i + 1]}
    for j in range(m):
        if j != i:
            groups[f"m{j + 1}"] = [j] + ([m + j] if nz else []) + [m + nz + 2 * j, m + nz + 2 * j + 1]
    assert len(rows) == truth.shape[0] - n0, (len(rows), truth.shape[0], n0)
    drift = np.array([r[0][i] for r in rows])
    thw = np.array([r[1][i] for r in rows])
    rate = np.array([r[1][3 * m + nz + i] for r in rows])
    sd = np.array([r[2][i] for r in rows])
    cw = np.array([r[3][i] for r in rows])              # (n, p): contributions to ω_i
    ca = np.array([r[3][m + i] for r in rows])          # to ω̇_i
    dw_upd = np.array([r[4][i] for r in rows])
    da_upd = np.array([r[5][i] for r in rows])
    p_wa = np.array([r[6][i] for r in rows])
    p_aa = np.array([r[7][i] for r in rows])
    # the mode's own zero-rate conditional (``rate_test="mode"``) and its weight μ₀, from the same posterior
    prior_var = (opts.get("rate_rel_per_s", 1e-3) * cell["prior_rad_s"][args.replicate][i]) ** 2
    w0 = thw - p_wa / p_aa * rate
    mu0 = 1 / (1 + np.exp(-np.clip(0.5 * np.log(prior_var / p_aa) - 0.5 * rate ** 2 / p_aa, -50, 50)))
    k_all = n0 + np.arange(len(rows))
    w_true = truth[k_all, i]
    print(f"seed {args.seed} | {args.cell} | replicate {args.replicate} | {args.row}{args.extra} | mode {args.mode} | "
          f"step {float(cell['step_time_s'])} s | resets "
          + " ".join(f"{a:.1f}/m{b + 1}" for a, b in tr.extra["reset_times_s"]))
    print("check: |update − Σ split| max (ω, rate): "
          f"{np.max(np.abs(dw_upd - cw.sum(1))):.2e}, {np.max(np.abs(da_upd - ca.sum(1))):.2e} "
          f"(max update {np.max(np.abs(dw_upd)):.2e}, {np.max(np.abs(da_upd)):.2e}; a reset between samples "
          "is neither)")
    names = list(groups)
    print("t s | e % | rate %/s | 1σ % | bound % | rate-0 e % | μ₀ | Δω % over the stretch: rate drift, "
          + ", ".join(names)
          + " | Δrate %/s: " + ", ".join(names))
    step_n = int(round(args.every / dt))
    for a in range(0, len(rows), step_n):
        b = min(len(rows), a + step_n)
        k = k_all[b - 1]
        sl = slice(a, b)
        wt = w_true[b - 1]
        parts = [100 * drift[sl].sum() / wt] + [100 * cw[sl][:, groups[g]].sum() / wt for g in names]
        rparts = [100 * ca[sl][:, groups[g]].sum() / wt for g in names]
        print(f"{k * dt:6.1f} | {100 * (thw[b - 1] - wt) / wt:+.2f} | {100 * rate[b - 1] / wt:+.4f} | "
              f"{100 * sd[b - 1] / wt:.2f} | {100 * bound[k, i] / wt:.2f} | {100 * (w0[b - 1] - wt) / wt:+.2f} | "
              f"{mu0[b - 1]:.2f} | "
              + " ".join(f"{v:+.2f}" for v in parts) + " | " + " ".join(f"{v:+.4f}" for v in rparts), flush=True)


if __name__ == "__main__":
    main()
