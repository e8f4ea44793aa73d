"""``gated_pencil`` against the truth of a record built independently: free decays restarted by pulses.

Between two pulses the record is an exact sum of damped sinusoids at known frequencies; at each pulse every
mode jumps to a new random amplitude and phase (what a thruster pulse does). The gated pencil's window
estimates must sit on the true frequencies; the same windows through NExT-ERA (the naive baseline) must not
— the phase jumps are what the gating removes. Also: the pulse detector finds the pulses.
"""

import numpy as np
import pytest
import scipy.signal

import methods
from methods import pem
from methods.tracking import _gated_pencil

DT = 0.02
FREQ = np.array([3.23, 20.24, 22.0, 56.67])
PRIOR = FREQ * np.array([1.03, 0.98, 1.02, 0.97])


def pulsed_decays(n, pulses, seed, zeta=0.005, noise=1e-4):
    """Sum of the four modes, each restarted at every pulse with a random amplitude and phase (+ white noise)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    y = np.zeros(n)
    starts = np.concatenate(([0], pulses))
    stops = np.concatenate((pulses, [n]))
    for a, b in zip(starts, stops, strict=True):
        tau = t[a:b] - t[a]
        for w in FREQ:
            amp, phase = rng.uniform(0.02, 0.1), rng.uniform(0, 2 * np.pi)
            y[a:b] += amp * np.exp(-zeta * w * tau) * np.cos(w * np.sqrt(1 - zeta ** 2) * tau + phase)
    return y + noise * rng.standard_normal(n)


def test_window_estimates_are_unbiased_under_pulses_where_next_era_is_not():
    n = 3000
    pulses = np.arange(150, n, 230)                       # every 4.6 s: two or three in each 10 s window
    y = pulsed_decays(n, pulses, seed=3)
    gp = methods.track("gated_pencil", y, DT, PRIOR, hop_samples=100, trend=False)
    ne = methods.track("next_era", y, DT, PRIOR, hop_samples=100)
    err_gp = np.nanmedian(np.abs(gp.frequencies / FREQ - 1), axis=0)
    err_ne = np.nanmedian(np.abs(ne.frequencies / FREQ - 1), axis=0)
    assert gp.converged.all(axis=0).mean() == 1.0 or gp.converged.mean() > 0.95
    assert np.all(err_gp < 0.002), err_gp
    assert np.median(err_ne) > 3 * np.median(err_gp), (err_ne, err_gp)


def test_the_pulse_detector_flags_the_pulses():
    n = 512
    pulses = np.array([100, 300])
    y = pulsed_decays(n, pulses, seed=4)
    flags = _gated_pencil.pulse_flags(y - y.mean(), ar_order=16, cut=4.0)
    for p in pulses:
        assert flags[p - 1: p + 2].any(), p
    assert flags.mean() < 0.05


def test_the_trend_stage_is_on_by_default_and_its_options_are_checked():
    opts = methods.check_track_options("gated_pencil", PRIOR, DT, {})
    five_periods = round(5 * 2 * np.pi / PRIOR[0] / DT)            # 472 samples: the prior's slowest mode
    assert opts.trend is True and opts.refine is True and opts.close_pairs is True
    assert opts.window_samples == five_periods
    assert opts.hop_samples == round(five_periods / 10) and opts.rows == round(five_periods / 8)
    for bad, words in (({"rows": 3}, "rows = 3"), ({"rows": 10}, "rows = 10 must be at least"),
                       ({"outlier_cut": 0}, "outlier_cut = 0"), ({"trend_gate": -1.0}, "trend_gate = -1.0"),
                       ({"window_samples": 30}, "30 samples (0.6 s) is too short for 4 mode(s)"),
                       ({"window_s": 2.0, "window_samples": 100}, "give window_s or window_samples, not both"),
                       ({"refine": "yes"}, "refine = 'yes'"), ({"refine_steps": 0}, "refine_steps = 0"),
                       ({"min_segment": 2}, "min_segment = 2"), ({"max_phase_std": 0.0}, "max_phase_std = 0.0"),
                       ({"overlap_inflation": float("nan")}, "overlap_inflation = nan"),
                       ({"close_pairs": 1}, "close_pairs = 1")):
        try:
            methods.check_track_options("gated_pencil", PRIOR, DT, bad)
        except ValueError as err:
            assert words in str(err) and "\n" not in str(err), str(err)
        else:
            raise AssertionError(f"{bad} accepted")


def test_white_noise_is_never_tracked_as_converged():
    for seed in range(3):
        y = 0.01 * np.random.default_rng(seed).standard_normal(3000)
        tr = methods.track("gated_pencil", y, DT, PRIOR)
        assert not tr.converged.any(), tr.message


def test_a_run_too_short_for_the_slowest_mode_is_left_out_not_the_window():
    # six modes at Δt = 0.1 s (the slowest period 7.5 s): a 2.7 s run cannot tell mode 1's cosine and sine
    # from the offset and the other modes, and the shared fit refuses the whole window with it; left out,
    # the window's other run gives the exact poles of a noise-free decay
    dt = 0.1
    w, z = np.array([0.84, 1.365, 2.08, 3.016, 4.223, 5.665]), np.full(6, 0.005)
    runs = [(0, 27), (28, 400)]
    rng = np.random.default_rng(0)
    y = np.zeros(400)
    for a, b in runs:
        t = np.arange(b - a) * dt
        for wi, zi in zip(w, z, strict=True):
            y[a:b] += rng.uniform(0.5, 1.0) * np.exp(-zi * wi * t) * np.cos(wi * np.sqrt(1 - zi ** 2) * t
                                                                          + rng.uniform(0, 2 * np.pi))
    assert pem.separable_fit(y, dt, runs, w * 1.002, z, 10) is None
    kept = _gated_pencil._fittable(y, dt, runs, w * 1.002, z)
    assert kept == [(28, 400)]
    np.testing.assert_allclose(pem.separable_fit(y, dt, kept, w * 1.002, z, 10)[0], w, rtol=1e-6)


def _pulsed_pair(scale, seed, n=4000, noise=0.01):
    """Four modes with two of them 1.5 % apart (20.0 and 20.3 rad/s: half the 9.7 s window's resolution,
    2π/9.7 = 0.65 rad/s), each restarted at every pulse (every 4.6 s); ``scale`` the amplitude of each mode."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    y = np.zeros(n)
    pulses = np.arange(150, n, 230)
    for a, b in zip(np.concatenate(([0], pulses)), np.concatenate((pulses, [n])), strict=True):
        for w, s in zip(PAIR, scale, strict=True):
            amp, phase = rng.uniform(0.02, 0.1), rng.uniform(0, 2 * np.pi)
            y[a:b] += s * amp * np.exp(-0.005 * w * (t[a:b] - t[a])) * np.cos(w * (t[a:b] - t[a]) + phase)
    return y + noise * rng.standard_normal(n)


