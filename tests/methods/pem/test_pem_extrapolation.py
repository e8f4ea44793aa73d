"""The std of pem's small-amplitude frequency ω₀ (methods/pem/_drift.py): the amplitude line's std at zero
amplitude against numpy's own weighted fit, the model error of a bent backbone, and their combination."""

import dataclasses

import numpy as np

from methods.pem import _drift

X = np.array([0.05, 0.2, 0.5, 1.0])          # envelope amplitude² of four segments, (m/s²)²
S = np.full(4, 0.01)


def test_line_std_at_zero_is_numpys_weighted_fit_scaled_by_the_scatter():
    """σ₀ is √cov[1, 1] of ``numpy.polyfit(x, f, 1, w=1/s, cov=True)`` (numpy scales by χ²/(K − 2)) where the
    points scatter more than their s, and the unscaled covariance (their s alone) where they scatter less."""
    rng = np.random.default_rng(1)
    wide = 20.0 - 0.2 * X + 3 * S * rng.standard_normal(4)
    _, std0, _ = _drift._backbone_check(X, wide, S)
    _, cov = np.polyfit(X, wide, 1, w=1 / S, cov=True)
    chi2 = np.sum(((wide - np.polyval(np.polyfit(X, wide, 1, w=1 / S), X)) / S) ** 2)
    assert chi2 / 2 > 1
    np.testing.assert_allclose(std0, np.sqrt(cov[1, 1]), rtol=1e-9)
    tight = 20.0 - 0.2 * X + 0.1 * S * rng.standard_normal(4)
    _, std0, delta = _drift._backbone_check(X, tight, S)
    _, cov = np.polyfit(X, tight, 1, w=1 / S, cov="unscaled")
    np.testing.assert_allclose(std0, np.sqrt(cov[1, 1]), rtol=1e-9)
    assert delta == 0.0                                   # a straight backbone: no model error


def test_a_backbone_bent_like_a_loose_clamp_gets_the_model_error_it_misses():
    """Points on ω = ω₀ − c·a (a shift ∝ a, not a²) with small s: the straight line in a² is rejected and
    misses ω₀; δ is the larger change of ω₀ to a quadratic in a² or a line in a (by ``numpy.linalg.lstsq``
    here), and the line's ω₀ ± δ reaches the true ω₀."""
    w0, c = 20.0, 0.05
    f = w0 - c * np.sqrt(X)
    p, std0, delta = _drift._backbone_check(X, f, S * 0.01)
    assert p < 1e-6
    v = np.vander(X, 2)
    line = np.linalg.lstsq(v, f, rcond=None)[0][-1]
    quad = np.linalg.lstsq(np.vander(X, 3), f, rcond=None)[0][-1]
    in_a = np.linalg.lstsq(np.vander(np.sqrt(X), 2), f, rcond=None)[0][-1]
    np.testing.assert_allclose(delta, max(abs(quad - line), abs(in_a - line)), rtol=1e-6)
    assert abs(line - w0) > 3 * std0                       # beyond even the scatter-scaled std of the line
    assert abs(line - w0) <= delta * (1 + 1e-9)


def _report(p, std0, delta):
    m = len(p)
    nan = np.full(m, np.nan)
    report = _drift._report(np.zeros(3), np.full((3, m), np.nan), np.full((3, m), np.nan),
                            np.full((3, m), np.nan), np.zeros(m), 0.05)
    return dataclasses.replace(report, lack_of_fit_p=np.asarray(p, float), line_std_at_zero=np.asarray(std0, float),
                               small_amplitude_model_error=np.asarray(delta, float), small_amplitude_std=nan)


def test_the_reported_std_adds_the_line_and_the_model_error_only_where_the_line_is_rejected():
    """σ² = σ_x² + δ², σ_x = σ_chirp, or max(σ_chirp, σ₀) where the lack of fit rejects (p < 0.05); a mode
    without a line (NaN) keeps σ_chirp."""
    chirp = np.array([1.0, 1.0, 1.0, 1.0])
    report = _report([0.5, 0.01, 0.01, np.nan], [3.0, 3.0, 0.5, np.nan], [0.0, 4.0, 4.0, np.nan])
    got = _drift.extrapolation_std(chirp, report)
    np.testing.assert_allclose(got, [1.0, 5.0, np.hypot(1.0, 4.0), 1.0], rtol=1e-12)


