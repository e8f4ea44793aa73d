"""Prediction-error method (paper §3.3, §4.3): exactness, derivatives, the step rule, accuracy, bias."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.config_schema import stated_options
from methods import pem
from methods.pem import _fit, search
from methods.pem import predictor as pp

DT = 0.02
UG = 9.80665e-6
TRUE_W = np.array([3.23, 20.24, 22.00, 56.67])        # Table 3
TABLE4_PRIOR = np.array([2.65, 16.73, 17.32, 52.91])   # Table 4


def damped_sinusoids(w, zeta, amp_cos, amp_sin, n, offset=0.0):
    """The identification model's own output with K = 0: Σ e^{−ζωt}(A cos ω_d t + B sin ω_d t) + b."""
    t = np.arange(n)[:, None] * DT
    wd = w * np.sqrt(1 - zeta**2)
    return (np.exp(-zeta * w * t) * (amp_cos * np.cos(wd * t) + amp_sin * np.sin(wd * t))).sum(1) + offset


def paper_record(n, noise_ug, seed):
    from experiments.simulate.plant import build_plant
    plant = build_plant()
    y = plant.tip_acceleration(n, DT)
    y = y + noise_ug * UG * np.random.default_rng(seed).standard_normal(n)
    return plant, y


def test_noise_free_model_output_gives_frequencies_to_1e6_from_20_percent_prior_error():
    zeta = np.array([0.005, 0.004, 0.006, 0.005])
    y = damped_sinusoids(TRUE_W, zeta, np.array([1.0, -3.9, -5.1, 6.4]), np.array([0.2, 0.5, -0.3, 1.0]), 256)
    prior = TRUE_W * np.array([0.8, 0.8, 0.8, 1.2])
    est = pem.identify(y, DT, prior)
    assert est.converged, est.message
    np.testing.assert_allclose(est.frequencies, TRUE_W, rtol=1e-6)
    np.testing.assert_allclose(est.extra["damping"], zeta, rtol=1e-4)


@pytest.mark.parametrize("with_gain", [False, True])
def test_casadi_jacobian_of_prediction_errors_matches_finite_differences(with_gain):
    n, m = 64, 4
    free = (True,) * pp.n_params(m)
    rng = np.random.default_rng(1)
    y = damped_sinusoids(TRUE_W, np.full(4, 0.01), np.ones(4), np.ones(4), n) + 0.01 * rng.standard_normal(n)
    theta = np.r_[TRUE_W * 1.01, [0.02, 0.01, 0.03, 0.01], rng.standard_normal(2 * m), 0.1]
    K = (pp.kalman_gain(theta[:m], theta[m:2 * m], DT, [2, -2, -2, 2], 0.001, 0.4) if with_gain
         else np.zeros(2 * m))
    ev = pp.Evaluator(n, m, free, with_gain, y, K, DT)
    e, J = ev.residual_jacobian(theta)
    np.testing.assert_allclose(e, ev.residual(theta), rtol=0, atol=1e-14)
    J_fd = np.empty_like(J)
    for j in range(theta.size):
        h = 1e-6 * max(abs(theta[j]), 1e-2)
        up, down = theta.copy(), theta.copy()
        up[j] += h
        down[j] -= h
        J_fd[:, j] = (ev.residual(up) - ev.residual(down)) / (2 * h)
    scale = np.abs(J).max(axis=0)
    assert np.max(np.abs(J - J_fd) / scale) < 1e-6


def test_kalman_gain_is_a_stable_innovation_predictor_in_modal_coordinates():
    """K from the Riccati equation in (q, q̇) coordinates, moved to modal coordinates: φ − KC is stable and
    has the same eigenvalues as in the paper's coordinates (a similarity transform)."""
    zeta = np.full(4, 0.005)
    K = pp.kalman_gain(TABLE4_PRIOR, zeta, DT, [2, -2, -2, 2], 0.001, 0.4)
    phi_p, C_p, T = pp.paper_state_space(TABLE4_PRIOR, zeta, DT, [2, -2, -2, 2])
    phi_m = np.linalg.solve(T, phi_p @ T)
    C_m = C_p @ T
    np.testing.assert_allclose(C_m.ravel(), np.tile([1.0, 0.0], 4), atol=1e-12)
    closed_loop = np.abs(np.linalg.eigvals(phi_m - np.outer(K, C_m)))
    assert closed_loop.max() < 1.0
    k_paper = T @ K
    np.testing.assert_allclose(np.sort(np.abs(np.linalg.eigvals(phi_p - np.outer(k_paper, C_p)))),
                               np.sort(closed_loop), rtol=1e-10)


