"""The frequency-weighted Kalman filter (paper §3.2, §4.2): the weighting filter of eq. (38), convergence,
robustness."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.signal
from _signals import DT, damped_modes

from methods.kalman import akf, wkf
from methods.kalman._filter import run_filter, settings_from

K, W0, XI = 10.0, 3.0, 0.2          # eq. (38), §4.2


def discrete_gain(wf, omega):
    """|C_f (e^{jωΔt} I − φ_f)⁻¹ Δ_f| of the discretised weighting filter."""
    eye = np.eye(wf.phi_f.shape[0])
    return np.array([abs(wf.c_f @ np.linalg.solve(np.exp(1j * w * DT) * eye - wf.phi_f, wf.delta_f))
                     for w in np.atleast_1d(omega)])


def test_discretised_weighting_filter_keeps_the_dc_gain_K_of_eq_38():
    wf = wkf.weighting_filter(K, W0, XI, DT)
    dc = wf.c_f @ np.linalg.solve(np.eye(2) - wf.phi_f, wf.delta_f)
    assert dc == pytest.approx(K, rel=1e-12)


def test_discretised_weighting_filter_resonates_where_eq_38_does():
    wf = wkf.weighting_filter(K, W0, XI, DT)
    omega = np.linspace(0.5, 10.0, 20_000)
    gain = discrete_gain(wf, omega)
    peak = np.argmax(gain)
    assert omega[peak] == pytest.approx(W0 * np.sqrt(1 - 2 * XI**2), rel=0.01)     # 2.88 rad/s
    assert gain[peak] == pytest.approx(K / (2 * XI * np.sqrt(1 - XI**2)), rel=0.01)  # 25.5
    assert discrete_gain(wf, W0)[0] == pytest.approx(K / (2 * XI), rel=0.01)        # |H(jω0)| = 25


def test_weighting_emphasises_mode_1_and_suppresses_mode_4():
    wf = wkf.weighting_filter(K, W0, XI, DT)
    g = discrete_gain(wf, [3.23, 20.24, 22.0, 56.67])
    assert g[0] > 20 and g[3] < 0.05 and g[1] > g[2] > g[3]


def test_weighting_of_the_data_is_the_discrete_filter_of_eq_26():
    wf = wkf.weighting_filter(K, W0, XI, DT)
    u = np.random.default_rng(1).standard_normal(500)
    _, ref, _ = scipy.signal.dlsim((wf.phi_f, wf.delta_f[:, None], wf.c_f[None, :], np.zeros((1, 1)), DT), u)
    np.testing.assert_allclose(wf.apply(u), ref[:, 0], rtol=1e-12, atol=1e-12)


def test_options_are_those_of_the_augmented_filter_plus_the_weighting():
    base = {f.name: f.default for f in dataclasses.fields(akf.Options) if f.default is not dataclasses.MISSING}
    for name, default in base.items():
        assert getattr(wkf.Options(), name) == default
    assert (wkf.Options().weight_gain, wkf.Options().weight_omega0_rad_s, wkf.Options().weight_damping,
            wkf.Options().r_f) == (10.0, 3.0, 0.2, 0.005)


@pytest.mark.parametrize("measurement, freq, amp, p0", [
    ("position", 3.23, 1.0, 1.0),
    ("acceleration", 20.24, 3.9, 20.0),
])
def test_noise_free_single_mode_with_true_prior_stays_at_the_true_frequency(measurement, freq, amp, p0):
    y = damped_modes([freq], [amp], 1500)
    est = wkf.identify(y, DT, [freq], measurement=measurement, p0_frequency_var=[p0])
    assert est.converged, est.message
    dev = np.abs(est.history[:, 0] - freq) / freq
    assert dev[-1] < 1e-3
    assert dev[y.size // 4:].max() < 0.02


@pytest.mark.parametrize("measurement, freq, amp, p0", [
    ("position", 3.23, 1.0, 1.0),
    ("acceleration", 20.24, 3.9, 20.0),
])
@pytest.mark.parametrize("prior_factor", [0.8, 1.2])
def test_twenty_percent_prior_error_converges_within_one_percent_at_10ug(measurement, freq, amp, p0,
                                                                        prior_factor):
    y = damped_modes([freq], [amp], 1500, noise_ug=10.0, seed=2)
    est = wkf.identify(y, DT, [prior_factor * freq], measurement=measurement, p0_frequency_var=[p0])
    assert est.converged, est.message
    assert abs(est.frequencies[0] - freq) < 0.01 * freq
    assert 0 < est.std[0] < np.sqrt(p0)


@pytest.mark.parametrize("measurement", ["position", "acceleration"])
def test_covariance_stays_symmetric_positive_semidefinite_over_10000_steps(measurement):
    y = damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 10_000, noise_ug=10.0, seed=3)
    prior = np.array([3.8, 16.0, 26.0, 46.0])
    opts = wkf.Options(measurement=measurement)
    wf = wkf.weighting_filter(opts.weight_gain, opts.weight_omega0_rad_s, opts.weight_damping, DT)
    settings = settings_from(opts, prior, "wkf", weighting=wf, r_f=opts.r_f)
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


@pytest.mark.parametrize("y", [
    np.random.default_rng(4).standard_normal(300),
    damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 20),
    damped_modes([3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4], 256, noise_ug=1e5, seed=5),
    np.zeros(64),
], ids=["pure-noise", "20-samples", "0.1g-noise", "zeros"])
@pytest.mark.parametrize("measurement", ["position", "acceleration"])
def test_hostile_but_valid_records_never_raise(y, measurement):
    est = wkf.identify(y, DT, [3.8, 16.0, 26.0, 46.0], measurement=measurement)
    assert est.frequencies.shape == (4,)
    if est.converged:
        assert np.all(np.isfinite(est.frequencies)) and np.all(est.frequencies > 0)
    else:
        assert est.message and np.all(np.isnan(est.frequencies))


@pytest.mark.parametrize("options", [{"weight_gain": 0.0}, {"r_f": -1.0}, {"weight_damping": float("nan")},
                                     {"measurement": "strain"}])
def test_invalid_options_raise_value_error(options):
    with pytest.raises(ValueError):
        wkf.identify(np.ones(64), DT, [3.8, 16.0, 26.0, 46.0], **options)


def test_default_frequency_p0_is_the_augmented_filters_rule_for_any_number_of_modes():
    for prior in ([5.0], [4.3, 13.5, 26.0], [3.8, 16.0, 26.0, 46.0], [3.0, 9.0, 20.0, 33.0, 50.0]):
        prior = np.array(prior)
        p0 = settings_from(wkf.Options(), prior, "wkf").p0_frequency_var
        np.testing.assert_allclose(p0, (0.27 * prior) ** 2, rtol=1e-12)
    with pytest.raises(ValueError, match=r"p0_frequency_var = \[1.0, 20.0, 40.0, 200.0\] must be one"):
        wkf.identify(np.ones(64), DT, [4.3, 13.5, 26.0], p0_frequency_var=[1.0, 20.0, 40.0, 200.0])
