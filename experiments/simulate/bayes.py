"""The Bayesian yardstick of the frequencies: the van Trees bound and the attainable (MMSE) limit.

When the prior is information (ω ~ N(μ, diag(s²)), truths drawn from it), the classical Cramér–Rao bound
(:mod:`experiments.simulate.crlb`) ignores what the prior knows and is huge or undefined on short records.
Two numbers per (cell, mode) replace it there:

**van Trees bound** (the Bayesian Cramér–Rao bound; Van Trees 1968, Gill & Levit 1995). With the signal
model of crlb.py, unknowns θ = (aᵢ, φᵢ, ωᵢ, ζᵢ per mode [, offset]), Fisher information J_data(θ) = GᵀG/σ²
and a Gaussian prior on the frequencies only (the other unknowns held at their values: a hybrid bound),

    B = ( E_prior[ J_data(θ) ] + J_prior )⁻¹,     J_prior = diag(1/sᵢ²) on the ω entries, 0 elsewhere,

and the bound on the RMSE of ωᵢ is √B_ωᵢωᵢ. The expectation over the prior is a tensor Gauss–Hermite
quadrature in the m frequencies (``points`` per mode; numpy's ``hermegauss``). It is a lower bound on the
RMSE of every estimator, but loose where the record cannot separate modes: averaging the information over
the prior overstates it (J_data is large for draws that happen to separate, and the average of an
information is not the information of the average).

**Attainable limit**: the RMSE of the posterior-mean (MMSE) estimator, which no estimator beats on truths
drawn from the prior. For each of R records (truth drawn from the prior, noise of σ), E[ω | y] is computed
by importance sampling, weights wₖ ∝ p(y | ωₖ)·prior(ωₖ)/q(ωₖ) with the linear unknowns (the amplitudes
and phases as cos/sin coefficients, and the offset) **projected out** — set to their least-squares values,
p(y | ω) ∝ exp(−RSS(ω)/2σ²) — and the damping held at its value (known, so the limit is slightly
optimistic). Importance sampling from the prior alone collapses (effective sample size ~1) as soon as one
mode is sharply determined (mode 4 at 1 mg from N = 32 on), so the posterior is reached by sequential Monte
Carlo with likelihood tempering (:func:`smc_posterior_mean`): importance sampling in stages with
resampling and Metropolis moves. Then RMSE = √(mean over records of (E[ω|y] − ω_true)²).

Written here because no kept library computes either quantity for this model.
"""

from __future__ import annotations

import itertools

import numpy as np
import scipy.special

from experiments.simulate.crlb import signal_jacobian

__all__ = ["fisher_information", "van_trees_std", "basis", "posterior_mean", "projected_log_likelihood",
           "orthonormal_bases", "projected_log_likelihoods", "MOVES", "ESS_TARGET", "smc_posterior_mean",
           "importance_posterior_mean",
           "mmse_rmse", "draw_prior", "signal"]


def fisher_information(freq_rad_s, damping, amplitude, phase, n_samples: int, dt_s: float, noise_std: float,
                       *, offset: bool = False) -> np.ndarray:
    """J_data = GᵀG/σ² of the signal model of crlb.py (unknowns (a, φ, ω, ζ) per mode [, offset])."""
    t = np.arange(int(n_samples)) * float(dt_s)
    G = signal_jacobian(freq_rad_s, damping, amplitude, phase, t, offset=offset)
    return (G.T @ G) / float(noise_std) ** 2