def test_a_gauss_newton_step_that_would_increase_the_loss_is_halved():
    """From a start 10 % off, the full Gauss–Newton step overshoots (the loss is far from quadratic);
    the paper's rule halves μ until the loss decreases."""
    n, m = 128, 4
    zeta = np.full(4, 0.005)
    y = damped_sinusoids(TRUE_W, zeta, np.array([1.0, -3.9, -5.1, 6.4]), np.zeros(4), n)
    opts = pem.Options(search="gauss_newton", separable=False, max_iterations=1, estimate_damping=False)
    free = pem.free_mask(m, opts)
    ev = pp.Evaluator(n, m, free, False, y, np.zeros(2 * m), DT)
    start = np.r_[TRUE_W * np.array([1.0, 1.04, 0.97, 1.0]), zeta, np.zeros(2 * m), 0.0]
    theta0, e0, loss0 = search.solve_linear(ev, start, m)
    e, J = ev.residual_jacobian(theta0)
    d = search.lstsq_step(J, e)[0]
    full = theta0.copy()
    full[np.flatnonzero(free)] += d
    e_full = ev.residual(full)
    assert e_full @ e_full / n > loss0                         # the full step would increase the loss
    fit = search.gauss_newton(theta0, np.flatnonzero(free), ev, DT, opts, search.search_bounds(TRUE_W, DT, opts))
    assert fit["step_lengths"] and fit["step_lengths"][0] < 1.0
    assert fit["step_lengths"][0] in {0.5**k for k in range(1, 41)}
    assert fit["loss"] < loss0


def test_paper_plant_at_1000ug_and_256_samples_is_within_3_crlb():
    from experiments.simulate.crlb import crlb_std
    plant, y = paper_record(256, 1000.0, seed=1)
    est = pem.identify(y, DT, TABLE4_PRIOR)
    crlb = crlb_std(plant.freq_rad_s, plant.damping, plant.modal_amplitude, plant.modal_phase, 256, DT,
                    1000.0 * UG)
    assert est.converged, est.message
    assert np.all(np.abs(est.frequencies - plant.freq_rad_s) <= 3 * crlb)
    # the reported std is the local covariance σ̂²(JᵀJ)⁻¹ and must be close to the bound
    np.testing.assert_allclose(est.std, crlb, rtol=0.3)


def test_a_constant_sensor_bias_leaves_the_estimates_unchanged():
    """The minimum is the same to rounding (searched to the 1e-4 std step rule); with the default
    statistical stop (tol_decrease) each search ends within 0.1 std of it, from starts that see the offset."""
    _, y = paper_record(128, 100.0, seed=2)
    a = pem.identify(y, DT, TABLE4_PRIOR, tol_decrease=0.0)
    b = pem.identify(y + 0.37, DT, TABLE4_PRIOR, tol_decrease=0.0)
    np.testing.assert_allclose(b.frequencies, a.frequencies, rtol=1e-9)
    assert b.extra["offset_m_s2"] == pytest.approx(a.extra["offset_m_s2"] + 0.37, abs=1e-6)
    a_stop = pem.identify(y, DT, TABLE4_PRIOR)
    b_stop = pem.identify(y + 0.37, DT, TABLE4_PRIOR)
    assert np.all(np.abs(b_stop.frequencies - a_stop.frequencies) <= 0.2 * a.std)


def test_subtracting_the_mean_biases_the_estimates_even_without_noise():
    """The paper removes the bias by subtracting the mean (§4); on 128 samples of the slow mode 1 the
    mean is not the offset, and mode 1 moves by tens of CRLB std at 1 mg; modelling the offset does not."""
    plant, _ = paper_record(128, 0.0, seed=0)
    y = plant.tip_acceleration(128, DT)
    by_mean = pem.identify(y, DT, TABLE4_PRIOR, bias="subtract_mean")
    modelled = pem.identify(y, DT, TABLE4_PRIOR, bias="estimate")
    assert abs(by_mean.frequencies[0] - plant.freq_rad_s[0]) > 0.01
    np.testing.assert_allclose(modelled.frequencies, plant.freq_rad_s, rtol=1e-10)


def test_paper_setting_kalman_predictor_converges_from_table4_prior():
    plant, y = paper_record(256, 1000.0, seed=3)
    est = pem.identify(y, DT, TABLE4_PRIOR, **stated_options("pem_paper"))
    assert est.extra["n_starts"] == 1
    np.testing.assert_allclose(est.frequencies, plant.freq_rad_s, rtol=5e-3)