def test_a_segments_frequency_on_the_backbone_chirp_is_a_constant_frequency_fits():
    """The frequency :func:`chirp_segment_frequencies` predicts for each segment of a noise-free backbone chirp
    e^{−σt}cos(ω_d t + κ(1 − e^{−2σt})/(2σ)) against a constant-frequency damped sinusoid fitted to that segment
    by ``scipy.optimize.curve_fit``: the shift from ω₀ agrees within 1 % of κ."""
    import scipy.optimize  # only this test fits a sinusoid by hand

    w0, zeta, kappa, dt, n = 10.0, 0.01, 0.05, 0.02, 200
    sigma, wd = zeta * w0, w0 * np.sqrt(1 - zeta ** 2)
    t = dt * np.arange(3 * n)
    y = np.exp(-sigma * t) * np.cos(wd * t + kappa * (1 - np.exp(-2 * sigma * t)) / (2 * sigma))
    pred = _drift.chirp_segment_frequencies(w0, kappa, zeta, 3, n, dt)[:, 0]

    def model(tt, w, s, a, b):
        return np.exp(-s * tt) * (a * np.cos(w * tt) + b * np.sin(w * tt))

    for k in range(3):
        part = slice(k * n, (k + 1) * n)
        p0 = (pred[k], sigma, 1.0, 0.0)
        w_fit = scipy.optimize.curve_fit(model, t[part], y[part], p0=p0, xtol=1e-12, ftol=1e-12)[0][0]
        assert abs((pred[k] - w0) - (w_fit - wd)) <= 0.01 * kappa     # the envelope²-weighted mean: 3 % off
    assert pred[0] > pred[1] > pred[2] > w0                    # the shift decays with the envelope²


def test_segments_on_the_chirps_backbone_give_a_small_chi2_and_off_it_the_sum_of_squares():
    """χ² of :func:`chirp_scatter` is Σ((ω̂ₖ − ω̄ₖ)/sₖ)² over the segments that count, on K dof."""
    fit = {"frequencies": np.array([10.0, 20.0]), "kappa": np.array([0.05, 0.0]), "damping": np.array([0.01, 0.01])}
    pred = _drift.chirp_segment_frequencies(fit["frequencies"], fit["kappa"], fit["damping"], 3, 200, 0.02)
    s = np.full((3, 2), 0.002)
    offsets = np.array([[0.0, 1.0], [0.0, -2.0], [0.0, 3.0]])
    report = _report([0.5, 0.5], [np.nan, np.nan], [0.0, 0.0])
    report = dataclasses.replace(report, frequencies=pred + offsets * s, std=s)
    chi2, dof, p = _drift.chirp_scatter(fit, report, 200, 0.02)
    np.testing.assert_allclose(chi2, [0.0, 14.0], atol=1e-9)
    np.testing.assert_array_equal(dof, [3, 3])
    assert p[0] > 0.99 and p[1] < 0.01
    report.frequencies[2, 1] = np.nan                          # a segment that does not count for mode 2
    chi2, dof, _ = _drift.chirp_scatter(fit, report, 200, 0.02)
    np.testing.assert_allclose(chi2[1], 5.0, rtol=1e-9)
    assert dof[1] == 2


