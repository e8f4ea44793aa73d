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


def _sliding_over_a_step(n, t_step, w1, w2, noise, seed):
    """Window estimates as the windows slide over a step at ``t_step``: at centre t_c a window holds the share
    clip((t_c + LEAD − t_step)/(2 LEAD), 0, 1) of its samples after the step, and its estimate moves from w1 to
    w2 in proportion (a ramp over one window span), then stays at w2; relative noise ``noise``."""
    t_end = _ends(n)
    share = np.clip((t_end - t_step) / (2 * LEAD), 0.0, 1.0)
    z = w1 + (w2 - w1) * share[:, None]
    z = z * (1 + noise * np.random.default_rng(seed).standard_normal(z.shape))
    return t_end, z, np.where(t_end[:, None] >= t_step, w2, w1)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_restart_forgets_the_rate_the_ramp_over_a_step_taught(seed):
    # a +5 % step on 20 rad/s: the windows' ramp over the step teaches the filter a rate; kept at the restart it
    # carries the output past the new level, reset and held until the windows are past the step it does not
    n, t_step = 120, 60.0
    t_end, z, truth = _sliding_over_a_step(n, t_step, np.array([20.0]), np.array([21.0]), 5e-4, seed)
    runs = {rr: _trend.smooth(t_end, z, np.ones((n, 1), bool), 2 * LEAD, **OPTS, restart_rate=rr)
            for rr in _trend.RESTART_RATES}
    past = t_end >= t_step + 2 * LEAD + H * DT                  # every window wholly after the step
    over = {rr: np.max(np.abs(f[past, 0] / truth[past, 0] - 1)) for rr, (f, *_rest) in runs.items()}
    assert all(r[3][0] >= 1 for r in runs.values())              # the gate restarted the mode in every variant
    assert over["keep"] > 0.005, over                            # the overshoot of the kept rate
    assert over["hold"] < 0.003, over                            # 3 × the windows' noise
    late = t_end >= t_step + 4 * LEAD
    np.testing.assert_allclose(runs["hold"][0][late, 0], 21.0, rtol=2e-3)


def test_a_restart_holds_the_rate_at_zero_until_the_windows_are_past_the_change():
    n, t_step = 120, 60.0
    t_end, z, _ = _sliding_over_a_step(n, t_step, np.array([20.0]), np.array([21.0]), 0.0, 0)
    bank = _trend.TrendBank(1, **_bank_opts(), restart_rate="hold")
    first_miss = restart = None
    for j in range(n):
        _, _, conv, nu = bank.step(t_end[j] - LEAD, LEAD, z[j], np.ones(1, bool))
        if first_miss is None and np.isfinite(nu[0]) and nu[0] ** 2 > OPTS["gate"]:
            first_miss = j
        if restart is None and bank.restarts[0] == 1:
            restart = j
        if restart is not None and t_end[j] - 2 * LEAD <= t_end[first_miss]:
            # a window that still holds samples from before the first gated window's end: its own estimate, rate 0
            assert bank.kf[0].x[1] == 0.0 and bank.kf[0].x[0] == z[j, 0] and conv[0]
    assert first_miss is not None and restart == first_miss + OPTS["restart_after"] - 1
    assert np.isfinite(nu[0])                    # afterwards the windows are gated and update the mode again


def _gap(n, t_end, gap):
    """Determined flags: every window but those whose centre lies in ``gap`` (s)."""
    t_c = t_end - LEAD
    return ((t_c < gap[0]) | (t_c > gap[1]))[:, None] & np.ones((n, 1), bool)


def test_a_jump_across_a_gap_is_a_new_level_not_a_rate():
    # no window determines the mode for 30 s (three window spans: the windows over a step fail the fit's
    # tests) and the frequency is 4 % lower after it: the first window after the gap sets the level, the
    # rate held before the gap stays; spread over the gap as a rate, the jump overshoots
    n = 140
    t_end = _ends(n)
    t_c = t_end - LEAD
    z = np.where(t_c[:, None] < 65.0, 20.0, 19.2) * (1 + 5e-4 * np.random.default_rng(4).standard_normal((n, 1)))
    determined = _gap(n, t_end, (55.0, 85.0))
    after = t_c > 85.0
    out = {rg: _trend.TrendBank(1, **_bank_opts(), relevel_gap=rg) for rg in (True, False)}
    freq = {rg: np.array([b.step(t_c[j], LEAD, z[j], determined[j])[0][0] for j in range(n)])
            for rg, b in out.items()}
    err = {rg: np.max(np.abs(f[after] / 19.2 - 1)) for rg, f in freq.items()}
    assert out[True].relevels[0] == 1 and out[True].restarts[0] == 0
    assert err[True] < 0.002 and err[False] > 0.005, err


