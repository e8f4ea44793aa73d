"""The closed-form output-error predictor of pem: exact derivatives, the same answers as the
recursive reference predictor, linear cost in N, and honest answers on records without information."""

from __future__ import annotations

import numpy as np
import pytest

from methods import pem
from methods.pem import _fast as _pem_fast
from methods.pem import predictor as pp

DT = 0.02
TRUE_W = np.array([3.23, 20.24, 22.00, 56.67])        # Table 3
TABLE4_PRIOR = np.array([2.65, 16.73, 17.32, 52.91])   # Table 4


def damped_sinusoids(w, zeta, amp_cos, amp_sin, n, offset=0.0):
    """Σ e^{−ζωt}(A cos ω_d t + B sin ω_d t) + b, the output-error model's own output."""
    t = np.arange(n)[:, None] * DT
    wd = w * np.sqrt(1 - zeta**2)
    return (np.exp(-zeta * w * t) * (amp_cos * np.cos(wd * t) + amp_sin * np.sin(wd * t))).sum(1) + offset


@pytest.mark.parametrize("free_damping, free_offset", [(True, True), (False, False), (True, False)])
def test_closed_form_jacobian_matches_central_differences(free_damping, free_offset):
    """∂ε/∂θ of the closed form (chain rule through σ = ζω, ω_d = ω√(1−ζ²)) against central differences."""
    n, m = 300, 4
    free = tuple([True] * m + [free_damping] * m + [True] * (2 * m) + [free_offset])
    rng = np.random.default_rng(2)
    y = rng.standard_normal(n)
    theta = np.r_[TRUE_W * 1.01, [0.02, 0.01, -0.03, 0.01], rng.standard_normal(2 * m), 0.1]
    ev = pp.ClosedForm(y, DT, m, free)
    e, J = ev.residual_jacobian(theta)
    np.testing.assert_allclose(e, ev.residual(theta), rtol=0, atol=1e-14)
    idx = np.flatnonzero(free)
    J_fd = np.empty_like(J)
    for k, j in enumerate(idx):
        h = 1e-6 * max(abs(theta[j]), 1e-2)
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        J_fd[:, k] = (ev.residual(up) - ev.residual(down)) / (2 * h)
    assert np.max(np.abs(J - J_fd) / np.abs(J).max(axis=0)) < 1e-6       # central differences: ~1e-7
    e0, G = ev.linear_part(theta)                   # ε affine in (x₀, b): G is J's linear columns
    np.testing.assert_array_equal(G, J[:, idx >= 2 * m])


@pytest.mark.parametrize("n", [64, 3000])
def test_closed_form_equals_the_recursive_predictor(n):
    """K = 0: the closed form and the CasADi recursion x̂(k+1) = φx̂(k) give the same ε and ∂ε/∂θ
    (3000 > 2·512 exercises the blocked powers e^{jBs Δt}·e^{rsΔt})."""
    m = 4
    free = (True,) * pp.n_params(m)
    rng = np.random.default_rng(3)
    y = rng.standard_normal(n)
    theta = np.r_[TRUE_W, [0.002, 0.001, 0.003, 0.001], rng.standard_normal(2 * m), 0.1]
    e1, J1 = pp.ClosedForm(y, DT, m, free).residual_jacobian(theta)
    e2, J2 = pp.Recursive(n, m, free, False, y, np.zeros(2 * m), DT).residual_jacobian(theta)
    np.testing.assert_allclose(e1, e2, rtol=0, atol=1e-10 * np.abs(y).max())
    assert np.max(np.abs(J1 - J2) / np.abs(J2).max(axis=0)) < 1e-10


@pytest.mark.parametrize("free_damping, free_offset", [(True, True), (False, True), (True, False)])
def test_reduced_jacobian_is_the_projected_closed_form_jacobian(free_damping, free_offset):
    """Kaufman's Jacobian of the fast search (complex-factor form) equals P⊥·∂ε/∂(ω, ζ) of the closed form
    (itself checked against central differences above), P⊥ the projector off the basis Φ = −∂ε/∂(x₀, b)."""
    n, m = 300, 4
    rng = np.random.default_rng(5)
    y = rng.standard_normal(n)
    w, z = TRUE_W * 1.01, np.array([0.02, 0.01, -0.03, 0.01])
    model = _pem_fast._Model(y, DT, m, free_offset, 0.0)
    c, e, _, solver = model.fit(w, z)
    Jr = model.reduced_jacobian(w, z, c, solver, free_damping)
    free = tuple([True] * m + [free_damping] * m + [True] * (2 * m) + [free_offset])
    theta = np.r_[w, z, np.c_[c[:m], c[m:2 * m]].ravel(), c[2 * m] if free_offset else 0.0]
    e_ref, J = pp.ClosedForm(y, DT, m, free).residual_jacobian(theta)
    nn = m * (1 + free_damping)
    Jn, G = J[:, :nn], J[:, nn:]
    expected = Jn - G @ np.linalg.lstsq(G, Jn, rcond=None)[0]
    np.testing.assert_allclose(e, e_ref, rtol=0, atol=1e-13)
    assert np.max(np.abs(Jr - expected)) < 1e-12 * np.abs(expected).max()


