"""The recursive trackers against their batch counterparts.

* ``rls_ar``'s recursion after n samples is the weighted, regularised least-squares solution of the same AR
  regression (numpy.linalg.lstsq): θ(n) = argmin λ^(n−p+1) θᵀθ/δ + Σ_{k=p..n} λ^(n−k) (y(k) − φ(k)ᵀθ)²;
* on a stationary record its poles give the modes' frequencies;
* the online ``akf`` is the batch filter: with the acceleration measurement P0 depends on max |y| only, and a
  free decay has it in the warm-up, so the tracked states are the batch run's history sample by sample; after
  a divergence it restarts;
* the ``pll`` track is the loop bank's VCO history; the ``next_era`` baseline finds stationary modes.
"""

import numpy as np
import pytest
from _signals import DT, damped_modes
from _tracking_signals import driven_modes, schedule

import methods
from methods.kalman import akf
from methods.tracking import _rls_ar


def _batch_ar(y, p, lam, delta, n):
    """The weighted, regularised least squares of the AR(p) regression over samples p … n − 1."""
    k = np.arange(p, n)
    phi = np.stack([y[k - i] for i in range(1, p + 1)], axis=1)
    w = np.sqrt(lam ** (n - 1 - k))
    reg = np.sqrt(lam ** (n - p) / delta) * np.eye(p)
    a = np.vstack([phi * w[:, None], reg])
    b = np.concatenate([y[k] * w, np.zeros(p)])
    return np.linalg.lstsq(a, b, rcond=None)[0], phi


@pytest.mark.parametrize("lam", [1.0, 0.99])
def test_rls_equals_least_squares_on_the_same_weighted_regression(lam):
    y = driven_modes(schedule(1500, freq=[5.0, 20.0]), gain=[3.0, 1.0], noise_ug=1000.0, seed=2)
    p, delta = 6, 100.0
    theta, eps = _rls_ar.rls(y, p, lam, delta)
    for n in (200, 900, 1500):
        ref, phi = _batch_ar(y, p, lam, delta, n)
        # the one-step predictions φᵀθ are what the fit determines well (the AR coefficients of poles close
        # to z = 1 are ill-conditioned): they agree to 1e-6 of the signal, and θ to 1e-4 of its norm
        scale = np.std(y[:n])
        np.testing.assert_allclose(phi @ theta[n - 1], phi @ ref, atol=1e-6 * scale)
        np.testing.assert_allclose(theta[n - 1], ref, atol=1e-4 * np.linalg.norm(ref))
    assert np.isnan(eps[:p]).all() and np.isfinite(eps[p:]).all()


def test_rls_ar_finds_the_modes_of_a_stationary_record():
    freq = np.array([5.0, 20.0, 45.0])
    y = driven_modes(schedule(3000, freq=freq), gain=[3.0, 1.0, 1.0], noise_ug=100.0, seed=5)
    tr = methods.track("rls_ar", y, DT, [4.5, 18.0, 50.0])
    late = tr.t_s > 30.0
    # the two upper modes are steady and reported converged; the low one (0.1 rad per sample) wanders by a
    # few % and is mostly reported unconverged, but its median is right
    assert tr.converged[late, 1:].mean() > 0.9
    med = np.nanmedian(tr.frequencies[late], axis=0)
    np.testing.assert_allclose(med, freq, rtol=0.03)      # an AR(MA) fit of a driven record: a few % bias


def test_online_akf_is_the_batch_filter_sample_by_sample():
    y = damped_modes([3.23, 20.24], [1.0, 4.0], 800, noise_ug=1000.0, seed=3)
    assert np.argmax(np.abs(y)) < 50                   # the largest magnitude lies in the warm-up
    opts = {"measurement": "acceleration"}
    batch = akf.identify(y, DT, [3.8, 16.0], **opts)
    tr = methods.track("akf", y, DT, [3.8, 16.0], warmup_s=1.0, **opts)
    k = np.round(tr.t_s / DT).astype(int)
    assert k[0] == 49
    np.testing.assert_allclose(tr.frequencies, batch.history[k], rtol=1e-12)
    np.testing.assert_allclose(tr.std, batch.extra["std_history"][k], rtol=1e-9)


def test_online_akf_restarts_after_a_divergence_and_goes_on_tracking():
    # the acceleration measurement with Rd = 1e-2 (m/s²)² against a force-driven record whose accelerometer
    # sees the force's feed-through (variance ≈ 50 (m/s²)²): the filter diverges, and must restart
    y = driven_modes(schedule(1500), noise_ug=300.0, seed=6)
    tr = methods.track("akf", y, DT, [3.8, 16.0, 26.0, 46.0], measurement="acceleration", max_restarts=3)
    n_div = tr.extra["n_divergences"]
    assert n_div >= 1 and "diverged at sample" in tr.message
    assert np.isnan(tr.frequencies).any(axis=1).sum() >= min(n_div, 4)      # each diverged sample is NaN
    one = methods.track("akf", y, DT, [3.8, 16.0, 26.0, 46.0], measurement="acceleration", max_restarts=0)
    assert np.isfinite(tr.frequencies).all(axis=1).sum() > np.isfinite(one.frequencies).all(axis=1).sum()


def test_pll_track_is_the_loop_banks_vco_frequency():
    from methods import pll

    y = damped_modes([3.23, 20.24], [1.0, 4.0], 1500, zeta=0.001, noise_ug=100.0, seed=8)
    tr = methods.track("pll", y, DT, [3.8, 16.0])
    batch = pll.identify(y, DT, [3.8, 16.0], remove_mean=False)
    k = np.round(tr.t_s / DT).astype(int)
    assert k[0] == tr.extra["lead_in_samples"] - 1
    np.testing.assert_array_equal(tr.frequencies, batch.history[k])
    late = tr.t_s > 20.0
    np.testing.assert_allclose(np.median(tr.frequencies[late], axis=0), [3.23, 20.24], rtol=0.01)


def test_next_era_baseline_finds_the_modes_of_a_stationary_driven_record():
    freq = np.array([5.0, 20.0, 45.0])
    y = driven_modes(schedule(3000, freq=freq), gain=[3.0, 1.0, 1.0], noise_ug=100.0, seed=9)
    tr = methods.track("next_era", y, DT, [4.5, 18.0, 50.0])
    assert tr.converged.mean() > 0.9
    np.testing.assert_allclose(np.nanmedian(tr.frequencies, axis=0), freq, rtol=0.02)