PAIR = np.array([3.23, 20.0, 20.3, 56.67])


def test_close_pairs_counts_a_resolved_pair_and_never_a_dead_mode():
    # within half the window's resolution each member's std (0.2–0.3 % of ω) is over the phase-std test's
    # 0.5 rad / 9.7 s (0.26 %), so the default determines the pair in almost no window; resolved at 3
    # combined std, close_pairs counts it, every estimate within 1 % of the true frequency
    prior = PAIR * np.array([1.03, 0.99, 1.01, 0.97])
    for seed in (2, 3, 5):
        y = _pulsed_pair([1, 1, 1, 1], seed)
        runs = {cp: methods.track("gated_pencil", y, DT, prior, hop_samples=100, trend=False, close_pairs=cp)
                for cp in (False, True)}
        assert runs[False].converged[:, 1:3].mean() < 0.1, seed
        got = runs[True].converged[:, 1:3]
        assert np.all(got.mean(axis=0) >= 0.2), (seed, got.mean(axis=0))
        err = np.abs(runs[True].frequencies[:, 1:3] / PAIR[1:3] - 1)
        assert np.all(err[got] < 0.01), (seed, err[got].max())
        # the same record with the upper member absent: its component has no pole of its own, never counted
        dead = methods.track("gated_pencil", _pulsed_pair([1, 1, 0, 1], seed), DT, prior, hop_samples=100,
                             trend=False, close_pairs=True)
        assert not dead.converged[:, 2].any(), seed
        assert dead.converged[:, 1].mean() > 0.4, seed