def test_a_drift_across_a_gap_keeps_its_rate():
    # a drift of 0.1 %/s learnt before the gap: the window after it agrees with the prediction, so it updates
    # the filter as any other, and the output stays on the line (no lag while a rate is learnt again)
    n = 140
    t_end = _ends(n)
    t_c = t_end - LEAD
    z = (20.0 * (1 + 0.001 * t_c))[:, None]
    determined = _gap(n, t_end, (70.0, 90.0))
    bank = _trend.TrendBank(1, **_bank_opts())
    freq = np.array([bank.step(t_c[j], LEAD, z[j], determined[j])[0][0] for j in range(n)])
    after = t_c > 90.0
    assert bank.relevels[0] == 0 and bank.restarts[0] == 0
    np.testing.assert_allclose(freq[after], 20.0 * (1 + 0.001 * t_end[after]), rtol=1e-3)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_gate_tests_a_window_against_its_own_std(seed):
    # windows with their own std 0.3 %, weighed as gated_pencil weighs them, R = 10·std² (ten windows share
    # each sample), and a +3 % jump: against the inflated R the jump passes the gate, the level follows it as
    # an update and learns a rate that overshoots by ~1 %; against the window's own std it fails the gate and
    # the restart takes the new level
    n, own = 140, 0.003
    t_c = _ends(n) - LEAD
    z = np.where(t_c[:, None] < 60.0, 20.0, 20.6) * (1 + own * np.random.default_rng(seed).standard_normal((n, 1)))
    after = t_c > 60.0 + 2 * LEAD
    err, restarts = {}, {}
    for own_gate in (True, False):
        bank = _trend.TrendBank(1, **_bank_opts())
        f = np.array([bank.step(t_c[j], LEAD, z[j], np.ones(1, bool), np.sqrt(10) * own * z[j],
                                own * z[j] if own_gate else None)[0][0] for j in range(n)])
        err[own_gate], restarts[own_gate] = np.max(np.abs(f[after] / 20.6 - 1)), bank.restarts[0]
    assert restarts[True] == 1 and err[True] < 0.004, (err, restarts)
    assert restarts[False] == 0 and err[False] > 0.008, (err, restarts)


def _bank_opts():
    return {"rate_noise": OPTS["rate_noise"], "meas_rel": OPTS["meas_rel"], "gate": OPTS["gate"],
            "restart_after": OPTS["restart_after"], "rate0": OPTS["rate0"]}


def _ramp_then_gap(seed, n=160, t_step=60.0, rise=0.05, own_straddle=0.01, own_clean=5e-4, gap=(1.0, 1.6)):
    """Windows sliding over a +``rise`` step on 20 rad/s (a ramp over one window span), their own std
    ``own_straddle`` while they straddle it and ``own_clean`` after, and no window determining the mode from
    ``gap[0]`` to ``gap[1]`` spans after the step (the windows over a step that rang the modes often fail the
    fit's tests: the 0.1 s six-mode record). Returns (t_end, z, own, determined, the new level)."""
    t_end = _ends(n)
    share = np.clip((t_end - t_step) / (2 * LEAD), 0.0, 1.0)
    own = np.where((share > 0) & (share < 1), own_straddle, own_clean)
    z = 20.0 * (1 + rise * share) * (1 + own * np.random.default_rng(seed).standard_normal(n))
    determined = ~((t_end > t_step + gap[0] * 2 * LEAD) & (t_end < t_step + gap[1] * 2 * LEAD))
    return t_end, z, own, determined, 20.0 * (1 + rise)


def _run_bank(restart_rate, t_end, z, own, determined):
    """The bank fed as gated_pencil feeds it: R = 10·own² (W/H = 10), the gate against the window's own std."""
    bank = _trend.TrendBank(1, **_bank_opts(), restart_rate=restart_rate)
    out, rates = [], []
    for j in range(t_end.size):
        zj = z[j:j + 1]
        out.append(bank.step(t_end[j] - LEAD, LEAD, zj, determined[j:j + 1], np.sqrt(10) * own[j] * zj,
                             own[j] * zj)[0][0])
        rates.append(bank.kf[0].x[1] if bank.kf[0] is not None else np.nan)
    return np.array(out), np.array(rates), bank


