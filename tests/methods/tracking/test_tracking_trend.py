"""The trend stage of the windowed trackers (``trend=True``; methods/tracking/_trend.py).

Against independent numbers: window estimates that are exactly the frequency at each window's centre (what a
window estimator gives for a frequency linear in time) must be carried to the window's end with no lag — the
straight line itself, evaluated at the end; a step must be taken within the bound the module claims,
W/2 + ``trend_restart_after``·H samples; a single outlying window must be ignored. End to end, on a record
whose frequencies drift, a windowed tracker with the trend stage must not lag where it lagged without it.
"""

import numpy as np
import pytest
from _tracking_signals import DT, schedule

import methods
from methods.tracking import _trend

W, H = 512, 50
LEAD = (W - 1) * DT / 2
OPTS = dict(rate_noise=1e-4, meas_rel=0.005, gate=9.0, restart_after=2, rate0=0.002)


def _ends(n_windows):
    return (W - 1 + H * np.arange(n_windows)) * DT


def test_a_noise_free_linear_drift_is_followed_with_no_lag():
    t_end = _ends(80)
    w0, rate = np.array([3.2, 20.0, 22.0, 56.0]), np.array([0.1, 0.067, 0.067, 0.033]) / 100   # per s, relative
    line = lambda t: w0 * (1 + rate * t[:, None])                                                # noqa: E731
    freq, std, conv, restarts = _trend.smooth(t_end, line(t_end - LEAD), np.ones((80, 4), bool), 2 * LEAD, **OPTS)
    truth = line(t_end)
    lag_free = np.abs(freq / truth - 1)
    end_stamped = np.abs(line(t_end - LEAD) / truth - 1)           # what the window's end stamp would give
    assert np.all(end_stamped[20:, 0] > 0.004)                     # 0.5 % of ω behind at 0.1 %/s
    assert np.all(lag_free[40:] < 0.01 * end_stamped[40:])          # once the rate is learnt (~40 windows)
    assert lag_free[-1].max() < 1e-6
    assert conv.all() and restarts.sum() == 0 and np.all(std > 0)


def test_a_step_is_taken_within_half_a_window_plus_the_restart_delay():
    n = 120
    t_end = _ends(n)
    t_c = t_end - LEAD
    t_step = 60.0
    w = np.where(t_c[:, None] >= t_step, [3.2, 20.0, 23.32, 54.0], [3.2, 20.0, 22.0, 56.25])     # +6 %, −4 %
    rng = np.random.default_rng(11)
    z = w * (1 + 0.001 * rng.standard_normal(w.shape))
    freq, _, _, restarts = _trend.smooth(t_end, z, np.ones((n, 4), bool), 2 * LEAD, **OPTS)
    truth = np.where(t_end[:, None] >= t_step, [3.2, 20.0, 23.32, 54.0], [3.2, 20.0, 22.0, 56.25])
    bound = t_step + LEAD + OPTS["restart_after"] * H * DT + H * DT
    after = t_end >= bound
    assert np.all(np.abs(freq[after] / truth[after] - 1) < 0.01)
    assert np.all(restarts[2:] >= 1) and np.all(restarts[:2] == 0)


def test_one_outlying_window_is_ignored():
    n = 60
    t_end = _ends(n)
    z = np.full((n, 1), 20.0)
    z[30] = 22.0                                                   # one window mislabels the mode by 10 %
    freq, _, conv, restarts = _trend.smooth(t_end, z, np.ones((n, 1), bool), 2 * LEAD, **OPTS)
    assert restarts[0] == 0 and not conv[30, 0] and conv[31, 0]
    np.testing.assert_allclose(freq[25:, 0], 20.0, rtol=1e-3)


def test_the_trend_option_removes_the_lag_on_a_drifting_record():
    # four sinusoids whose frequencies rise by 0.25 %/s (phase = ∫ω dt), 100 µg of noise: the windows' own
    # estimates are accurate, their end stamp is W/2 behind (≈ 1.3 %)
    n = 4000
    w = schedule(n, drift=0.2)
    rng = np.random.default_rng(5)
    phase = np.cumsum(w, axis=0) * DT + rng.uniform(0, 2 * np.pi, 4)
    y = np.sin(phase) @ np.array([1.0, 1.0, 1.0, 1.0]) + 100 * 9.80665e-6 * rng.standard_normal(n)
    prior = w[0] * np.array([1.02, 0.99, 1.01, 0.98])
    plain = methods.track("fft", y, DT, prior, window_samples=W, hop_samples=H)
    trend = methods.track("fft", y, DT, prior, window_samples=W, hop_samples=H, trend=True)
    k = np.round(plain.t_s / DT).astype(int)
    late = plain.t_s > 40
    bias_plain = np.median(plain.frequencies[late] / w[k][late] - 1, axis=0)
    bias_trend = np.median(trend.frequencies[late] / w[k][late] - 1, axis=0)
    expected = -LEAD * 0.2 / ((n - 1) * DT) / (1 + 0.2 * 0.75)     # the end stamp's lag, relative, late in the record
    np.testing.assert_allclose(bias_plain, expected, rtol=0.3)
    assert np.all(np.abs(bias_trend) < 0.1 * abs(expected)), bias_trend
    assert "trend stage" in trend.message
    np.testing.assert_array_equal(trend.extra["window_frequencies"], plain.frequencies)


@pytest.mark.parametrize("options, words", [
    ({"trend": "yes"}, "trend = 'yes'"), ({"trend_gate": 0.0}, "trend_gate = 0.0"),
    ({"trend_rate_noise": -1.0}, "trend_rate_noise = -1.0"), ({"trend_restart_after": 0}, "trend_restart_after = 0"),
    ({"trend_meas_rel": float("nan")}, "trend_meas_rel = nan")])
def test_bad_trend_options_are_one_line_naming_the_option(options, words):
    with pytest.raises(ValueError) as err:
        methods.check_track_options("fft", [3.8, 16.0, 26.0, 46.0], DT, options)
    assert words in str(err.value) and "\n" not in str(err.value)