def test_multistart_is_seeded_and_reports_agreement():
    _, y = paper_record(256, 1000.0, seed=4)
    a = pem.identify(y, DT, TABLE4_PRIOR, n_starts=4, seed=7, accept_white=False)
    b = pem.identify(y, DT, TABLE4_PRIOR, n_starts=4, seed=7, accept_white=False)
    np.testing.assert_array_equal(a.frequencies, b.frequencies)
    assert a.extra["n_starts"] == 4 and 1 <= a.extra["n_agree"] <= 4


@pytest.mark.parametrize("n, noise_ug", [(20, 1000.0), (256, 1e5), (64, 1e7)])
def test_hostile_records_return_an_estimate_without_raising(n, noise_ug):
    rng = np.random.default_rng(5)
    y = noise_ug * UG * rng.standard_normal(n)                  # pure noise
    est = pem.identify(y, DT, TABLE4_PRIOR)
    assert est.frequencies.shape == (4,)
    assert isinstance(est.message, str) and est.message


def test_too_few_samples_for_the_unknowns_is_a_failure_not_an_exception():
    est = pem.identify(np.ones(12), DT, TABLE4_PRIOR)
    assert not est.converged and np.all(np.isnan(est.frequencies))


def test_invalid_options_raise_value_error_naming_them():
    y = np.zeros(64)
    with pytest.raises(ValueError, match="predictor"):
        pem.identify(y, DT, TABLE4_PRIOR, predictor="ekf")
    with pytest.raises(ValueError, match="unknown option"):
        pem.identify(y, DT, TABLE4_PRIOR, gain=0.1)
    with pytest.raises(ValueError, match="tip_mode_shape"):
        pem.identify(y, DT, TABLE4_PRIOR[:3], predictor="kalman")
    for absurd in (0, -1, 1_000_000_000):          # a bound, not only a sign: a billion starts is a typo
        with pytest.raises(ValueError, match=f"n_starts = {absurd} must be between 1 and"):
            pem.check_options(np.array(TABLE4_PRIOR), DT, n_starts=absurd)


def test_the_first_start_is_accepted_only_when_it_explains_the_record():
    """The early stop (accept_white) gives the all-starts answer (the same minimum, searched to the 1e-4 std
    step rule from other starts: within 1e-3 std; within 0.2 std with the statistical stop, each search
    ending within 0.1 std of it); a residual with a sinusoid in it (a mode the fit missed) is never
    accepted, white noise is accepted at the false-alarm rate."""
    for seed in range(5):
        _, y = paper_record(256, 1000.0, seed=seed)
        for tol, within_std in ((0.0, 1e-3), (0.01, 0.2)):
            fast = pem.identify(y, DT, TABLE4_PRIOR, tol_decrease=tol)
            every = pem.identify(y, DT, TABLE4_PRIOR, accept_white=False, tol_decrease=tol)
            assert fast.extra["n_starts"] == 1 and every.extra["n_starts"] == 3
            assert np.all(np.abs(fast.frequencies - every.frequencies) <= within_std * every.std)
    n, rng = 256, np.random.default_rng(0)
    w_std = np.full(4, 1e-3)
    accepted = [_fit._explains_record({"e": rng.standard_normal(n)}, w_std, n, DT) for _ in range(400)]
    assert 0.97 <= np.mean(accepted) < 1.0          # α = 1 %: a few false alarms, not none, not many
    t = np.arange(n) * DT
    missed = rng.standard_normal(n) + 0.6 * np.sin(20.24 * t)   # E/σ² = 0.36·N/2 = 46 > 2 ln(N/2α) = 18.7
    assert not _fit._explains_record({"e": missed}, w_std, n, DT)
    assert not _fit._explains_record({"e": rng.standard_normal(n)}, np.full(4, 1.0), n, DT)  # not detected


def test_a_damped_mode_of_a_long_record_is_detected_by_its_energy():
    """Mode 4 (ζ = 0.005, 56.7 rad/s) decays within ~200 samples: in a long record its std stops shrinking
    while detection_std keeps falling as 1/N; its fitted energy still shows it (E/σ² ≫ 2 ln(N/2α))."""
    plant, y = paper_record(262144, 1000.0, seed=2)
    est = pem.identify(y, DT, TABLE4_PRIOR)
    assert est.std[3] > pem.detection_std(y.size, DT)                  # the std rule alone would refuse it
    assert est.converged and est.converged_per_mode.all(), est.message
    assert est.extra["n_starts"] == 1                                  # and the first start is accepted
    np.testing.assert_allclose(est.frequencies, plant.freq_rad_s, rtol=1e-4)