def test_freeze_after_a_step_the_level_is_back_within_two_clean_window_stds_after_the_gap():
    # the independent number: once a clean window (own std 0.05 %) follows the gap, the output is a level
    # sample of it, so within 2σ = 0.1 % of the new level from the first window after the gap on; with the rate
    # the ramp taught kept ("keep", main's default before) the output carries it on
    t_step, gap_end = 60.0, 1.6
    worst = {"freeze": [], "keep": []}
    for seed in range(1, 11):
        t_end, z, own, det, level = _ramp_then_gap(seed, t_step=t_step, gap=(1.0, gap_end))
        after = t_end >= t_step + gap_end * 2 * LEAD + H * DT
        for rr in worst:
            worst[rr].append(np.max(np.abs(_run_bank(rr, t_end, z, own, det)[0][after] / level - 1)))
    assert max(worst["freeze"]) < 1e-3, worst
    assert sum(w > 1e-3 for w in worst["keep"]) >= 4, worst


def test_freeze_the_windows_that_may_straddle_a_change_do_not_teach_the_rate():
    t_end, z, own, det, _ = _ramp_then_gap(3, gap=(5.0, 5.0))          # no gap
    out, rates, bank = _run_bank("freeze", t_end, z, own, det)
    keep_rates = _run_bank("keep", t_end, z, own, det)[1]
    first = int(np.flatnonzero(np.isfinite(bank.first_miss_end) & (t_end >= bank.first_miss_end[0]))[0])
    # until the first gated window the two variants are the same filter
    np.testing.assert_array_equal(rates[:first], keep_rates[:first])
    # at it the rate goes back to the one after the last window that ended before its start
    before = np.flatnonzero(t_end <= t_end[first] - 2 * LEAD)[-1]
    assert rates[first] == keep_rates[before]
    # and the windows that start before its end leave the rate as it was
    straddling = (t_end - 2 * LEAD <= t_end[first]) & (np.arange(t_end.size) >= first)
    assert np.all(rates[straddling] == rates[first])
    assert not np.all(rates[~straddling & (np.arange(t_end.size) > first)] == rates[first])


def test_gated_pencil_refuses_an_unknown_trend_restart_rate():
    with pytest.raises(ValueError) as err:
        methods.check_track_options("gated_pencil", [3.8, 16.0, 26.0, 46.0], DT, {"trend_restart_rate": "drop"})
    assert "trend_restart_rate = 'drop'" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("window_s, hop_s, memory", [(10.2, 1.02, 1.0), (37.8, 3.8, 1.0), (0.126, 0.0126, 2.0)])
def test_trend_memory_gives_the_filter_a_time_constant_of_that_many_windows(window_s, hop_s, memory):
    # the bank's own filter, run to its steady state on a constant frequency (windows every hop_s), then its
    # closed loop x ← (I − KH)F x: a second-order loop whose natural frequency, |log λ|/hop, must be
    # 1/(memory · window_s) (methods/tracking/_defaults.py, trend_rate_noise_memory), damping 1/√2
    from methods.tracking import _defaults
    q = _defaults.trend_rate_noise_memory(0.005, window_s, memory)
    bank = _trend.TrendBank(1, rate_noise=q, meas_rel=0.005, gate=9.0, restart_after=2, rate0=0.002)
    for j in range(4000):
        bank.step(j * hop_s, window_s / 2, np.array([2.0]), np.array([True]))
    kf = bank.kf[0]
    gain = kf.P_prior @ kf.H.T / (kf.H @ kf.P_prior @ kf.H.T + kf.R)   # the steady-state Kalman gain
    loop = (np.eye(2) - gain @ kf.H) @ kf.F
    s = np.log(np.linalg.eigvals(loop).astype(complex)) / hop_s
    assert np.allclose(1 / np.abs(s), memory * window_s, rtol=0.03)
    assert np.allclose(-s.real / np.abs(s), 1 / np.sqrt(2), atol=0.02)


def test_gated_pencil_trend_memory_sets_the_rate_noise_from_the_window_and_scales_with_time():
    from methods.tracking import _gated_pencil
    prior = np.array([0.8, 1.3, 2.0, 2.9, 4.1, 5.5])
    opts = [_gated_pencil.check_options("gated_pencil", prior / a, 0.1 * a, {"trend_memory": 1.0}) for a in (1, 5)]
    span = [(o.window_samples - 1) * 0.1 * a for o, a in zip(opts, (1, 5), strict=True)]
    assert opts[0].trend_rate_noise == pytest.approx(0.005 / span[0] ** 2, rel=1e-12)
    assert opts[1].trend_rate_noise == pytest.approx(opts[0].trend_rate_noise / 25, rel=1e-12)   # q ∝ time⁻²
    given = _gated_pencil.check_options("gated_pencil", prior, 0.1, {"trend_memory": 1.0, "trend_rate_noise": 1e-5})
    assert given.trend_rate_noise == 1e-5                                                      # the user's wins
    with pytest.raises(ValueError) as err:
        methods.check_track_options("gated_pencil", prior, 0.1, {"trend_memory": 0})
    assert "trend_memory = 0" in str(err.value) and "\n" not in str(err.value)


