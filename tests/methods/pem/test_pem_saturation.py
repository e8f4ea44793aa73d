"""A clipped sensor (methods/pem/_saturation.py) and the amplitude line's jackknife std (methods/pem/_drift.py)."""

from __future__ import annotations

import numpy as np
import pytest

from methods import pem
from methods.pem import _drift, _saturation

DT = 0.02


def _raw(n=512, seed=1):
    """Two decaying modes in white noise, unclipped."""
    t = DT * np.arange(n)
    rng = np.random.default_rng(seed)
    return (3.0 * np.exp(-0.15 * t) * np.cos(20.0 * t) + 1.0 * np.exp(-0.3 * t) * np.cos(52.0 * t + 0.4)
            + 0.01 * rng.standard_normal(n))


def test_a_clipped_record_is_flagged_with_its_plateaus():
    raw = _raw()
    limit = 0.5 * np.abs(raw).max()
    y = np.clip(raw, -limit, limit)
    clip = _saturation.detect(y)
    # independent counts: the raw samples beyond the range
    above, below = np.flatnonzero(raw >= limit), np.flatnonzero(raw <= -limit)
    assert clip is not None
    assert sorted(clip["plateau_samples"]) == sorted([above.size, below.size])
    assert clip["clipped_samples"] == above.size + below.size
    assert clip["last_clipped"] == max(above.max(), below.max())
    assert sorted(clip["levels_m_s2"]) == pytest.approx([-limit, limit])


def test_continuous_and_quantised_records_are_not_flagged():
    raw = _raw()
    assert _saturation.detect(raw) is None
    for step in (0.01, 0.03, 0.1):        # rounding to 1, 3 and 10 noise std: ties everywhere, no plateau
        assert _saturation.detect(step * np.round(raw / step)) is None


def test_identify_fits_after_the_last_clipped_sample():
    raw = _raw(1024)
    limit = 0.5 * np.abs(raw).max()
    y = np.clip(raw, -limit, limit)
    est = pem.identify(y, DT, [18.0, 52.0])
    sat = est.extra["saturation"]
    assert sat["fit_start"] == sat["last_clipped"] + 1
    assert "clipped" in est.message
    # the same as a fit to the unclipped tail itself
    tail = pem.identify(raw[sat["fit_start"]:], DT, [18.0, 52.0])
    np.testing.assert_allclose(est.frequencies, tail.frequencies, rtol=1e-9)
    wd = np.array([20.0 * np.sqrt(1 - (0.15 / 20) ** 2), 52.0 * np.sqrt(1 - (0.3 / 52) ** 2)])
    omega = np.hypot(wd, [0.15, 0.3])                 # undamped ω of σ ± iω_d
    assert np.all(np.abs(est.frequencies - omega) <= 4 * est.std)
    kept = pem.identify(y, DT, [18.0, 52.0], skip_clipped=False)
    assert "saturation" not in kept.extra


def test_skip_clipped_is_checked():
    with pytest.raises(ValueError, match="skip_clipped = 'yes' must be true or false"):
        pem.identify(np.ones(100), DT, [18.0], skip_clipped="yes")


def test_line_std_against_a_monte_carlo_when_the_segments_std_is_too_small():
    """The intercept's std of :func:`methods.pem._drift._line` on a toy line whose points scatter 3× their
    stated std: the weighted-least-squares std alone is 3× too small, the jackknife's matches the spread of
    4000 Monte-Carlo fits."""
    rng = np.random.default_rng(3)
    x, s = np.array([0.05, 0.2, 0.5, 1.0, 1.6]), np.full(5, 0.01)
    est, std, wls = [], [], []
    for _ in range(4000):
        f = 20.0 - 0.2 * x + 3 * s * rng.standard_normal(5)
        _, _, w0, w0_std = _drift._line(x, f, s)
        est.append(w0)
        std.append(w0_std)
        wls.append(np.sqrt(np.polyfit(x, f, 1, w=1 / s, cov="unscaled")[1][1, 1]))
    mc = np.std(est)
    assert np.mean(wls) < 0.4 * mc
    assert 0.8 * mc < np.sqrt(np.mean(np.square(std))) < 1.5 * mc
    inside = np.abs(np.array(est) - 20.0) <= np.array(std)
    assert 0.6 < inside.mean() < 0.8


def test_backbone_fit_against_a_monte_carlo_in_coloured_noise():
    """:func:`methods.pem._chirp.fit` on one Duffing mode (backbone ω√(1 + 2δA²), A = 1 at release) in AR(1)
    noise (φ = 0.8): ω₀ is the linear ω, κ the first-order shift ωδ at release, and the robust std matches
    the spread of 300 fits (measured: 0.00315 against 0.00308 rad/s, 69 % / 95 % within 1σ / 2σ)."""
    import scipy.signal

    from experiments.simulate.mismatch import duffing_modes
    from methods.pem import _chirp

    n, w, delta = 1024, 20.0, -0.01
    clean = duffing_modes(DT * np.arange(n), [w], [0.01], [1.0], [0.3], delta)
    rng = np.random.default_rng(11)
    est, std, kappa = [], [], []
    for _ in range(300):
        noise = 0.02 * scipy.signal.lfilter([np.sqrt(1 - 0.8 ** 2)], [1, -0.8], rng.standard_normal(n))
        fit = _chirp.fit(clean + noise, DT, np.array([19.95]), np.array([0.01]))
        est.append(fit["frequencies"][0])
        std.append(fit["std"][0])
        kappa.append(fit["kappa"][0])
    est, std = np.array(est), np.array(std)
    mc = est.std()
    assert abs(est.mean() - w) < 0.2 * mc
    assert 0.8 * mc < np.sqrt(np.mean(std ** 2)) < 1.25 * mc
    assert 0.6 < np.mean(np.abs(est - w) <= std) < 0.76
    assert np.mean(kappa) == pytest.approx(w * delta, rel=0.05)


def test_backbone_fit_of_two_windows_agrees():
    """The two halves of a Duffing record: ω₀ (a → 0) is the same number for both, within 3 combined std,
    while their constant-frequency fits differ by far more."""
    from experiments.simulate.mismatch import duffing_modes

    n, w = 2048, 20.0
    rng = np.random.default_rng(12)
    y = duffing_modes(DT * np.arange(n), [w], [0.003], [1.0], [0.0], -0.01) + 1e-3 * rng.standard_normal(n)
    a, b = pem.identify(y[:n // 2], DT, [18.0]), pem.identify(y[n // 2:], DT, [18.0])
    assert a.extra["drift_reported"] == ["small_amplitude"] == b.extra["drift_reported"]
    assert abs(a.frequencies[0] - b.frequencies[0]) <= 3 * np.hypot(a.std[0], b.std[0])
    for est in (a, b):
        assert abs(est.frequencies[0] - w) <= 3 * est.std[0]
    whole_a, whole_b = a.extra["drift"]["whole_record"][0], b.extra["drift"]["whole_record"][0]
    assert abs(whole_a - whole_b) > 10 * np.hypot(a.extra["white_noise_std"][0], b.extra["white_noise_std"][0])
