"""pem with a Gaussian prior on the frequencies (prior_std_rad_s): the MAP fit (methods/pem/_map.py)."""

from __future__ import annotations

import numpy as np
import pytest

import methods
from methods import pem

TRUE_W = np.array([3.23, 20.24, 22.00, 56.67])        # Table 3
DT = 0.02


def _record(n, noise, seed, w=TRUE_W, amp=(1.04, -4.10, -4.84, 6.42), zeta=0.005, offset=0.0):
    t = np.arange(n) * DT
    clean = sum(a * np.exp(-zeta * wi * t) * np.cos(wi * np.sqrt(1 - zeta**2) * t) for wi, a in
                zip(w, amp, strict=True))
    return clean + offset + noise * np.random.default_rng(seed).standard_normal(n)


def _one_mode_cost(y, t, w, mu, s, zeta):
    """Φ(ω) = (N − q) log RSS(ω) + ((ω − μ)/s)², RSS from numpy's lstsq on the basis
    [e^{−ζωt}cos ω_d t, e^{−ζωt}sin ω_d t, 1] (ζ held): the brute force the one-mode tests compare with."""
    env = np.exp(-zeta * w * t)
    wd = w * np.sqrt(1 - zeta**2)
    V = np.column_stack([env * np.cos(wd * t), env * np.sin(wd * t), np.ones(t.size)])
    rss = np.sum((y - V @ np.linalg.lstsq(V, y, rcond=None)[0]) ** 2)
    return (t.size - 3) * np.log(rss) + ((w - mu) / s) ** 2


def test_one_mode_map_is_the_minimum_of_the_posterior_cost_on_a_grid():
    # brute force, independent of the search: Φ(ω) = (N − q) log RSS(ω) + ((ω − μ)/s)², RSS from numpy's
    # lstsq on the basis [e^{−ζωt}cos ω_d t, e^{−ζωt}sin ω_d t, 1] (ζ held), minimised over a fine grid
    n, mu, s, zeta = 24, 10.0, 0.4, 0.005
    y = _record(n, 0.3, 1, w=[10.3], amp=[1.0], offset=0.2)
    t = np.arange(n) * DT
    grid = np.linspace(mu - 4 * s, mu + 4 * s, 16001)

    def cost(w):
        return _one_mode_cost(y, t, w, mu, s, zeta)

    costs = np.array([cost(w) for w in grid])
    w_grid = grid[np.argmin(costs)]
    est = pem.identify(y, DT, [mu], prior_std_rad_s=s, estimate_damping=False, damping_ratio=zeta)
    assert abs(est.frequencies[0] - w_grid) <= 2 * (grid[1] - grid[0])
    assert abs(w_grid - mu) > 0.05 and abs(w_grid - 10.3) > 0.01       # neither the prior nor the truth
    # Laplace std: the curvature of Φ/2 at the minimum, by finite differences of the brute-force cost
    h = 1e-3
    curv = (cost(w_grid + h) - 2 * cost(w_grid) + cost(w_grid - h)) / h**2 / 2
    assert est.std[0] == pytest.approx(1 / np.sqrt(curv), rel=0.1)


def test_map_reduces_to_ml_as_the_prior_widens():
    # a long record (N = 256, 1 mg): with a 1e6 rad/s prior spread the MAP fit is the ML fit to a hundredth of
    # its std; with a spread of 1e-3 of the CRLB it stays at the prior mean
    y = _record(256, 1000 * 9.80665e-6, 3)
    prior = TRUE_W * 1.05
    ml = pem.identify(y, DT, prior)
    wide = pem.identify(y, DT, prior, prior_std_rad_s=1e6)
    assert wide.converged_per_mode.all()
    np.testing.assert_array_less(np.abs(wide.frequencies - ml.frequencies), 0.01 * ml.std)
    np.testing.assert_allclose(wide.std, ml.std, rtol=0.2)
    tight = pem.identify(y, DT, prior, prior_std_rad_s=(1e-3 * ml.std).tolist())
    np.testing.assert_allclose(tight.frequencies, prior, atol=float(3e-3 * ml.std.max()))
    np.testing.assert_array_less(tight.std, 1.01e-3 * ml.std)


