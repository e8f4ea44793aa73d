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
import scipy.special

from methods.pem import search
from methods.pem._fast import _Model
from methods.pem._pencil import pencil_start

MAX_LM_ITERATIONS = 60
TOL_STEP = 1e-2              # stop when every step is below this many posterior std
TOL_COST = 1e-6              # … or Φ (a −2 log posterior) improves by less than this
PENCIL_MIN_SAMPLES = 48      # below, the pencil's poles are no better than the prior
PROPOSAL_DOF = 5             # the importance sampler's proposal: a multivariate t with these degrees of freedom,
PROPOSAL_SCALE = 1.5         # … the Laplace covariance scaled by this squared
RIDGE = 1e-12                # on the unit diagonal of the sampler's normal equations (_projected_rss)
CHUNK_ELEMENTS = 256 * 9 * 32  # basis entries per block of draws in _projected_rss


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
    zeta_prior = None if opts.damping_prior_std is None else (opts.damping_ratio, opts.damping_prior_std)
    fits = []
    for label, w0, z0 in starts:
        try:
            fit = _lm(model, np.clip(np.concatenate([w0, z0]), lo, hi), prior, prior_std, dof, est_z, lo, hi, dt,
                      zeta_prior)
        except np.linalg.LinAlgError:
            continue
        fit["start"] = label
        fits.append(fit)
    if not fits:
        return {"failed": "the basis of the prior and pencil starts is singular"}
    best = min(fits, key=lambda f: f["cost"])
    # a maximum whose frequencies are not in the prior's order is a relabelling of another: the prior of
    # a labelled mode list is zero there (the SMC limit truncates it alike)
    order = np.argsort(prior, kind="stable")
    best["maxima"] = laplace_mixture([f for f in fits if np.all(np.diff(f["x"][:m][order]) > 0)], m)
    best["summary"] = opts.posterior_summary
    if opts.posterior_draws > 0:
        best["sampled"] = posterior_mean(best, model.y, dt, prior, prior_std, est_z, with_offset, dof, zeta_prior,
                                         bounds, opts.posterior_draws, opts.seed)
    return _result(best, m, free, n)


def laplace_mixture(fits: list[dict], m: int) -> dict:
    """The posterior as a mixture of Laplace approximations, one per distinct local maximum among the
    searches (two are the same when every frequency differs by less than half its posterior std):
    weights ∝ exp(−Φ/2)·√det Σ (the Laplace evidence of each maximum), the mixture's mean and std of ω
    (the posterior mean and std it implies), and how many maxima there were."""
    distinct = []
    for f in sorted(fits, key=lambda f: f["cost"]):
        if not np.all(np.isfinite(f["cov"])):
            continue
        sd = np.sqrt(np.abs(np.diag(f["cov"])))[:m]
        if all(np.any(np.abs(f["x"][:m] - g["x"][:m]) > 0.5 * sd) for g in distinct):
            distinct.append(f)
    if not distinct:
        return {"count": 0}
    log_w = np.array([-0.5 * f["cost"] + 0.5 * np.linalg.slogdet(f["cov"])[1] for f in distinct])
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    nn = distinct[0]["cov"].shape[0]                     # (ω, ζ) when ζ is estimated, else ω
    x = np.array([f["x"][:nn] for f in distinct])
    var = np.array([np.abs(np.diag(f["cov"])) for f in distinct])
    mean = w @ x
    # Σ wₖ (σₖ² + (xₖ − x̄)²): the law of total variance about the mean, not E[x²] − x̄², which cancels to
    # zero when σ is below ~1e-8 of x (a 20 rad/s mode at 0.1 µg on 256 samples)
    return {"count": len(distinct), "weights": w, "mean": mean,
            "std": np.sqrt(w @ (var + (x - mean) ** 2))}


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


