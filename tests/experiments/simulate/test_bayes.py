"""The Bayesian yardstick: van Trees bound and importance-sampling MMSE (experiments.simulate.bayes)."""

import numpy as np
import pytest

from experiments.simulate import bayes


def test_van_trees_one_mode_matches_brute_force_integration():
    # brute force, independent of the module's Jacobian and quadrature: J_data from central differences of
    # the signal, averaged over the Gaussian prior by the trapezoid rule on ±8σ, then (E J + J_prior)⁻¹
    mu, s, z, a, ph, n, dt, sigma = 10.0, 0.5, 0.01, 1.0, 0.3, 24, 0.02, 0.05
    t = np.arange(n) * dt

    def f(q):
        return q[0] * np.exp(-q[3] * q[2] * t) * np.cos(q[2] * np.sqrt(1 - q[3] ** 2) * t + q[1])

    def jac(w):
        th = np.array([a, ph, w, z])
        cols = []
        for i in range(4):
            h = 1e-6 * max(abs(th[i]), 1.0)
            up, dn = th.copy(), th.copy()
            up[i] += h
            dn[i] -= h
            cols.append((f(up) - f(dn)) / (2 * h))
        G = np.column_stack(cols)
        return G.T @ G / sigma**2

    grid = np.linspace(mu - 8 * s, mu + 8 * s, 4001)
    dens = np.exp(-0.5 * ((grid - mu) / s) ** 2)
    dens /= np.trapezoid(dens, grid)
    EJ = np.trapezoid(np.array([jac(w) for w in grid]) * dens[:, None, None], grid, axis=0)
    EJ[2, 2] += 1 / s**2
    brute = np.sqrt(np.linalg.inv(EJ)[2, 2])
    vt = bayes.van_trees_std([mu], [s], [z], [a], [ph], n, dt, sigma, points=20)
    assert vt[0] == pytest.approx(brute, rel=1e-4)
    assert vt[0] < s                                   # the record adds information to the prior


def test_importance_posterior_mean_matches_the_linear_gaussian_closed_form():
    # θ ~ N(μ, S) in 2-D, y = Hθ + e, e ~ N(0, σ²I): posterior mean (S⁻¹ + HᵀH/σ²)⁻¹(S⁻¹μ + Hᵀy/σ²), and the
    # MMSE is √diag of the posterior covariance, the same for every y
    rng = np.random.default_rng(3)
    mu, S = np.array([1.0, -2.0]), np.diag([0.5**2, 0.8**2])
    H, sigma = np.array([[1.0, 0.5], [0.2, 1.0], [1.0, -1.0]]), 0.6
    post_cov = np.linalg.inv(np.linalg.inv(S) + H.T @ H / sigma**2)
    samples = rng.multivariate_normal(mu, S, 40000)
    errs, ests = [], []
    for _ in range(400):
        theta = rng.multivariate_normal(mu, S)
        y = H @ theta + sigma * rng.standard_normal(3)
        loglik = -0.5 * np.sum((y - samples @ H.T) ** 2, axis=1) / sigma**2
        est, ess = bayes.posterior_mean(loglik, samples)
        exact = post_cov @ (np.linalg.solve(S, mu) + H.T @ y / sigma**2)
        # importance error of one record: ~ posterior std / √ESS; 5 of them bound it
        assert np.all(np.abs(est - exact) <= 5 * np.sqrt(np.diag(post_cov) / ess))
        ests.append(ess)
        errs.append(est - theta)
    assert np.median(ests) > 1000
    np.testing.assert_allclose(np.sqrt(np.mean(np.square(errs), axis=0)), np.sqrt(np.diag(post_cov)), rtol=0.1)