def test_short_record_map_answers_every_mode_with_an_honest_posterior_std():
    # N = 24: the ML fit does not determine modes 1-3; the MAP fit answers every mode, in order, with a
    # posterior std below the prior's that covers the truth (4σ), pins mode 4 far below the prior's spread and
    # calls determined only the modes where the data halved the prior's variance (mode 4 at least)
    prior = TRUE_W * 1.03
    s = 0.03 * TRUE_W
    y = _record(24, 1000 * 9.80665e-6, 5)
    est = methods.get("pem")(y, DT, prior, prior_std_rad_s=s.tolist())
    assert np.all(np.diff(est.frequencies) > 0) and est.converged_per_mode[3]
    np.testing.assert_array_equal(est.converged_per_mode, est.std <= s / np.sqrt(2))
    np.testing.assert_array_less(est.std, s * 1.0001)
    np.testing.assert_array_less(np.abs(est.frequencies - TRUE_W), 4 * est.std)
    assert est.std[3] < 0.1 * s[3]
    ml = pem.identify(y, DT, prior)
    assert not ml.converged_per_mode[:3].any()


@pytest.mark.parametrize(("value", "match"), [
    (-1.0, "positive"), ([1.0, 2.0], "one per mode"), ("wide", "a number"), (float("nan"), "positive")])
def test_bad_prior_std_is_refused_with_one_line(value, match):
    with pytest.raises(ValueError, match=match):
        methods.check_options("pem", TRUE_W, DT, {"prior_std_rad_s": value})


def test_damping_prior_holds_the_damping_near_its_assumed_value_on_a_short_record():
    # N = 20: the record barely informs any ζ; with ζ ~ N(0.005, 0.001²) every ζ stays within 5 sd of
    # 0.005 (the search bounds allow ±0.8), and a bad value is refused
    y = _record(20, 1000 * 9.80665e-6, 2)
    s = 0.03 * TRUE_W
    held = pem.identify(y, DT, TRUE_W, prior_std_rad_s=s.tolist(), damping_prior_std=0.001)
    assert np.all(np.abs(np.asarray(held.extra["damping"]) - 0.005) <= 0.005)
    with pytest.raises(ValueError, match="damping_prior_std"):
        methods.check_options("pem", TRUE_W, DT, {"prior_std_rad_s": 1.0, "damping_prior_std": -0.1})


def test_prior_std_needs_the_output_error_model():
    with pytest.raises(ValueError, match="output_error"):
        methods.check_options("pem", TRUE_W, DT, {"prior_std_rad_s": 1.0, "predictor": "kalman"})


def test_posterior_mean_by_importance_sampling_matches_a_brute_force_integral():
    # one mode, ζ held, a record short and noisy enough that the posterior is skewed (its mean is not its
    # mode): exp(−Φ/2) integrated on a fine grid (numpy lstsq for the RSS) gives the posterior mean and std
    n, mu, s, zeta = 24, 10.0, 0.4, 0.005
    y = _record(n, 0.1, 2, w=[10.3], amp=[1.0], offset=0.2)
    t = np.arange(n) * DT
    grid = np.linspace(mu - 6 * s, mu + 6 * s, 6001)

    def cost(w):
        return _one_mode_cost(y, t, w, mu, s, zeta)

    c = np.array([cost(w) for w in grid])
    p = np.exp(-0.5 * (c - c.min()))
    p /= p.sum()
    mean, std = p @ grid, np.sqrt(p @ (grid - p @ grid) ** 2)
    common = {"prior_std_rad_s": s, "estimate_damping": False, "damping_ratio": zeta}
    mode = pem.identify(y, DT, [mu], posterior_summary="mode", **common)
    sampled = pem.identify(y, DT, [mu], posterior_draws=20000, **common)
    assert sampled.extra["posterior_summary"] == "importance-sampled mean"
    assert abs(sampled.frequencies[0] - mean) <= 0.03 * std        # Monte-Carlo error ~0.01 std
    assert sampled.std[0] == pytest.approx(std, rel=0.05)
    assert abs(mode.frequencies[0] - grid[np.argmin(c)]) <= 2 * (grid[1] - grid[0])
    assert abs(mode.frequencies[0] - mean) > 0.08 * std            # the case tells mode from mean