def test_the_chirps_std_is_scaled_by_the_segments_scatter_about_it_only_where_it_is_significant():
    """σ_c = σ_chirp·√(χ²_s/K) where p_s < 0.05, σ_chirp elsewhere (and where p_s is NaN); the line's terms
    as before on top."""
    chirp = np.ones(4)
    report = _report([0.5, 0.5, 0.01, np.nan], [3.0, 3.0, 2.0, np.nan], [0.0, 0.0, 4.0, np.nan])
    scatter = (np.array([16.0, 6.0, 12.0, np.nan]), np.array([4, 4, 3, 0]), np.array([0.003, 0.2, 0.007, np.nan]))
    got = _drift.extrapolation_std(chirp, report, scatter)
    np.testing.assert_allclose(got, [2.0, 1.0, np.hypot(2.0, 4.0), 1.0], rtol=1e-12)


def test_a_kept_modes_record_average_is_its_own_not_the_other_modes_misfit():
    """The backbone fit's ``record_average`` ω + k̄κ of a mode whose envelope hardly decays, on a noise-free
    two-mode backbone chirp, against ``scipy.optimize.curve_fit`` of a constant-frequency damped sinusoid to
    that mode alone: within 2 % of its shift κ. A constant-frequency fit of both modes is further off: the
    other, decaying mode's drift stays in its residual and leaks in."""
    import scipy.optimize  # only this test fits sinusoids by hand

    from methods.pem import _chirp

    dt, n = 0.02, 512
    t = dt * np.arange(n)
    w, zeta, kappa, amp = np.array([3.2, 56.7]), np.array([0.005, 0.005]), np.array([-0.0064, -0.113]), (0.2, 1.0)
    sigma, wd = zeta * w, w * np.sqrt(1 - zeta ** 2)
    modes = [a * np.exp(-s * t) * np.cos(d * t + k * -np.expm1(-2 * s * t) / (2 * s))
             for a, s, d, k in zip(amp, sigma, wd, kappa, strict=True)]
    y = modes[0] + modes[1] + 1e-7 * np.random.default_rng(3).standard_normal(n)

    def model(tt, *p):
        return sum(np.exp(-p[i + 1] * tt) * (p[i + 2] * np.cos(p[i] * tt) + p[i + 3] * np.sin(p[i] * tt))
                   for i in range(0, len(p), 4))

    alone = scipy.optimize.curve_fit(model, t, modes[0], p0=(wd[0], sigma[0], amp[0], 0.0),
                                     xtol=1e-13, ftol=1e-13)[0][0]
    both = scipy.optimize.curve_fit(model, t, y, p0=(wd[0], sigma[0], amp[0], 0.0, wd[1], sigma[1], 1.0, 0.0),
                                    xtol=1e-13, ftol=1e-13)[0][0]
    fit = _chirp.fit(y, dt, w * (1 + kappa / w / 2), zeta)
    average_d = fit["record_average"][0] * np.sqrt(1 - fit["damping"][0] ** 2)   # as ω_d, like the fits above
    assert abs(average_d - alone) <= 0.02 * abs(kappa[0])
    assert abs(both - alone) > 5 * abs(average_d - alone)
    assert 0 < fit["record_average_std"][0] < np.inf


def test_a_mode_whose_fitted_envelope_grows_has_no_record_average():
    """The backbone fit's ζ may go negative within its bounds. A mode whose envelope grows e^{2.7} over the
    record has k̄ far beyond 1 (e^{-2σt} weighted): no record average for it (NaN, so the drift path keeps
    pem's own answer), while the decaying mode beside it keeps a finite one."""
    from methods.pem import _chirp  # the backbone fit itself, private to pem

    dt = 0.02
    t = np.arange(750) * dt
    rng = np.random.default_rng(1)
    y = (np.exp(3.0 * (t - t[-1])) * np.sin(56.0 * t) + np.exp(-0.05 * t) * np.sin(20.0 * t)
         + 0.01 * rng.standard_normal(t.size))
    fit = _chirp.fit(y, dt, np.array([20.0, 56.0]), np.array([0.0025, -3.0 / 56.0]))
    assert fit["damping"][1] < 0                                      # the premise: a growing envelope
    assert np.isnan(fit["record_average"][1]) and np.isnan(fit["record_average_std"][1])
    assert abs(fit["record_average"][0] - 20.0) < 0.01 and 0 < fit["record_average_std"][0] < 0.01
