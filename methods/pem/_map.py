"""Maximum a posteriori (MAP) frequencies: the output-error fit with a Gaussian prior on ω.

With ``prior_std_rad_s`` = s the prior is ω ~ N(μ, diag(s²)) (μ the prior frequencies). The record is
four damped sinusoids in white noise σ², so with the linear unknowns c = (x₀, b) at their least-squares
value for every (ω, ζ) (variable projection, :mod:`methods.pem._fast`), the negative log posterior is,
up to constants,

    Φ(ω, ζ) = ‖ε(ω, ζ)‖² / σ̂²  +  Σᵢ ((ωᵢ − μᵢ) / sᵢ)²,

the residual augmented with the rows (ω − μ)/s, scaled by the noise level σ̂ estimated from the record.
σ̂ is not known: with Jeffreys' prior 1/σ on it and σ integrated out, the cost minimised is

    Φ(ω, ζ) = (N − q) log ‖ε(ω, ζ)‖²  +  Σᵢ ((ωᵢ − μᵢ) / sᵢ)²,      q = 2m (+1 with the offset),

whose Gauss–Newton Hessian is the one above with σ̂² = ‖ε‖²/(N − q) at the current point: the noise
level is re-estimated from the record at every iterate. Levenberg–Marquardt on (ω, ζ), column-scaled:

    (H_d + P + λ·diag(H_d + P)) d = −(J_rᵀε/σ̂² + P(ω − μ)),   H_d = J_rᵀJ_r/σ̂²,  P = diag(1/s², 0 for ζ),

With ``damping_prior_std`` = s_ζ, every ζ gets a Gaussian prior N(``damping_ratio``, s_ζ²) too (rows
(ζ − ζ₀)/s_ζ, P's ζ entries 1/s_ζ²): on a short record the damping is as undetermined as the close
frequencies, and a free ζ lets the fit absorb noise (σ̂ too small, mode 4 at N = 20 ten times the error of
the fit with ζ held; measured in experiments.benchmarks.prior).
λ = 0 (Gauss–Newton) while steps succeed, else from 1e-3 × 4 per rejected step, ÷ 3 after an accepted one.
``extra["data_dof"]`` = tr(H_d (H_d + P)⁻¹): how many of the nonlinear unknowns the data determine. The prior term
curves the valley that a short record leaves flat, so the search needs a handful of iterations from the
prior mean. Starts: the prior mean, and the matrix pencil's when the record is long enough to carry one
(the data may then be far more precise than the prior, and the multi-modal loss of a long record needs
the data's own start); the lower Φ wins.

The posterior std reported is the Laplace approximation √diag((H_d + P)⁻¹) at the MAP. As s → ∞ the
prior rows vanish and Φ is the ML loss / σ̂²: the MAP tends to the output-error ML fit (test).

Hand-written rather than ``scipy.optimize.least_squares``: the variable projection (no library solves
separable least squares) and the ≤ 3 ms budget at 20–32 samples, where least_squares' own overhead per
call is of the order of the whole fit.
"""

from __future__ import annotations

import numpy as np

from methods.pem import search
from methods.pem._fast import _Model
from methods.pem._pencil import pencil_start

MAX_LM_ITERATIONS = 60
TOL_STEP = 1e-2              # stop when every step is below this many posterior std
TOL_COST = 1e-6              # … or Φ (a −2 log posterior) improves by less than this
PENCIL_MIN_SAMPLES = 48      # below, the pencil's poles are no better than the prior


def map_fit(y, dt, prior, prior_std, opts, bounds, free) -> dict:
    """The MAP fit (module docstring): a dict with θ = [ω, ζ, x₀, b], ``std_free`` (posterior std of the
    free unknowns; NaN for the linear ones), ``loss`` (mean square residual), ``cost`` (Φ), ``sigma2``,
    ``iterations``, ``message``, ``converged``, ``e``, ``start``."""
    m = prior.size
    est_z = bool(free[m])
    with_offset = bool(free[4 * m])
    model = _Model(y, dt, m, with_offset, 0.0)
    n = model.y.size
    z_prior = np.full(m, opts.damping_ratio)
    starts = [("prior", prior.copy(), z_prior)]
    if opts.data_driven_start and n >= PENCIL_MIN_SAMPLES:
        try:
            w0, z0 = pencil_start(y, dt, prior, extra_order=opts.pencil_extra_order,
                                  default_zeta=opts.damping_ratio, max_columns=120)
            starts.append(("pencil", w0, z0 if est_z else z_prior))
        except np.linalg.LinAlgError:
            pass
    lo, hi = bounds
    dof = n - (2 * m + with_offset)
    if dof < 1:
        return {"failed": f"{n} samples leave no degree of freedom for the noise after {n - dof} amplitudes"}
    best = None
    for label, w0, z0 in starts:
        try:
            fit = _lm(model, np.clip(np.concatenate([w0, z0]), lo, hi), prior, prior_std, dof, est_z, lo, hi, dt,
                      None if opts.damping_prior_std is None else (opts.damping_ratio, opts.damping_prior_std))
        except np.linalg.LinAlgError:
            continue
        fit["start"] = label
        if best is None or fit["cost"] < best["cost"]:
            best = fit
    if best is None:
        return {"failed": "the basis of the prior and pencil starts is singular"}
    return _result(best, m, free, n)