def van_trees_std(prior_mean, prior_std, damping, amplitude, phase, n_samples: int, dt_s: float,
                  noise_std: float, *, offset: bool = False, points: int = 5,
                  known_damping: bool = False) -> np.ndarray:
    """√diag of B = (E_prior[J_data] + J_prior)⁻¹ on the frequencies (module docstring), rad/s.

    Parameters
    ----------
    prior_mean, prior_std : array_like, shape (m,)
        μ and s of the Gaussian prior of the frequencies, rad/s.
    damping, amplitude, phase : array_like, shape (m,)
        The other unknowns' values (held: a hybrid bound).
    n_samples, dt_s, noise_std : the record (noise 1σ in the amplitudes' units).
    offset : bool
        A constant sensor offset unknown too.
    points : int
        Gauss–Hermite nodes per mode (points^m evaluations of J_data).
    known_damping : bool
        The damping ratios known (their rows and columns dropped from J), as the MMSE limit assumes.

    Returns
    -------
    ndarray, shape (m,)
    """
    mu, s = np.asarray(prior_mean, float), np.asarray(prior_std, float)
    m = mu.size
    if not (np.all(s > 0) and points >= 1):
        raise ValueError(f"prior_std = {s.tolist()} must be positive and points = {points} at least 1")
    x, w = np.polynomial.hermite_e.hermegauss(points)          # ∫ f(x) e^{−x²/2} dx ≈ Σ wⱼ f(xⱼ)
    w = w / w.sum()
    p = 4 * m + offset
    expected = np.zeros((p, p))
    for idx in itertools.product(range(points), repeat=m):
        idx = list(idx)
        freq = mu + s * x[idx]
        expected += np.prod(w[idx]) * fisher_information(freq, damping, amplitude, phase, n_samples, dt_s,
                                                          noise_std, offset=offset)
    omega = 4 * np.arange(m) + 2
    expected[omega, omega] += 1.0 / s**2
    if known_damping:
        keep = np.setdiff1d(np.arange(p), 4 * np.arange(m) + 3)
        expected = expected[np.ix_(keep, keep)]
        omega = np.searchsorted(keep, omega)
    # inverse through the column-scaled eigendecomposition: J is as badly conditioned as in crlb.py
    d = np.sqrt(np.diag(expected))
    d[d == 0] = 1.0
    lam, V = np.linalg.eigh(expected / np.outer(d, d))
    lam = np.maximum(lam, lam.max() * np.finfo(float).eps)
    cov = (V / lam) @ V.T / np.outer(d, d)
    return np.sqrt(np.diag(cov)[omega])


def basis(freq_rad_s, damping, t, offset: bool) -> np.ndarray:
    """Columns e^{−ζωt}cos(ω_d t), e^{−ζωt}sin(ω_d t) per mode [, 1]: the model linear in its amplitudes.
    ``freq_rad_s`` may be (K, m): then (K, N, 2m [+1])."""
    w = np.atleast_2d(np.asarray(freq_rad_s, float))
    z = np.asarray(damping, float)
    z = z if z.ndim == 2 else np.broadcast_to(z, w.shape)   # one damping vector per draw, or one for all
    k, m = w.shape
    p = _modal_powers(((-z + 1j * np.sqrt(1 - z**2)) * w).T, np.asarray(t, float))     # (m, N, K)
    out = np.empty((k, p.shape[1], 2 * m + offset))
    out[:, :, :m] = p.real.T
    out[:, :, m:2 * m] = p.imag.T
    if offset:
        out[:, :, 2 * m] = 1.0
    return out