def test_fast_path_equals_the_reference_path_on_noise_free_data(monkeypatch):
    """identify() through the closed form and through the recursive predictor (the reference): the same
    frequencies and damping ratios to 1e-8 relative on a noise-free record."""
    zeta = np.array([0.005, 0.004, 0.006, 0.005])
    y = damped_sinusoids(TRUE_W, zeta, np.array([1.0, -3.9, -5.1, 6.4]), np.array([0.2, 0.5, -0.3, 1.0]), 200,
                         offset=0.01)
    fast = pem.identify(y, DT, TABLE4_PRIOR)
    # the reference search (methods/pem/search.py) on the closed form, then on the recursive predictor
    monkeypatch.setattr(_pem_fast, "applies", lambda opts: False)
    closed = pem.identify(y, DT, TABLE4_PRIOR)
    monkeypatch.setattr(pp, "make_evaluator", lambda y_, dt, m, free, K: pp.Recursive(
        y_.size, m, free, False, y_, np.zeros(2 * m), dt))
    ref = pem.identify(y, DT, TABLE4_PRIOR)
    for other in (closed, ref):
        assert fast.converged and other.converged
        np.testing.assert_allclose(fast.frequencies, other.frequencies, rtol=1e-8)
        np.testing.assert_allclose(fast.extra["damping"], other.extra["damping"], rtol=1e-6)
        np.testing.assert_allclose(fast.std, other.std, atol=1e-12)     # rounding level: no data noise
    np.testing.assert_allclose(fast.frequencies, TRUE_W, rtol=1e-8)


def test_the_fast_search_takes_the_steps_of_the_reference_search():
    """On a noisy record from the same start: the variable-projection search (methods/pem/_fast.py) and the
    reference Gauss–Newton (methods/pem/search.py) end at the same minimum, with the same std of ω and ζ
    (the reduced normal equations are the Schur complement of the full ones)."""
    from methods.pem import search
    from methods.pem._pencil import pencil_start

    zeta = np.array([0.005, 0.004, 0.006, 0.005])
    clean = damped_sinusoids(TRUE_W, zeta, np.array([1.0, -3.9, -5.1, 6.4]), np.array([0.2, 0.5, -0.3, 1.0]),
                             256, offset=0.01)
    y = clean + 0.05 * np.random.default_rng(3).standard_normal(256)
    for options in ({}, {"estimate_damping": False}, {"bias": "none"}):
        opts = pem.Options(**options, tol_decrease=0.0)        # both to the 1e-4 std step rule
        free = pem.free_mask(4, opts)
        bounds = search.search_bounds(TABLE4_PRIOR, DT, opts)
        w0, z0 = pencil_start(y, DT, TABLE4_PRIOR, extra_order=6, default_zeta=0.005)
        z0 = z0 if opts.estimate_damping else np.full(4, opts.damping_ratio)
        a = _pem_fast.fit_one_start(y, DT, w0, z0, free, opts, bounds)
        b = search.fit_one_start(y, DT, w0, z0, np.ones(4), free, opts, bounds)
        assert a["converged"] and b["converged"], (a["message"], b["message"])
        np.testing.assert_allclose(a["theta"], b["theta"], rtol=1e-7, atol=1e-10)
        assert a["loss"] == pytest.approx(b["loss"], rel=1e-10)
        n_nl = 8 if opts.estimate_damping else 4
        std_b = search.lstsq_step(b["J"], b["e"])[1]
        np.testing.assert_allclose(a["std_free"][:n_nl], std_b[:n_nl], rtol=1e-6)