def _lm(model, x, mu, s, dof, est_z, lo, hi, dt, zeta_prior=None) -> dict:
    """Levenberg–Marquardt on Φ (module docstring); returns the point, Φ, ε, c, σ̂², the posterior
    covariance of (ω, ζ) and the data's effective degrees of freedom. ``zeta_prior`` = (mean, std) of a
    Gaussian prior on every ζ, or None (ζ free within its bounds)."""
    m, n = mu.size, model.y.size
    nn = m * (1 + est_z)
    p = np.zeros(nn)
    p[:m] = 1.0 / s**2
    centre = np.zeros(nn)
    centre[:m] = mu
    if est_z and zeta_prior is not None:
        centre[m:] = zeta_prior[0]
        p[m:] = 1.0 / zeta_prior[1] ** 2
    root_p = np.sqrt(p)

    def evaluate(x):
        sol = model.fit(x[:m], x[m:])
        if sol is None:
            return None
        c, e, _, solver = sol
        r = (x[:nn] - centre) * root_p
        rss = float(e @ e)
        if not rss > 0:
            return None
        return c, e, solver, dof * np.log(rss) + float(r @ r)

    def normal_equations(x, cur):
        c, e, solver, _ = cur
        Jr = model.reduced_jacobian(x[:m], x[m:], c, solver, est_z)
        sigma2 = float(e @ e) / dof
        Hd = (Jr.T @ Jr) / sigma2
        H = Hd.copy()
        H[np.diag_indices(nn)] += p
        g = (Jr.T @ e) / sigma2                    # ½∇(‖ε‖²/σ̂²) with J_r = P⊥ ∂ε/∂x
        g += (x[:nn] - centre) * p
        return Hd, H, g, sigma2

    cur = evaluate(x)
    if cur is None:
        raise np.linalg.LinAlgError("singular basis at the start")
    lam, it, message, converged = 0.0, 0, "iteration limit", False
    Hd, H, g, sigma2 = normal_equations(x, cur)
    while it < MAX_LM_ITERATIONS:
        it += 1
        scale = np.sqrt(np.maximum(H.diagonal(), np.finfo(float).tiny))
        Hs = H / np.outer(scale, scale)
        gs = g / scale
        accepted = False
        for _ in range(12):
            try:
                d = -np.linalg.solve(Hs + lam * np.eye(nn), gs) / scale
            except np.linalg.LinAlgError:
                lam = max(4.0 * lam, 1e-3)
                continue
            cand = x.copy()
            cand[:nn] += d
            np.clip(cand, lo, hi, out=cand)
            trial = evaluate(cand) if search.valid_modes(cand[:m], cand[m:], dt, n) else None
            if trial is not None and trial[3] < cur[3]:
                accepted = True
                break
            lam = max(4.0 * lam, 1e-3)
        if not accepted:
            message, converged = "no decrease of the posterior cost along the damped step", True
            break
        step = np.abs(cand[:nn] - x[:nn])
        gain = cur[3] - trial[3]
        x, cur = cand, trial
        lam = lam / 3.0 if lam > 1e-6 else 0.0
        Hd, H, g, sigma2 = normal_equations(x, cur)
        try:
            post_std = np.sqrt(np.abs(np.diag(np.linalg.inv(H))))
        except np.linalg.LinAlgError:
            post_std = np.full(nn, np.inf)
        if (step <= TOL_STEP * post_std).all() or gain <= TOL_COST:
            message, converged = "step below tolerance", True
            break
    try:
        cov = np.linalg.inv(H)
        edf = float(np.trace(cov @ Hd))
    except np.linalg.LinAlgError:
        cov, edf = np.full((nn, nn), np.nan), float(nn)
    return {"x": x, "cost": cur[3], "e": cur[1], "c": cur[0], "cov": cov, "edf": edf, "iterations": it,
            "message": message, "converged": converged, "sigma2": sigma2}


def _result(fit: dict, m: int, free, n: int) -> dict:
    """The pem fit dict (θ, loss, std of the free unknowns, ...) of a MAP fit."""
    x, c = fit["x"], fit["c"]
    theta = np.zeros(4 * m + 1)
    theta[:2 * m] = x
    theta[2 * m:4 * m:2], theta[2 * m + 1:4 * m:2] = c[:m], c[m:2 * m]
    if c.size > 2 * m:
        theta[4 * m] = c[2 * m]
    nn = fit["cov"].shape[0]
    std = np.full(int(sum(free)), np.nan)
    std[:nn] = np.sqrt(np.abs(np.diag(fit["cov"])))
    e = fit["e"]
    return {"theta": theta, "loss": float(e @ e) / n, "cost": fit["cost"], "e": e, "J": None,
            "std_free": std, "iterations": fit["iterations"], "message": fit["message"],
            "converged": fit["converged"], "start": fit["start"], "sigma2": fit["sigma2"], "edf": fit["edf"],
            "joined": False, "step_lengths": []}