def _modal_powers(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """e^{sᵢₖ tⱼ}, shape (m, N, K), for poles s (m, K) in rad/s (the draws last: numpy's loops run along
    them). On a uniform grid tⱼ = t₀ + jΔt (N ≥ 16) as e^{s(t₀ + rΔt)}·e^{s·qBΔt} (j = qB + r, B the power
    of two at or above √N): 2√N complex exponentials per pole instead of N, each factor exact to rounding
    (the phase error (|t₀ + rΔt| + |qBΔt|)·|ω|·ε of one exponential of s·tⱼ). The exponentials were most of
    the yardstick's time: numpy's exp, cos and sin cost 30–60 ns an entry here, the product 2."""
    n = t.size
    dt = t[1] - t[0] if n > 1 else 0.0
    # uniform to 1e-12 relative (numpy's allclose test, written out: allclose costs ~0.1 ms a call here)
    if n < 16 or not (dt > 0 and bool((np.abs(np.diff(t) - dt) <= 1e-12 * dt).all())):
        return np.exp(t[None, :, None] * s[:, None, :])
    block = 1 << int(np.ceil(np.log2(np.sqrt(n))))
    head = np.exp((t[0] + dt * np.arange(block))[None, :, None] * s[:, None, :])               # (m, B, K)
    steps = np.exp((dt * block * np.arange(-(-n // block)))[None, :, None] * s[:, None, :])     # (m, Q, K)
    return (steps[:, :, None, :] * head[:, None, :, :]).reshape(s.shape[0], -1, s.shape[1])[:, :n]


def posterior_mean(log_likelihood: np.ndarray, samples: np.ndarray) -> tuple[np.ndarray, float]:
    """Self-normalised importance estimate of E[θ | y] with prior draws ``samples`` (K, d) as proposal and
    log-likelihoods (K,): Σ wₖθₖ / Σ wₖ, wₖ = e^{ℓₖ}; and the effective sample size (Σw)²/Σw²."""
    lw = log_likelihood - scipy.special.logsumexp(log_likelihood)
    w = np.exp(lw)
    return w @ samples, float(1.0 / np.sum(w**2))


def projected_log_likelihood(y: np.ndarray, U: np.ndarray, noise_std: float) -> np.ndarray:
    """log p(y | ωₖ) up to a constant, linear unknowns at their least-squares values: −RSSₖ/2σ² with
    RSSₖ = ‖y‖² − ‖Uₖᵀy‖² (Uₖ the orthonormal basis of draw k's columns)."""
    proj = np.einsum("knp,n->kp", U, y)
    rss = float(y @ y) - np.sum(proj**2, axis=1)
    return -0.5 * rss / noise_std**2


def orthonormal_bases(freq_draws, damping, t, offset: bool, rcond: float = 1e-10) -> np.ndarray:
    """Q of the thin (Householder) QR of every draw's basis (K, N, p), the directions whose |Rᵢᵢ| is below
    ``rcond`` × the largest zeroed (rank-safe). Backward stable as the SVD, and 2–4× faster on these
    shapes (K = 250, N = 20–128, p = 9), which is most of the posterior mean's cost."""
    Q, R = np.linalg.qr(basis(freq_draws, damping, t, offset))
    d = np.abs(np.diagonal(R, axis1=1, axis2=2))
    return Q * (d > rcond * d.max(axis=1, keepdims=True))[:, None, :]


def projected_log_likelihoods(y: np.ndarray, freq_draws, damping, t, offset: bool, noise_std: float,
                              rcond: float = 1e-10) -> np.ndarray:
    """:func:`projected_log_likelihood` of every draw's basis, from the R of one Householder QR of the basis
    with y appended, [B y] = Q[R_B r; 0 ρ]: RSS = ρ². No Q is formed and RSS is not ‖y‖² − ‖Qᵀy‖² (no
    cancellation): half the QR's time on these shapes. A draw whose basis is rank-deficient (some |R_ii| at or
    below ``rcond`` × the largest: repeated modes) gets its RSS from a rank-revealing least squares instead
    (numpy's ``lstsq``, LAPACK's SVD-based gelsd): its columns' span is not that of the Householder directions
    kept (the later columns have components along a dropped one), so no formula on R alone gives it. Rare:
    the prior's draws are distinct."""
    B = basis(freq_draws, damping, t, offset)
    y = np.asarray(y, float)
    k, n, p = B.shape
    # mode 'raw' is LAPACK's geqrf output as it stands (R in its upper triangle, transposed): the R of mode
    # 'r' without the copy that zeroes the Householder vectors below it
    R = np.linalg.qr(np.concatenate([B, np.broadcast_to(y[None, :, None], (k, n, 1))], axis=2),
                     mode="raw")[0].swapaxes(1, 2)
    d = np.abs(np.diagonal(R[:, :p, :p], axis1=1, axis2=2))
    rss = R[:, p, p] ** 2
    for i in np.flatnonzero(np.any(d <= rcond * d.max(axis=1, keepdims=True), axis=1)):
        coef = np.linalg.lstsq(B[i], y, rcond=rcond)[0]
        rss[i] = np.sum((y - B[i] @ coef) ** 2)
    return -0.5 * rss / noise_std**2


MOVES = 3              # Metropolis moves per tempering stage
ESS_TARGET = 0.5       # each stage keeps this share of the particles' effective sample size


def _prior_vectors(mu, s, damping, damping_std):
    """(μ, s, ζ₀ per mode, centre, spread): the prior of the sampled vector, (ω) or (ω, ζ) when
    ``damping_std`` gives ζ a Gaussian prior N(ζ₀, damping_std²)."""
    mu, s = np.asarray(mu, float), np.asarray(s, float)
    z0 = np.broadcast_to(np.asarray(damping, float), (mu.size,))
    if damping_std is None:
        return mu, s, z0, mu, s
    return mu, s, z0, np.r_[mu, z0], np.r_[s, np.broadcast_to(np.asarray(damping_std, float), (mu.size,))]


def smc_posterior_mean(y, t, mu, s, damping, noise_std: float, rng, *, particles: int = 1000,
                       ordered: bool = True, offset: bool = True, max_stages: int = 200, damping_std=None,
                       particles_out: bool = False):
    """E[ω | y] by sequential Monte Carlo with likelihood tempering (Del Moral, Doucet & Jasra 2006).

    Particles start as prior draws and move through π_β ∝ prior(ω)·p(y | ω)^β, β: 0 → 1. Each stage picks
    the next β by bisection so that the incremental weights keep an effective sample size of
    ``ESS_TARGET`` × particles, resamples (systematic), and moves every particle by :data:`MOVES` random-walk
    Metropolis steps with covariance 2.38²/m × the particles' covariance. The likelihood has the linear
    unknowns projected out (:func:`projected_log_likelihood`). Plain importance sampling from the prior is
    the one-stage case; it fails as soon as one mode is sharply determined (effective sample size ~1 for
    mode 4 at 1 mg from N = 32 on), which tempering avoids.

    ``damping_std``: the damping ratios unknown too, with the Gaussian prior N(``damping``, damping_std²)
    (|ζ| < 0.9); the particles then carry (ω, ζ) and the mean returned is that of ω. None: ζ known.

    Returns (E[ω | y] as the weighted particle mean at β = 1, the ESS of that last weighting, stages);
    ``particles_out``: also the last particles (K, d) and their weights (K,), a sample of the posterior.
    """
    mu, s, z0, centre, spread = _prior_vectors(mu, s, damping, damping_std)
    m = mu.size
    d = centre.size

    def log_prior(x):
        lp = -0.5 * np.sum(((x - centre) / spread) ** 2, axis=1)
        ok = np.all(x[:, :m] > 0, axis=1) & np.all(np.abs(x[:, m:]) < 0.9, axis=1)
        if ordered:
            ok &= np.all(np.diff(x[:, :m], axis=1) > 0, axis=1)
        return np.where(ok, lp, -np.inf)

    def log_lik(x):
        out = np.full(x.shape[0], -np.inf)
        w, z = x[:, :m], (x[:, m:] if damping_std is not None else z0)
        ok = np.all(w > 0, axis=1) & np.all(w * np.sqrt(1 - z**2) * (t[1] - t[0]) < np.pi, axis=1)
        if damping_std is not None:
            ok &= np.all(np.abs(z) < 0.9, axis=1)
        if ok.any():
            zk = z[ok] if damping_std is not None else z0
            out[ok] = projected_log_likelihoods(y, w[ok], zk, t, offset, noise_std)
        return out

    x = draw_prior(rng, mu, s, particles, ordered)
    if damping_std is not None:
        x = np.hstack([x, z0 + spread[m:] * rng.standard_normal((particles, m))])
    ll = log_lik(x)
    beta = 0.0
    for stage in range(1, max_stages + 1):
        def ess(b, beta=beta, ll=ll):
            lw = (b - beta) * ll               # in place and by methods: ~40 calls a stage, the same bits
            lw -= lw.max()
            np.exp(lw, out=lw)
            return lw.sum() ** 2 / (lw * lw).sum()

        if ess(1.0) >= ESS_TARGET * particles or stage == max_stages:
            nxt = 1.0
        else:
            lo, hi = beta, 1.0
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if ess(mid) >= ESS_TARGET * particles else (lo, mid)
            nxt = lo if lo > beta else 0.5 * (beta + hi)
        lw = (nxt - beta) * ll
        w = np.exp(lw - scipy.special.logsumexp(lw))
        if nxt >= 1.0:
            out = (w @ x[:, :m], float(1.0 / np.sum(w**2)), stage)
            return (*out, x, w) if particles_out else out
        beta = nxt
        # systematic resampling
        idx = np.searchsorted(np.cumsum(w), (rng.random() + np.arange(particles)) / particles)
        idx = np.minimum(idx, particles - 1)
        x, ll = x[idx], ll[idx]
        cov = np.cov(x, rowvar=False).reshape(d, d) * 2.38**2 / d + 1e-12 * np.diag(spread**2)
        chol = np.linalg.cholesky(cov + 1e-12 * np.trace(cov) * np.eye(d))
        lp = log_prior(x)
        for _ in range(MOVES):
            prop = x + rng.standard_normal((particles, d)) @ chol.T
            lp_new = log_prior(prop)
            ll_new = np.full(particles, -np.inf)
            finite = np.isfinite(lp_new)
            ll_new[finite] = log_lik(prop[finite])
            accept = np.log(rng.random(particles)) < (lp_new + beta * ll_new) - (lp + beta * ll)
            x[accept], ll[accept], lp[accept] = prop[accept], ll_new[accept], lp_new[accept]
    raise AssertionError("unreachable: the last stage sets β = 1")


def importance_posterior_mean(y, t, mu, s, damping, noise_std: float, rng, centres, *, draws: int = 20000,
                              centre_weights=None, defensive: float = 0.1, offset: bool = True,
                              ordered: bool = True, damping_std=None):
    """E[ω | y] by plain importance sampling, an estimate independent of the SMC's moves: the proposal q is
    a Gaussian kernel mixture on ``centres`` (K, d) — (ω [, ζ]) points, e.g. another run's posterior
    particles — with bandwidth Silverman's factor × their covariance, mixed with the prior itself (share
    ``defensive``, so that a posterior mode the centres miss is still proposed). Weights are exact,
    prior·likelihood/q, so the estimate is consistent whatever the centres. Returns (E[ω | y], ESS)."""
    mu, s, z0, centre, spread = _prior_vectors(mu, s, damping, damping_std)
    m = mu.size
    c = np.asarray(centres, float)
    k, d = c.shape
    cw = np.full(k, 1.0 / k) if centre_weights is None else np.asarray(centre_weights, float) / np.sum(centre_weights)
    cov = np.atleast_2d(np.cov(c, rowvar=False, aweights=cw)) * (4.0 / ((d + 2) * k)) ** (2.0 / (d + 4))
    cov += 1e-12 * np.diag(spread**2)
    chol = np.linalg.cholesky(cov)
    n_kernel = rng.binomial(draws, 1.0 - defensive)
    pick = rng.choice(k, size=n_kernel, p=cw)
    x = np.vstack([c[pick] + rng.standard_normal((n_kernel, d)) @ chol.T,
                   centre + spread * rng.standard_normal((draws - n_kernel, d))])
    # log q: the kernel mixture and the (untruncated) prior density
    inv = np.linalg.inv(chol)
    xc, cc = x @ inv.T, c @ inv.T
    log_kernel = np.empty(draws)
    for i in range(0, draws, 1000):                                      # (1000, K) distances at a time
        d2 = np.sum(xc[i:i + 1000] ** 2, axis=1)[:, None] - 2 * xc[i:i + 1000] @ cc.T + np.sum(cc**2, axis=1)
        log_kernel[i:i + 1000] = scipy.special.logsumexp(-0.5 * d2, axis=1, b=cw)
    log_kernel += -np.sum(np.log(np.diag(chol))) - 0.5 * d * np.log(2 * np.pi)
    log_prior_density = (-0.5 * np.sum(((x - centre) / spread) ** 2, axis=1) - np.sum(np.log(spread))
                         - 0.5 * d * np.log(2 * np.pi))
    log_q = np.logaddexp(np.log1p(-defensive) + log_kernel, np.log(defensive) + log_prior_density)
    w_, z = x[:, :m], (x[:, m:] if damping_std is not None else np.broadcast_to(z0, (draws, m)))
    ok = (np.all(w_ > 0, axis=1) & np.all(np.abs(z) < 0.9, axis=1)
          & np.all(w_ * np.sqrt(1 - np.minimum(z**2, 0.81)) * (t[1] - t[0]) < np.pi, axis=1))
    if ordered:
        ok &= np.all(np.diff(w_, axis=1) > 0, axis=1)
    lw = np.full(draws, -np.inf)
    idx = np.flatnonzero(ok)
    for i in range(0, idx.size, 4000):
        j = idx[i:i + 4000]
        ll = projected_log_likelihoods(y, w_[j], z[j], t, offset, noise_std)
        lw[j] = ll + log_prior_density[j] - log_q[j]
    mean, ess = posterior_mean(lw, x[:, :m])
    return mean, ess


def mmse_rmse(prior_mean, prior_std, damping, amplitude, phase, n_samples: int, dt_s: float, noise_std: float,
              *, offset: bool = False, records: int = 200, draws: int = 1000, seed: int = 0,
              ordered: bool = True) -> dict:
    """The attainable limit (module docstring): RMSE per mode of the posterior mean over ``records``
    truths drawn from the prior, each by :func:`smc_posterior_mean` with ``draws`` particles.

    ``ordered``: the prior is truncated to increasing frequencies (a draw that crosses two modes is redrawn),
    for the truths and the importance draws alike — the prior of a labelled mode list.

    Returns a dict: ``rmse`` (m,), ``prior_rmse`` (m,) (the prior mean as estimator, same truths), and
    ``ess_median``, ``ess_min`` over records.
    """
    mu, s = np.asarray(prior_mean, float), np.asarray(prior_std, float)
    amp, ph, z = (np.asarray(v, float) for v in (amplitude, phase, damping))
    rng = np.random.default_rng(seed)
    t = np.arange(int(n_samples)) * float(dt_s)
    truths = draw_prior(rng, mu, s, records, ordered)
    err, ess = np.zeros((records, mu.size)), np.zeros(records)
    for r, w in enumerate(truths):
        y = signal(w, z, amp, ph, t) + noise_std * rng.standard_normal(t.size)
        est, ess[r], _ = smc_posterior_mean(y, t, mu, s, z, noise_std, rng, particles=draws, ordered=ordered,
                                            offset=offset)
        err[r] = est - w
    return {"rmse": np.sqrt(np.mean(err**2, axis=0)), "prior_rmse": np.sqrt(np.mean((truths - mu) ** 2, axis=0)),
            "ess_median": float(np.median(ess)), "ess_min": float(ess.min())}


def draw_prior(rng, mu, s, k: int, ordered: bool) -> np.ndarray:
    """k draws of N(μ, diag(s²)); ``ordered``: only strictly increasing, positive ones (rejection)."""
    out = np.empty((0, mu.size))
    while out.shape[0] < k:
        d = mu + s * rng.standard_normal((2 * k, mu.size))
        keep = np.all(d > 0, axis=1) & (np.all(np.diff(d, axis=1) > 0, axis=1) if ordered else True)
        out = np.vstack([out, d[keep]])
    return out[:k]


def signal(freq_rad_s, damping, amplitude, phase, t) -> np.ndarray:
    """μ(t) = Σ aᵢ e^{−ζᵢωᵢt} cos(ωᵢrᵢt + φᵢ) (crlb.py's model)."""
    w, z = np.asarray(freq_rad_s, float), np.asarray(damping, float)
    tt = np.asarray(t, float)[:, None]
    return np.sum(amplitude * np.exp(-z * w * tt) * np.cos(w * np.sqrt(1 - z**2) * tt + phase), axis=1)