def test_yardstick_orders_van_trees_mmse_and_prior_on_a_short_record():
    # one mode, N = 20, 1 mg-like SNR: van Trees ≤ MMSE ≤ prior RMSE (within Monte-Carlo scatter)
    mu, s = np.array([20.0]), np.array([1.0])
    args = ([0.005], [1.0], [0.0], 20, 0.02, 0.3)
    vt = bayes.van_trees_std(mu, s, *args, offset=True)
    lim = bayes.mmse_rmse(mu, s, *args, offset=True, records=120, draws=1500, seed=1)
    assert vt[0] <= 1.1 * lim["rmse"][0]
    assert lim["rmse"][0] < 0.9 * lim["prior_rmse"][0]
    assert lim["ess_median"] > 50


def test_importance_posterior_mean_agrees_with_a_grid_integral_in_one_mode():
    # the independent check of the SMC limit: a one-mode posterior (σ known, ζ known) integrated on a grid
    rng = np.random.default_rng(5)
    n, dt, mu, s, sigma = 24, 0.02, np.array([10.0]), np.array([0.4]), 0.5
    t = np.arange(n) * dt
    y = bayes.signal([10.3], [0.005], [1.0], [0.3], t) + sigma * rng.standard_normal(n)
    grid = np.linspace(mu[0] - 6 * s[0], mu[0] + 6 * s[0], 4001)
    ll = bayes.projected_log_likelihood(y, bayes.orthonormal_bases(grid[:, None], [0.005], t, True), sigma)
    lp = ll - 0.5 * ((grid - mu[0]) / s[0]) ** 2
    p = np.exp(lp - lp.max())
    p /= p.sum()
    exact, sd = p @ grid, np.sqrt(p @ (grid - p @ grid) ** 2)
    centres = (mu + s * rng.standard_normal((300, 1)))             # deliberately poor centres: the prior's
    est, ess = bayes.importance_posterior_mean(y, t, mu, s, [0.005], sigma, rng, centres, draws=20000)
    assert ess > 500
    assert abs(est[0] - exact) < 0.05 * sd


def test_projected_log_likelihoods_match_least_squares_per_draw_including_a_repeated_mode():
    rng = np.random.default_rng(3)
    t = np.arange(40) * 0.05
    zeta = np.array([0.03, 0.03])
    draws = np.array([[3.0, 11.0], [4.0, 4.0], [7.5, 9.0]])        # the middle draw: two pairs of equal columns
    y = bayes.signal([3.2, 10.5], zeta, [1.0, 0.5], [0.3, -1.0], t) + 0.2 + 0.1 * rng.standard_normal(t.size)
    got = bayes.projected_log_likelihoods(y, draws, zeta, t, True, 0.1)
    for k, w in enumerate(draws):
        B = bayes.basis(w, zeta, t, True)[0]
        coef = np.linalg.lstsq(B, y, rcond=1e-10)[0]             # minimum-norm on the rank-deficient draw
        rss = np.sum((y - B @ coef) ** 2)
        assert got[k] == pytest.approx(-0.5 * rss / 0.1**2, rel=1e-8)


def test_basis_on_a_uniform_grid_matches_the_direct_exponentials_to_rounding_at_256_samples():
    rng = np.random.default_rng(4)
    w = np.sort(rng.uniform(1.0, 150.0, (50, 4)), axis=1)
    zeta = rng.uniform(0.0, 0.1, (50, 4))
    for t in (1.5 + np.arange(256) * 0.02, np.sort(rng.uniform(0.0, 5.0, 256))):   # blocked, then direct path
        got = bayes.basis(w, zeta, t, True)
        tt = t[None, :, None]
        decay, wd = np.exp(-(zeta * w)[:, None, :] * tt), (w * np.sqrt(1 - zeta**2))[:, None, :]
        direct = np.concatenate([decay * np.cos(wd * tt), decay * np.sin(wd * tt), np.ones((50, t.size, 1))], axis=2)
        # each entry's phase ωt is itself known to ~|ωt|·ε, the same for both ways of computing it
        assert np.max(np.abs(got - direct)) < 1e-12