def test_level_only_windows_move_the_level_and_leave_the_rate():
    # a drift of 0.1 %/s learnt over 60 windows, then windows 0.2 % above the line: marked level_only they
    # move the level towards them and leave the rate exactly as learnt; unmarked they also teach a rate
    n = 80
    t_end = _ends(n)
    t_c = t_end - LEAD
    z = 20.0 * (1 + 0.001 * t_c)
    z[60:] *= 1.002
    out = {}
    for level_only in (True, False):
        bank = _trend.TrendBank(1, **_bank_opts())
        rates = []
        for j in range(n):
            bank.step(t_c[j], LEAD, z[j:j + 1], np.ones(1, bool), level_only=np.array([level_only and j >= 60]))
            rates.append(bank.kf[0].x[1])
        out[level_only] = (np.asarray(rates), bank.kf[0].x[0])
    rates, level = out[True]
    assert np.all(rates[60:] == rates[59])
    assert abs(level / (20.0 * (1 + 0.001 * t_c[-1]) * 1.002) - 1) < 5e-4
    assert not np.all(out[False][0][60:] == rates[59])


def _collapse(seed, span_relevel, long_s=40.0, short_s=9.2, hop_s=3.7, t_step=30.0, rise=0.01, own=5e-4,
              short_from=41.0):
    """A capped window that collapses (``window_from_estimates``): windows of ``long_s`` up to 40.9 s, then of
    ``short_s`` every ``hop_s`` from ``short_from``; the frequency (20 rad/s) steps by ``rise`` at ``t_step``,
    inside the long windows; each window's estimate is the mean of the frequency over its span (own std
    ``own``). The bank fed as gated_pencil feeds it (R = (span/hop)·own², the gate against own). Returns the
    window ends, the output and the new level."""
    t_end = np.concatenate([np.arange(long_s, short_from, hop_s / 4), np.arange(short_from, 100.0, hop_s)])
    span = np.where(t_end < short_from, long_s, short_s)
    share = np.clip((t_end - t_step) / span, 0.0, 1.0)
    z = 20.0 * (1 + rise * share) * (1 + own * np.random.default_rng(seed).standard_normal(t_end.size))
    bank = _trend.TrendBank(1, **OPTS, span_relevel=span_relevel)
    out = np.array([bank.step(t_end[j] - span[j] / 2, span[j] / 2, z[j:j + 1], np.ones(1, bool),
                              np.sqrt(span[j] / hop_s) * own * z[j:j + 1], own * z[j:j + 1])[0][0]
                    for j in range(t_end.size)])
    return t_end, out, 20.0 * (1 + rise)


def test_span_relevel_the_jump_to_a_shorter_window_is_a_level_not_a_rate():
    # the long windows average a +1 % step made 10 s before their end (+0.25 %), the short ones after it are
    # wholly after it: the jump between them passes the gate. Learnt as a rate it carries the output past the
    # new level; with span_relevel the first short window sets the level, so the output stays within 3 × the
    # windows' own std (0.15 %) of it from the first short window on
    worst = {False: [], True: []}
    for seed in range(1, 11):
        for sr in worst:
            t_end, out, level = _collapse(seed, sr)
            worst[sr].append(np.max(np.abs(out[t_end >= 41.0] / level - 1)))
    assert max(worst[True]) < 1.5e-3, worst
    assert sum(w > 1.5e-3 for w in worst[False]) >= 8, worst


def test_span_relevel_changes_nothing_where_the_span_does_not_change():
    n, t_step = 120, 60.0
    t_end, z, _ = _sliding_over_a_step(n, t_step, np.array([20.0]), np.array([21.0]), 5e-4, 4)
    runs = []
    for sr in (False, True):
        bank = _trend.TrendBank(1, **OPTS, span_relevel=sr)
        runs.append([bank.step(t_end[j] - LEAD, LEAD, z[j], np.ones(1, bool))[0][0] for j in range(n)])
    np.testing.assert_array_equal(runs[0], runs[1])


def test_gated_pencil_refuses_a_trend_span_relevel_that_is_not_a_bool():
    with pytest.raises(ValueError) as err:
        methods.check_track_options("gated_pencil", [3.8, 16.0, 26.0, 46.0], DT, {"trend_span_relevel": "yes"})
    assert "trend_span_relevel = 'yes'" in str(err.value) and "\n" not in str(err.value)