def _projected_rss(y, w, z, dt, with_offset) -> np.ndarray:
    """:func:`_projected_rss_block` over blocks of draws whose bases stay in cache (~0.6 MB each: on a
    2 MB L2, 1024 draws × 32 samples at once took 1.7× the time of four blocks of 256;
    interleaved medians)."""
    rows = max(1, CHUNK_ELEMENTS // ((2 * w.shape[1] + 1) * y.size))
    return np.concatenate([_projected_rss_block(y, w[i:i + rows], z[i:i + rows], dt, with_offset)
                           for i in range(0, w.shape[0], rows)])


def _projected_rss_block(y, w, z, dt, with_offset) -> np.ndarray:
    """‖y − B_k c_k‖² for every draw k, c_k the least-squares coefficients of draw k's basis B_k (initial
    state, offset), vectorised over the draws.

    The columns (normalised to unit length) are solved by their normal equations, G_k c = B_kᵀy, stacked
    9 × 9 systems, and the residual is then formed explicitly. The RSS is stationary in c, so an error δ in
    the solved c (relative size ~cond(G)·ε) changes it by δᵀG δ only, second order — unlike ‖y‖² − bᵀG⁻¹b,
    which loses cond(G)·ε‖y‖² to cancellation. A ridge of 1e-12 on the unit diagonal keeps coincident
    frequencies solvable. The powers pᵏ come from one cumulative product (relative error ~Nε). Test: against
    numpy's lstsq on each draw's basis, within 1e-6 relative (2e-11 measured at 1 mg), and 1e-2 (7e-5
    measured) where the RSS is 1e-20 of ‖y‖²; coincident pairs included. It replaced a twice-applied
    Gram–Schmidt that cost 2–3× as much (the sampler's time per fit: experiments.benchmarks.prior
    --posterior-draws)."""
    k, m = w.shape
    n = y.size
    p = np.exp((-z * w + 1j * w * np.sqrt(1.0 - z**2)) * dt)                    # (K, m)
    rot = np.empty((k, m, n), complex)
    rot[:, :, 0] = 1.0
    np.cumprod(np.broadcast_to(p[:, :, None], (k, m, n - 1)), axis=2, out=rot[:, :, 1:])
    cols = [rot.real, rot.imag] + ([np.ones((k, 1, n))] if with_offset else [])
    basis = np.concatenate(cols, axis=1)                                         # (K, q, n)
    basis /= np.sqrt(np.einsum("kqn,kqn->kq", basis, basis))[:, :, None]
    gram = basis @ basis.transpose(0, 2, 1)
    gram[:, np.arange(gram.shape[1]), np.arange(gram.shape[1])] += RIDGE
    c = np.linalg.solve(gram, np.einsum("kqn,n->kq", basis, y)[:, :, None])[:, :, 0]
    r = y - np.einsum("kq,kqn->kn", c, basis)
    return np.einsum("kn,kn->k", r, r)


def posterior_mean(fit: dict, y, dt, mu, s, est_z, with_offset, dof, zeta_prior, bounds, draws: int,
                   seed: int) -> tuple[np.ndarray, np.ndarray, float] | None:
    """E[(ω, ζ) | y] and the posterior std by adaptive importance sampling around the MAP (module
    docstring). Round 1: ``draws`` points from a multivariate t (ν = :data:`PROPOSAL_DOF`) centred on the
    MAP with the Laplace covariance scaled by :data:`PROPOSAL_SCALE`²; round 2: as many from a t with the
    first round's weighted mean and covariance (so scaled), which follows a skewed posterior. Weights
    exp(−Φ/2)/q, Φ the posterior cost of :func:`_lm` (linear unknowns projected out, σ integrated out),
    the prior restricted to increasing frequencies; both rounds pooled, each with its own q (the
    deterministic-mixture weights of Owen & Zhou 2000). Returns (mean, std, effective sample size), or
    None where the Laplace covariance is unusable."""
    m, n = mu.size, y.size
    nn = m * (1 + est_z)
    if not np.all(np.isfinite(fit["cov"])):
        return None
    rng = np.random.default_rng([seed, 0x4D4150])
    lo, hi = bounds
    centre = np.r_[mu, np.full(nn - m, 0.0 if zeta_prior is None else zeta_prior[0])]
    p = np.r_[1.0 / s**2, np.full(nn - m, 0.0 if zeta_prior is None else 1.0 / zeta_prior[1] ** 2)]
    z_held = fit["x"][m:2 * m]
    nu = PROPOSAL_DOF
    proposals, xs, costs = [], [], []
    loc, cov = fit["x"][:nn], fit["cov"]
    for _ in range(2):
        try:
            chol = np.linalg.cholesky(0.5 * (cov + cov.T) * PROPOSAL_SCALE**2)
        except np.linalg.LinAlgError:
            return None
        u = rng.standard_normal((draws, nn)) @ chol.T
        x = loc + u / np.sqrt(rng.chisquare(nu, draws) / nu)[:, None]
        proposals.append((loc, chol))
        w, z = x[:, :m], (x[:, m:] if est_z else np.broadcast_to(z_held, (draws, m)))
        ok = (np.all(np.diff(w, axis=1) > 0, axis=1) & np.all((w > lo[:m]) & (w < hi[:m]), axis=1)
              & np.all((z > lo[m:]) & (z < hi[m:]), axis=1)
              & np.all(-z * w * dt * n < search.MAX_GROWTH_EXPONENT, axis=1))
        cost = np.full(draws, np.inf)              # a draw outside the support has weight zero
        k = np.flatnonzero(ok)
        if k.size:
            rss = _projected_rss(y, w[k], z[k], dt, with_offset)
            cost[k] = dof * np.log(np.maximum(rss, np.finfo(float).tiny)) + np.sum((x[k] - centre) ** 2 * p, axis=1)
        xs.append(x)
        costs.append(cost)
        x_all, cost_all = np.vstack(xs), np.concatenate(costs)
        keep = np.isfinite(cost_all)
        if keep.sum() < 2:
            return None
        x_all = x_all[keep]
        # log of the pooled proposal density (each t normalised by its Cholesky factor)
        log_q = scipy.special.logsumexp(
            [-0.5 * (nu + nn) * np.log1p(np.sum(np.linalg.solve(c, (x_all - l).T) ** 2, axis=0) / nu)
             - np.sum(np.log(np.diag(c))) for l, c in proposals], axis=0)
        lw = -0.5 * cost_all[keep] - log_q
        wt = np.exp(lw - lw.max())
        wt /= wt.sum()
        loc = wt @ x_all
        d = x_all - loc
        cov = (wt[:, None] * d).T @ d
    return loc, np.sqrt(np.diag(cov)), float(1.0 / np.sum(wt**2))


def _result(fit: dict, m: int, free, n: int) -> dict:
    """The pem fit dict (θ, loss, std of the free unknowns, ...) of a MAP fit."""
    x, c = fit["x"].copy(), fit["c"]
    nn = fit["cov"].shape[0]
    sd = np.sqrt(np.abs(np.diag(fit["cov"])))
    summary = "mode"
    if fit.get("summary") == "mean":           # the posterior mean: sampled, else the Laplace mixture's
        if fit.get("sampled") is not None:
            x[:nn], sd, summary = fit["sampled"][0], fit["sampled"][1], "importance-sampled mean"
        elif fit["maxima"].get("count", 0) > 0:
            x[:nn], sd, summary = fit["maxima"]["mean"][:nn], fit["maxima"]["std"][:nn], "Laplace-mixture mean"
    theta = np.zeros(4 * m + 1)
    theta[:2 * m] = x
    theta[2 * m:4 * m:2], theta[2 * m + 1:4 * m:2] = c[:m], c[m:2 * m]
    if c.size > 2 * m:
        theta[4 * m] = c[2 * m]
    std = np.full(int(sum(free)), np.nan)
    std[:nn] = sd
    e = fit["e"]
    return {"theta": theta, "loss": float(e @ e) / n, "cost": fit["cost"], "e": e, "J": None,
            "std_free": std, "iterations": fit["iterations"], "message": fit["message"],
            "converged": fit["converged"], "start": fit["start"], "sigma2": fit["sigma2"], "edf": fit["edf"],
            "joined": False, "step_lengths": [], "summary": summary,
            "maxima": int(fit["maxima"].get("count", 0)),
            "ess": float("nan") if fit.get("sampled") is None else fit["sampled"][2]}
