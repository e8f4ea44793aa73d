"""The augmented Kalman filter (paper §3.1, §4.1): exact discretisation, convergence, robustness."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from _signals import DT, damped_modes

from methods.kalman import akf
from methods.kalman._filter import double_integrate, modal_transition, run_filter, settings_from


def oscillator(w, zeta):
    return np.array([[0.0, 1.0], [-w * w, -2.0 * zeta * w]])


@pytest.mark.parametrize("zeta", [0.0, 0.005, 0.3])
def test_transition_is_the_matrix_exponential_of_the_oscillator(zeta):
    w = np.array([3.23, 20.24, 56.67, 140.0])
    phi, _ = modal_transition(w, zeta, DT)
    for i, wi in enumerate(w):
        np.testing.assert_allclose(phi[i], scipy.linalg.expm(oscillator(wi, zeta) * DT), rtol=1e-12,
                                   atol=1e-14)


@pytest.mark.parametrize("zeta", [0.0, 0.005, 0.3])
def test_frequency_jacobian_is_the_exact_frechet_derivative(zeta):
    w = np.array([3.23, 20.24, 56.67, 140.0])
    _, dphi = modal_transition(w, zeta, DT)
    for i, wi in enumerate(w):
        da_dw = np.array([[0.0, 0.0], [-2.0 * wi, -2.0 * zeta]])
        _, frechet = scipy.linalg.expm_frechet(oscillator(wi, zeta) * DT, da_dw * DT)
        np.testing.assert_allclose(dphi[i], frechet, rtol=1e-10, atol=1e-14)


def test_double_integration_turns_a_bias_into_the_exact_parabola_of_the_drift_states():
    b = 0.37
    z = double_integrate(np.full(200, b), DT)
    t = np.arange(200) * DT
    np.testing.assert_allclose(z, 0.5 * b * t**2, rtol=1e-12, atol=1e-15)


def test_double_integration_keeps_the_frequency_of_a_damped_sinusoid():
    # the trapezoidal integrator is LTI: its output is the same damped sinusoid plus c + v·t
    w, zeta = 20.24, 0.005
    y = damped_modes([w], [1.0], 400)
    z = double_integrate(y, DT)
    t = np.arange(400) * DT
    e = np.exp(-zeta * w * t)
    wd = w * np.sqrt(1 - zeta**2)
    basis = np.column_stack([e * np.cos(wd * t), e * np.sin(wd * t), np.ones_like(t), t])
    coef, *_ = np.linalg.lstsq(basis, z, rcond=None)
    assert np.max(np.abs(basis @ coef - z)) < 1e-9 * np.max(np.abs(z))


@pytest.mark.parametrize("measurement, freq, amp, p0", [
    ("position", 3.23, 1.0, 1.0),          # mode 1: the mode the position filter sees (§4.1)
    ("acceleration", 20.24, 3.9, 20.0),
])
def test_noise_free_single_mode_with_true_prior_stays_at_the_true_frequency(measurement, freq, amp, p0):
    y = damped_modes([freq], [amp], 1500)
    est = akf.identify(y, DT, [freq], measurement=measurement, p0_frequency_var=[p0])
    assert est.converged, est.message
    dev = np.abs(est.history[:, 0] - freq) / freq
    assert dev[-1] < 1e-3
    assert dev[y.size // 4:].max() < 0.02      # after the transient of the unknown modal state


@pytest.mark.parametrize("measurement, freq, amp, p0", [
    ("position", 3.23, 1.0, 1.0),
    ("acceleration", 20.24, 3.9, 20.0),
])
@pytest.mark.parametrize("prior_factor", [0.8, 1.2])
def test_twenty_percent_prior_error_converges_within_one_percent_at_10ug(measurement, freq, amp, p0,
                                                                        prior_factor):
    y = damped_modes([freq], [amp], 1500, noise_ug=10.0, seed=2)
    est = akf.identify(y, DT, [prior_factor * freq], measurement=measurement, p0_frequency_var=[p0])
    assert est.converged, est.message
    assert abs(est.frequencies[0] - freq) < 0.01 * freq
    assert 0 < est.std[0] < np.sqrt(p0)      # the filter has learned (its σ reflects Rd, not the noise)


@pytest.mark.parametrize("measurement", ["position", "acceleration"])
def test_covariance_stays_symmetric_positive_semidefinite_over_10000_steps(measurement):
    y = damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 10_000, noise_ug=10.0, seed=3)
    prior = np.array([3.8, 16.0, 26.0, 46.0])
    settings = settings_from(akf.Options(measurement=measurement), prior, "akf")
    worst = {"asym": 0.0, "neg": 0.0, "steps": 0}

    def watch(k, x, P):
        worst["asym"] = max(worst["asym"], np.max(np.abs(P - P.T)))
        eig = np.linalg.eigvalsh(P)
        worst["neg"] = max(worst["neg"], -eig[0] / max(eig[-1], 1e-300))
        worst["steps"] = k + 1

    est = run_filter(y, DT, prior, settings, observer=watch)
    assert worst["steps"] == est.iterations
    assert worst["asym"] == 0.0
    assert worst["neg"] < 1e-12
    if est.converged:
        assert est.iterations == 10_000


@pytest.mark.parametrize("y", [
    np.random.default_rng(4).standard_normal(300),                       # pure noise
    damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 20),  # 20 samples
    damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 256, noise_ug=1e5, seed=5),
    np.zeros(64),
    np.full(64, 1e5),                       # 10⁴ g: constant, within MAX_ABS_ACCEL_M_S2
], ids=["pure-noise", "20-samples", "0.1g-noise", "zeros", "huge-constant"])
@pytest.mark.parametrize("measurement", ["position", "acceleration"])
def test_hostile_but_valid_records_never_raise(y, measurement):
    est = akf.identify(y, DT, [3.8, 16.0, 26.0, 46.0], measurement=measurement)
    assert est.frequencies.shape == (4,)
    if est.converged:
        assert np.all(np.isfinite(est.frequencies)) and np.all(est.frequencies > 0)
    else:
        assert est.message and np.all(np.isnan(est.frequencies))


def test_divergence_is_reported_as_a_failed_estimate_with_the_reason():
    # an absurdly confident filter on a strong signal far from its prior leaves (0, Nyquist)
    y = damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 256)
    est = akf.identify(y, DT, [3.8, 16.0, 26.0, 46.0], measurement="acceleration", qd_modal=0.0,
                       p0_modal_scale=0.1)
    assert not est.converged
    assert "diverged at sample" in est.message
    assert est.history is not None and est.history.shape[0] == est.iterations


def test_history_is_per_sample_and_ends_at_the_estimate():
    y = damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 256, noise_ug=10.0)
    est = akf.identify(y, DT, [3.8, 16.0, 26.0, 46.0])
    assert est.history.shape == (256, 4)
    np.testing.assert_array_equal(est.history[-1], est.frequencies)
    np.testing.assert_array_equal(est.extra["std_history"][-1], est.std)
    np.testing.assert_array_equal(est.history[0], [3.8, 16.0, 26.0, 46.0])   # z_0 = 0 carries no news


def test_a_call_is_a_pure_function_of_its_inputs():
    y = damped_modes([3.23, 20.24], [1.0, -3.9], 200, noise_ug=10.0)
    a = akf.identify(y, DT, [3.5, 18.0], p0_frequency_var=[1.0])
    b = akf.identify(y, DT, [3.5, 18.0], p0_frequency_var=[1.0])
    np.testing.assert_array_equal(a.history, b.history)


@pytest.mark.parametrize("options", [
    {"measurement": "velocity"}, {"damping_ratio": 1.0}, {"rd": -1.0}, {"p0_frequency_var": [1.0, 2.0]},
    {"no_such_option": 1},
])
def test_invalid_options_raise_value_error(options):
    with pytest.raises(ValueError):
        akf.identify(np.ones(64), DT, [3.8, 16.0, 26.0, 46.0], **options)


def test_default_frequency_p0_is_derived_from_the_prior_close_to_table_3():
    # §4.1: "known with an uncertainty of approximately 30 %"; P0 = 1, 20, 40, 200 for Table 3's prior
    table3 = np.array([3.8, 16.0, 26.0, 46.0])
    p0 = settings_from(akf.Options(), table3, "akf").p0_frequency_var
    np.testing.assert_allclose(p0, (0.27 * table3) ** 2, rtol=1e-12)
    sigma_ratio = np.sqrt(p0 / [1.0, 20.0, 40.0, 200.0])
    assert np.all((sigma_ratio > 0.85) & (sigma_ratio < 1.15))          # 1.03, 0.97, 1.11, 0.88
    three = settings_from(akf.Options(), np.array([4.3, 13.5, 26.0]), "akf").p0_frequency_var
    np.testing.assert_allclose(three, (0.27 * np.array([4.3, 13.5, 26.0])) ** 2, rtol=1e-12)


def test_an_explicit_p0_list_of_the_wrong_length_is_a_clear_error():
    with pytest.raises(ValueError, match=r"p0_frequency_var = \[1.0, 20.0, 40.0, 200.0\] must be one"):
        akf.identify(np.ones(64), DT, [4.3, 13.5, 26.0], p0_frequency_var=[1.0, 20.0, 40.0, 200.0])