def test_laplace_mixture_weights_maxima_by_their_evidence():
    # two hand-made maxima: equal heights, the second twice as wide in every direction → 2^d times the mass
    from methods.pem import _map

    d = 2
    a = {"x": np.array([1.0, 5.0]), "cost": 10.0, "cov": np.diag([0.01, 0.01])}
    b = {"x": np.array([2.0, 5.0]), "cost": 10.0, "cov": np.diag([0.04, 0.04])}
    mix = _map.laplace_mixture([a, b, dict(a)], m=2)
    assert mix["count"] == 2                                      # the duplicate of a is merged
    np.testing.assert_allclose(mix["weights"], [1 / (1 + 2**d), 2**d / (1 + 2**d)])
    np.testing.assert_allclose(mix["mean"], [1 + 0.8, 5.0])
    var = 0.2 * (0.01 + 1.0) + 0.8 * (0.04 + 4.0) - 1.8**2
    np.testing.assert_allclose(mix["std"], [np.sqrt(var), np.sqrt(0.2 * 0.01 + 0.8 * 0.04)])


def test_laplace_mixture_std_survives_a_sharp_maximum_far_from_zero():
    # one maximum at 20 rad/s with σ = 1e-9 rad/s (a mode at 0.1 µg on 256 samples): E[x²] − x̄² cancels to 0
    from methods.pem import _map

    a = {"x": np.array([20.24, 56.67]), "cost": 1.0, "cov": np.diag([1e-18, 4e-18])}
    mix = _map.laplace_mixture([a], m=2)
    np.testing.assert_allclose(mix["std"], [1e-9, 2e-9], rtol=1e-12)


def test_the_samplers_projected_rss_equals_a_least_squares_solve_per_draw():
    # the importance sampler's batched RSS (normal equations, explicit residual) against numpy's lstsq on each
    # draw's basis: draws 3 % around the paper's modes, a coincident and a nearly coincident pair, and the
    # truth itself in noise of 1e-9 (RSS ~1e-20 of ‖y‖², where ‖y‖² − bᵀG⁻¹b would be all rounding)
    from methods.pem import _map

    rng = np.random.default_rng(1)
    for n, noise in [(20, 1e-2), (32, 1e-9), (256, 1e-8)]:
        w = np.sort(TRUE_W * (1 + 0.03 * rng.standard_normal((40, 4))), axis=1)
        z = 0.005 + 0.01 * rng.standard_normal((40, 4))
        w[0, 2], w[1, 2] = w[0, 1] + 1e-9, w[1, 1] + 1e-4
        w[2], z[2] = TRUE_W, 0.005
        t = np.arange(n) * DT
        y = 0.3 + sum(a * np.exp(-0.005 * wi * t) * np.cos(wi * np.sqrt(1 - 0.005**2) * t + ph)
                      for a, wi, ph in zip([1.0, 4.0, 5.0, 6.0], TRUE_W, [0.0, 3.0, 3.0, 0.0], strict=True))
        y = y + noise * rng.standard_normal(n)
        got = _map._projected_rss(y, w, z, DT, True)
        ref = np.empty(40)
        for k in range(40):
            p = np.exp((-z[k] * w[k] + 1j * w[k] * np.sqrt(1 - z[k] ** 2)) * DT)[None, :] ** np.arange(n)[:, None]
            basis = np.hstack([p.real, p.imag, np.ones((n, 1))])
            ref[k] = np.sum((y - basis @ np.linalg.lstsq(basis, y, rcond=None)[0]) ** 2)
        tiny = ref < 1e-12 * (y @ y)
        np.testing.assert_allclose(got[~tiny], ref[~tiny], rtol=1e-6)
        np.testing.assert_allclose(got[tiny], ref[tiny], rtol=1e-2)
        assert tiny.sum() == (noise < 1e-6)                # the truth's RSS is the tiny one, where it should be