def test_window_from_estimates_follows_the_resolved_modes_not_a_near_double_prior():
    # a prior whose modes 2 and 3 are 0.1 rad/s apart asks for the window's cap, 20 periods of its slowest mode
    # (39 s); the record's modes are 1.76 rad/s apart (over twice the prior's 0.1), so once they are determined
    # the window is five periods of the prior's slowest mode, 5 · 2π/3.3 = 9.52 s (pulses every 10 s: the long
    # window's Hankel rows, an eighth of it, leave ≥ 2L pulse-free columns)
    n = 6000
    y = pulsed_decays(n, np.arange(150, n, 500), seed=6)
    prior = np.array([3.3, 20.9, 21.0, 55.0])
    base = methods.track("gated_pencil", y, DT, prior, window_from_estimates=False)
    tr = methods.track("gated_pencil", y, DT, prior)
    cap = 20 * 2 * np.pi / prior[0]
    np.testing.assert_allclose(base.extra["window_span_s"], cap, rtol=0.01)
    late = tr.t_s > 60.0
    np.testing.assert_allclose(tr.extra["window_span_s"][late], 5 * 2 * np.pi / prior[0], rtol=0.01)
    err = np.abs(tr.frequencies[late] / FREQ - 1)
    assert np.all(err < 0.005) and tr.converged[late].mean() > 0.9, (err.max(), tr.converged[late].mean())
    # causal: a window's length follows the windows before it only
    changed = y.copy()
    changed[4000:] = pulsed_decays(n - 4000, np.arange(100, n - 4000, 300), seed=7)
    other = methods.track("gated_pencil", changed, DT, prior, window_from_estimates=True)
    early = tr.t_s <= 3999 * DT
    np.testing.assert_array_equal(other.frequencies[early], tr.frequencies[early])
    np.testing.assert_array_equal(other.extra["window_span_s"][early], tr.extra["window_span_s"][early])
    # a window the user gives is kept
    given = methods.track("gated_pencil", y, DT, prior, window_from_estimates=True, window_samples=600)
    np.testing.assert_allclose(given.extra["window_span_s"], 599 * DT)
    refused_in_one_line(prior, "window_from_estimates")


def refused_in_one_line(prior, option):
    """A non-boolean value of a switch is a one-line ValueError naming it, before any record."""
    with pytest.raises(ValueError, match=f"{option} = 'yes'") as err:
        methods.check_track_options("gated_pencil", prior, DT, {option: "yes"})
    assert "\n" not in str(err.value)


TWO = np.array([3.0, 60.0])