@pytest.mark.parametrize("noise", [0.02, 0.2])
def test_the_statistical_stop_ends_within_its_std_of_the_minimum(noise):
    """tol_decrease: the fast search stops once the Gauss–Newton step would lower Σε² by less than
    tol_decrease·σ̂², saving the iteration that takes and confirms that step; the point is then within
    √tol_decrease std of the minimum the search reaches without the rule (here 0.1 std, every (ω, ζ)),
    and the std it reports is the same to a few per mille."""
    from methods.pem import search
    from methods.pem._pencil import pencil_start

    zeta = np.array([0.005, 0.004, 0.006, 0.005])
    clean = damped_sinusoids(TRUE_W, zeta, np.array([1.0, -3.9, -5.1, 6.4]), np.array([0.2, 0.5, -0.3, 1.0]),
                             256, offset=0.01)
    for seed in range(4):
        y = clean + noise * np.random.default_rng(seed).standard_normal(256)
        fits = {}
        for tol in (0.01, 0.0):
            opts = pem.Options(tol_decrease=tol)
            free = pem.free_mask(4, opts)
            bounds = search.search_bounds(TABLE4_PRIOR, DT, opts)
            w0, z0 = pencil_start(y, DT, TABLE4_PRIOR, extra_order=6, default_zeta=0.005)
            fits[tol] = _pem_fast.fit_one_start(y, DT, w0, z0, free, opts, bounds)
        quick, full = fits[0.01], fits[0.0]
        assert quick["converged"] and full["converged"]
        assert quick["iterations"] < full["iterations"] and "predicted loss decrease" in quick["message"]
        std = full["std_free"][:8]
        assert np.all(np.abs(quick["theta"][:8] - full["theta"][:8]) <= 0.1 * std)
        np.testing.assert_allclose(quick["std_free"][:8], std, rtol=5e-3)


@pytest.mark.slow
def test_a_million_sample_noise_free_record_is_identified_to_1e6():
    """10⁶ samples (5.5 h at 50 Hz), lightly damped so the modes last the record: the windowed pencil
    start plus the O(N) search give every frequency to 1e-6 relative (it used not to finish in 400 s)."""
    zeta = np.array([2e-6, 1e-6, 1.5e-6, 1e-6])
    y = damped_sinusoids(TRUE_W, zeta, np.array([1.0, -3.9, -5.1, 6.4]), np.array([0.2, 0.5, -0.3, 1.0]),
                         1_000_000)
    est = pem.identify(y, DT, TABLE4_PRIOR, n_starts=1)
    assert est.converged, est.message
    np.testing.assert_allclose(est.frequencies, TRUE_W, rtol=1e-6)


@pytest.mark.parametrize("y", [np.zeros(256), np.full(256, 0.3)], ids=["zeros", "constant"])
def test_a_record_without_oscillation_is_not_converged_and_has_no_zero_std(y):
    """No information about any frequency: converged False per mode and overall, never std 0."""
    est = pem.identify(y, DT, TABLE4_PRIOR)
    assert not est.converged
    assert not est.converged_per_mode.any()
    assert np.all((est.std > 0) | np.isnan(est.std))


@pytest.mark.parametrize("p", [0, 1, 9, 17])
def test_symmetric_eigh_is_numpys_eigh_to_the_bit(p):
    """The searches' eigendecomposition without numpy's wrapper gives numpy.linalg.eigh's eigenvalues and
    eigenvectors exactly (same LAPACK kernel): the change is speed only, the searches' paths are unchanged."""
    rng = np.random.default_rng(p)
    for _ in range(20):
        a = rng.standard_normal((max(p, 1) + 3, p))
        h = a.T @ a
        lam, v = pp.symmetric_eigh(h)
        ref_lam, ref_v = np.linalg.eigh(h)
        assert lam.shape == (p,) and v.shape == (p, p)
        assert np.array_equal(lam, ref_lam) and np.array_equal(v, ref_v)


@pytest.mark.parametrize("n", [1, 2, 7, 64, 255, 256, 1000, 1024, 1025, 5000])
def test_basis_powers_are_the_exponentials_to_rounding(n):
    """zᵏ = e^{k·sΔt} by blocks, e^{jB·sΔt}·e^{r·sΔt} (k = jB + r), equals the direct exponential to a few
    rounding errors of the phase k·|sΔt| (both round it; the blocks round two exponentials and a product)."""
    logp = np.array([-0.0002 + 0.064j, -0.003 + 1.13j, -0.05 + 2.9j])
    k = np.arange(n)[:, None]
    direct = np.exp(k * logp)
    got = pp._powers(logp, n)
    assert got.shape == (n, 3)
    tol = 16 * np.finfo(float).eps * (1.0 + k * np.abs(logp)) * np.abs(direct)
    assert np.all(np.abs(got - direct) <= tol)


def test_identify_runs_on_one_blas_thread_and_restores_the_callers(monkeypatch):
    """The fit's small matrices run on one BLAS thread; the caller's thread count comes back unchanged."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def blas_threads():
        return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]

    y = damped_sinusoids(TRUE_W, np.full(4, 0.005), np.ones(4), np.zeros(4), 256)
    seen, search = [], _pem_fast.fit_one_start

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        return search(*args, **kwargs)

    monkeypatch.setattr(_pem_fast, "fit_one_start", spy)
    with threadpool_limits(limits=2, user_api="blas"):
        before = blas_threads()
        pem.identify(y, DT, TABLE4_PRIOR)
        assert blas_threads() == before == [2] * len(before)
    assert seen and all(threads == [1] * len(threads) for threads in seen)