def stepped_two_modes(n, pulses, step_at, step, seed, zeta=0.005, noise=1e-4):
    """A slow and a fast mode, free decays restarted at each pulse (random amplitude and phase); at sample
    ``step_at`` the fast mode's frequency steps by ``step`` (relative) with its amplitude and phase continuous."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    w = np.tile(TWO, (n, 1))
    w[step_at:, 1] *= 1 + step
    y = np.zeros(n)
    starts = np.concatenate(([0], pulses))
    stops = np.concatenate((pulses, [n]))
    for i in range(2):
        phase = np.concatenate(([0.0], np.cumsum(w[:-1, i]) * DT))        # ∫ω dt: continuous over the step
        for a, b in zip(starts, stops, strict=True):
            amp, phi = rng.uniform(0.02, 0.1), rng.uniform(0, 2 * np.pi)
            y[a:b] += amp * np.exp(-zeta * w[a:b, i] * (t[a:b] - t[a])) * np.cos(phase[a:b] - phase[a] + phi)
    return y + noise * rng.standard_normal(n), w


def test_own_windows_follow_a_fast_mode_stepping_with_no_pulse_after_it():
    # the window is five periods of the slow mode (10.5 s, 175 periods of the fast one); the fast mode's ring
    # dies away in 1/(ζω) = 3.3 s, so after a step with no pulse after it the long windows hold its old frequency
    # (the ring from the pulse before the step dominates them) and then determine nothing; its own window
    # (five of its periods, at least the model's minimum) sees the ring after the step
    n, step_at, step = 3500, 1850, 0.08                       # 70 s, the step at 37 s, 5 s after the last pulse
    y, w = stepped_two_modes(n, np.array([100, 600, 1100, 1600]), step_at, step, seed=8)
    prior = TWO * np.array([1.03, 0.97])
    base = methods.track("gated_pencil", y, DT, prior)
    tr = methods.track("gated_pencil", y, DT, prior, own_windows=True)
    fast_period = 2 * np.pi / w[-1, 1]
    k = np.round(tr.t_s / DT).astype(int)

    def reconverged(track):
        """Fast-mode periods after the step from which the track stays within 1 % (inf: never)."""
        bad = (track.t_s >= step_at * DT) & ~(np.abs(track.frequencies[:, 1] / w[k, 1] - 1) < 0.01)
        return np.inf if bad[-1] else (track.t_s[np.flatnonzero(bad)[-1] + 1] - step_at * DT) / fast_period

    assert reconverged(tr) <= 50 < reconverged(base), (reconverged(tr), reconverged(base))
    # each mode's own window: five of its periods, two beats of its neighbour, never under the minimum
    np.testing.assert_array_equal(_gated_pencil.own_window_samples(np.array([3.0, 60.0]), DT, 39),
                                  [round(5 * 2 * np.pi / 3.0 / DT), 39])
    np.testing.assert_array_equal(_gated_pencil.own_window_samples(np.array([20.0, 24.0]), DT, 39),
                                  [round(2 * 2 * np.pi / 4.0 / DT)] * 2)
    # before the step the two agree within 1 % (no false change on the pulsed record)
    early = tr.t_s < step_at * DT
    assert np.all(np.abs(tr.frequencies[early] - base.frequencies[early]) <= 0.01 * TWO), "changed before the step"
    refused_in_one_line(prior, "own_windows")


def test_own_windows_skip_a_watched_fit_at_the_pencils_pole_and_keep_the_track(monkeypatch):
    # the short fits skipped where the pencil's pole lies within one combined std of the trend: a change needs
    # three, so every decision and the track are those of the option fitting every short window
    n, step_at, step = 3500, 1850, 0.08
    y, w = stepped_two_modes(n, np.array([100, 600, 1100, 1600]), step_at, step, seed=8)
    prior = TWO * np.array([1.03, 0.97])
    tr = methods.track("gated_pencil", y, DT, prior, own_windows=True)
    monkeypatch.setattr(_gated_pencil, "OWN_SCREEN_STD", None)
    every = methods.track("gated_pencil", y, DT, prior, own_windows=True)
    assert tr.extra["own_fits_skipped"] > 0 == every.extra["own_fits_skipped"]
    np.testing.assert_array_equal(tr.extra["own_window_changes"], every.extra["own_window_changes"])
    np.testing.assert_array_equal(np.isnan(tr.frequencies), np.isnan(every.frequencies))
    np.testing.assert_allclose(tr.frequencies, every.frequencies, rtol=1e-6)


def test_window_from_estimates_only_for_a_prior_pair_the_estimates_put_twice_as_far_apart():
    # the prior's window: two beats of its closest pair, 2 · 2π/0.5 = 25.13 s, over five periods of 3 rad/s
    # (10.47 s); estimates 3 rad/s apart (≥ 2 × 0.5): five periods of the prior's slowest mode; 1.1 rad/s
    # apart: two beats of them, 4π/1.1 = 11.42 s; 0.9 apart (under 2 × 0.5), or a mode never determined: the
    # prior's window
    prior = np.array([3.0, 20.0, 20.5, 60.0])
    rule = _gated_pencil.estimates_window_s
    every = np.ones(4, dtype=bool)
    assert rule(prior, prior, every) == pytest.approx(4 * np.pi / 0.5)
    assert rule(prior, np.array([3.0, 19.0, 22.0, 60.0]), every) == pytest.approx(5 * 2 * np.pi / 3.0)
    assert rule(prior, np.array([3.0, 20.0, 21.1, 60.0]), every) == pytest.approx(4 * np.pi / 1.1)
    assert rule(prior, np.array([3.0, 20.0, 20.9, 60.0]), every) == pytest.approx(4 * np.pi / 0.5)
    undetermined = np.array([1, 1, 0, 1], dtype=bool)
    assert rule(prior, np.array([3.0, 19.0, 22.0, 60.0]), undetermined) == pytest.approx(4 * np.pi / 0.5)
    # a prior whose window is five periods of its slowest mode (one mode, or no close pair) keeps it, whatever
    # the estimates (a slowest mode estimated 5 % higher does not shorten the window)
    assert rule(np.array([3.0]), np.array([3.15]), np.ones(1, bool)) == pytest.approx(5 * 2 * np.pi / 3.0)
    assert rule(np.array([3.0, 30.0]), np.array([3.15, 31.0]), np.ones(2, bool)) == pytest.approx(5 * 2 * np.pi / 3.0)


def test_the_window_options_keep_the_default_track_under_a_continuing_force():
    # the same near-double prior as above, the four modes driven by white noise (no pulse: nothing flagged in
    # most windows); the estimates put modes 2 and 3 1.76 rad/s apart, but a forced response is averaged by
    # the longer window and no ring dies away: with both options the track is the default's
    rng = np.random.default_rng(11)
    n = 6000
    y = np.zeros(n)
    for w in FREQ:
        pole = np.exp((-0.005 * w + 1j * w * np.sqrt(1 - 0.005 ** 2)) * DT)
        y += w * scipy.signal.lfilter([0.0, 1.0], np.real(np.poly([pole, np.conj(pole)])), rng.standard_normal(n))
    y += 0.01 * np.std(y) * rng.standard_normal(n)
    prior = np.array([3.3, 20.9, 21.0, 55.0])
    base = methods.track("gated_pencil", y, DT, prior, window_from_estimates=False)
    tr = methods.track("gated_pencil", y, DT, prior, own_windows=True)
    assert base.converged.all(axis=1).mean() > 0.5
    np.testing.assert_array_equal(tr.extra["window_span_s"], base.extra["window_span_s"])
    np.testing.assert_array_equal(tr.frequencies, base.frequencies)


def test_ring_start_determines_a_stepped_fast_mode_from_the_first_ring_after_a_late_pulse():
    # the fast mode steps +8 % at 37 s, 15 s after the last pulse (its ring, decay time 1/(ζω) = 3.3 s, is
    # below the noise by then); a pulse 12 s after the step rings it again. The window (10.5 s, hop 1.05 s =
    # ten fast periods) ends 36, 87, 138 samples after that pulse: on the first the ring is ~5 fast periods
    # past the pulse detector's flags, and the window's fit of it fails the phase-std test over the whole
    # window; the ring alone passes it. The truth is the generator's frequency at each window's end.
    n, step_at, late = 3500, 1850, 2460
    prior = TWO * np.array([1.03, 0.97])
    for seed in (8, 9, 10):
        y, w = stepped_two_modes(n, np.array([100, 600, 1100, late]), step_at, 0.08, seed=seed, noise=3e-3)
        base = methods.track("gated_pencil", y, DT, prior)
        tr = methods.track("gated_pencil", y, DT, prior, ring_start=True)
        periods = []
        for track in (base, tr):
            e = track.extra["window_end_sample"]
            ok = (track.extra["window_converged"][:, 1] & (e > late)
                  & (np.abs(track.extra["window_frequencies"][:, 1] / w[e, 1] - 1) < 0.01))
            periods.append((e[np.argmax(ok)] - late) * DT * w[-1, 1] / (2 * np.pi) if ok.any() else np.inf)
        # before the late pulse the option changes nothing here (no ring holds the fast mode where the window's
        # own test fails)
        early = tr.t_s < late * DT
        np.testing.assert_array_equal(tr.frequencies[early], base.frequencies[early])
        assert periods[1] <= 20 < periods[0], (seed, periods)
    refused_in_one_line(prior, "ring_start")


def test_ring_search_finds_a_mode_on_a_short_ring_with_its_std():
    # a ring of 40 samples (about 8 periods of the 62 rad/s mode) over a slow mode that turns by 2.4 rad: the
    # 1-D search from a reference 10 % off lands on the truth within 3 of its own std, and that std is
    # the size a sinusoid's Cramér–Rao bound gives (σ √12 / (a √n T) within a factor 3)
    rng = np.random.default_rng(3)
    n, dt, a, sigma = 40, DT, 0.05, 2e-3
    t = np.arange(n) * dt
    truth = np.array([3.0, 62.0])
    y = (0.08 * np.cos(truth[0] * t + 0.4) + a * np.exp(-0.005 * truth[1] * t) * np.cos(truth[1] * t + 1.1)
         + sigma * rng.standard_normal(n))
    ref = np.array([3.1, 62.0 / 1.1])
    w, s = _gated_pencil.ring_search(y - y.mean(), dt, ref, np.full(2, 0.005), 1, np.log1p(0.3))
    crb = sigma * np.sqrt(12.0) / (a * np.sqrt(n) * n * dt)
    assert abs(w - truth[1]) <= 3 * s, (w, s)
    assert crb / 3 <= s <= 3 * crb, (s, crb)
