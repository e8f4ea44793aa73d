"""``gated_pencil``'s Hankel rows under pulses (``shrink_rows``, :func:`methods.tracking._gated_pencil.widest_rows`)
against records built independently: free decays restarted by pulses, and a white force.

A prior whose two modes lie 1.5 % apart asks for a window of 20 periods of the slowest mode, and the rows follow
as W/8 = 2.5 periods; pulses 2.6 periods apart then leave too few Hankel columns of that length for the pencil,
and the window determines no mode. With ``shrink_rows`` (on by default) the rows shrink to the pulse-free
runs. Under a white
force (no isolated pulses) the rule must not fire. A prior pair closer than the capped window resolves
(``capped_rows``, on by default): the rows start at the five-period window's, under pulses too close for
``shrink_rows``.
"""

import numpy as np
import scipy.signal

import methods
from methods.tracking import _gated_pencil

DT = 0.02
FREQ = np.array([3.23, 20.24, 22.0, 56.67])
NEAR_DOUBLE = np.array([3.3, 20.7, 21.0, 55.0])            # modes 2 and 3 of the prior 1.5 % apart
ZETA = 0.005


def decays(n, pulses, rng, noise):
    """The four modes, each restarted at every pulse (sample indices ``pulses``) with a random amplitude and
    phase, between pulses an exact free decay; + white noise."""
    t = np.arange(n) * DT
    y = np.zeros(n)
    for a, b in zip(np.concatenate(([0], pulses)), np.concatenate((pulses, [n])), strict=True):
        tau = t[a:b] - t[a]
        for w in FREQ:
            amp, phase = rng.uniform(0.02, 0.1), rng.uniform(0, 2 * np.pi)
            y[a:b] += amp * np.exp(-ZETA * w * tau) * np.cos(w * np.sqrt(1 - ZETA ** 2) * tau + phase)
    return y + noise * rng.standard_normal(n)


def pulsed(n, every, seed, noise=1e-4):
    """:func:`decays` with a pulse every ``every`` samples."""
    return decays(n, np.arange(150, n, every), np.random.default_rng(seed), noise)


def white_forced(n, seed):
    """The four modes driven by a Gaussian white force (each an exact discrete resonator), + white noise."""
    rng = np.random.default_rng(seed)
    y = np.zeros(n)
    for w in FREQ:
        r = np.exp(-ZETA * w * DT)
        y += scipy.signal.lfilter([1.0], [1.0, -2 * r * np.cos(w * DT), r * r], rng.standard_normal(n))
    return y + 0.01 * np.std(y) * rng.standard_normal(n)


def test_shrunk_rows_track_a_near_double_prior_under_pulses_the_default_leaves_undetermined():
    # window 20 · 2π/3.3 = 38 s (1904 samples), rows 238; a pulse every 5 s (250 samples, 2.6 slowest periods)
    # leaves 12 columns of 238 rows per run, ~90 in the window, under the 2L = 476 the pencil needs
    n = 6000
    for seed in (1, 2):
        y = pulsed(n, 250, seed)
        base = methods.track("gated_pencil", y, DT, NEAR_DOUBLE, shrink_rows=False, capped_rows=False)
        tr = methods.track("gated_pencil", y, DT, NEAR_DOUBLE, capped_rows=False)
        assert not base.extra["window_converged"].any() and not base.converged.any(), seed
        late = tr.t_s > 60.0
        err = np.abs(tr.frequencies[late] / FREQ - 1)
        assert tr.converged[late].all(), (seed, tr.converged[late].mean(axis=0))
        assert np.all(err < 0.001), (seed, err.max(axis=0))
    # causal: a window's rows follow its own flags; the record changed after sample 4000 leaves the earlier
    # estimates as they were
    changed = y.copy()
    changed[4001:] = pulsed(n - 4001, 170, seed=9)
    other = methods.track("gated_pencil", changed, DT, NEAR_DOUBLE, capped_rows=False)
    early = tr.t_s <= 4000 * DT
    np.testing.assert_array_equal(other.frequencies[early], tr.frequencies[early])
    np.testing.assert_array_equal(other.std[early], tr.std[early])
    assert not np.array_equal(other.frequencies[~early], tr.frequencies[~early], equal_nan=True)


def test_shrink_rows_does_not_fire_under_a_white_force():
    n = 6000
    for seed in (1, 2):
        y = white_forced(n, seed)
        tr = methods.track("gated_pencil", y, DT, NEAR_DOUBLE)
        # neither rows rule fires (capped_rows: no pulse flagged), also with the prior's pair 0.3 % apart
        for prior, off in ((NEAR_DOUBLE, {"shrink_rows": False}), (NEAR_DOUBLE, {"capped_rows": False}),
                           (np.array([3.3, 20.9, 20.96, 55.0]), {"shrink_rows": False, "capped_rows": False})):
            base = methods.track("gated_pencil", y, DT, prior, **off)
            got = tr if prior is NEAR_DOUBLE else methods.track("gated_pencil", y, DT, prior)
            np.testing.assert_array_equal(got.frequencies, base.frequencies)
            np.testing.assert_array_equal(got.converged, base.converged)


def test_the_rows_shrink_for_isolated_pulses_only_never_under_the_floor():
    n, rows, p = 1904, 238, 16
    floor, min_run = _gated_pencil.shrink_sizes(NEAR_DOUBLE, DT, 12)
    # the floor: the five-period window's rows, 5/8 of the slowest period (at least the pencil's order); the
    # mean run that makes the pulses isolated: two slowest periods (the shortest window after a restart)
    assert floor == round(5 / 8 * 2 * np.pi / 3.3 / DT) and abs(min_run - 2 * 2 * np.pi / 3.3 / DT) < 1e-9
    assert _gated_pencil.shrink_sizes(NEAR_DOUBLE, 0.5, 12)[0] == 12

    def free(flags, L):
        return _gated_pencil._free_columns(np.concatenate(([0], np.cumsum(flags))), n, L)

    def shrunk(flags, pulses=None):
        return _gated_pencil.shrunk_rows(flags, flags if pulses is None else pulses, rows, floor, min_run, p)

    # pulses every 250 samples (2.6 slowest periods), each flagged as three samples with a gap (the AR
    # residual crossing zero): the most rows that leave 2L pulse-free columns
    pulses = np.zeros(n, dtype=bool)
    for gap in (0, 1, 4):
        pulses[np.arange(100, n - 4, 250) + gap] = True
    assert free(pulses, rows) < 2 * rows
    got = shrunk(pulses)
    assert floor <= got < rows and free(pulses, got) >= 2 * got and free(pulses, got + 1) < 2 * (got + 1), got
    # pulses every 150 samples (1.6 slowest periods), runs too short to trust: the rule's rows
    close = np.zeros(n, dtype=bool)
    close[np.arange(100, n, 150)] = True
    assert free(close, rows) < 2 * rows and free(close, floor) >= 2 * floor and shrunk(close) == rows
    # the same shortage made by the kick test's splits (about a slowest period apart, as under a white force)
    # while the detector flags nothing: the rule's rows
    kicks = np.zeros(n, dtype=bool)
    kicks[np.arange(60, n, 100)] = True
    assert free(kicks, rows) < 2 * rows <= free(np.zeros(n, dtype=bool), rows)
    assert shrunk(kicks, np.zeros(n, dtype=bool)) == rows
    # pulses flagged everywhere, a fraction of a slowest period apart on average, with long clean stretches
    # between their bursts where the floor would find columns: the rule's rows
    rng = np.random.default_rng(0)
    scattered = np.zeros(n, dtype=bool)
    at = np.cumsum(rng.integers(20, 60, size=n // 20))
    scattered[at[at < n]] = True
    scattered[600:1000] = False
    scattered[1300:1700] = False
    assert free(scattered, floor) >= 2 * floor
    assert shrunk(scattered) == rows
    # a window with enough columns: untouched
    few = np.zeros(n, dtype=bool)
    few[[500, 1500]] = True
    assert shrunk(few) == rows


def bernoulli_pulsed(n, mean, seed, noise=1e-4):
    """:func:`decays` with the pulses at random times (a Bernoulli draw per sample, mean spacing ``mean``
    samples), as the benchmarks' thrusters."""
    rng = np.random.default_rng(seed)
    return decays(n, np.flatnonzero(rng.random(n) < 1.0 / mean), rng, noise)


def test_capped_rows_track_a_prior_pair_the_capped_window_cannot_resolve():
    # modes 2 and 3 of the prior 0.3 % apart: two beats (210 s) over the cap, 20 slowest periods (38 s), so
    # the rows were W/8 = 2.5 slowest periods; pulses at random times 1.7 slowest periods apart on average
    # (the mean run under the two periods shrink_rows needs) leave too few columns of that length
    prior = np.array([3.3, 20.9, 20.96, 55.0])
    assert _gated_pencil.pair_capped(prior) and _gated_pencil.pair_capped(NEAR_DOUBLE)
    assert not _gated_pencil.pair_capped(np.array([3.3, 20.5, 21.0, 55.0]))       # two beats 25 s: not capped
    assert not _gated_pencil.pair_capped(np.array([3.3]))
    n = 6000
    for seed in (2, 7):
        y = bernoulli_pulsed(n, 160, seed)
        base = methods.track("gated_pencil", y, DT, prior, capped_rows=False)
        tr = methods.track("gated_pencil", y, DT, prior)
        assert not base.extra["window_converged"].all(axis=1).any(), seed
        assert tr.extra["window_converged"].all(axis=1).mean() > 0.8, seed
        late = tr.t_s > 60.0
        err = np.abs(tr.frequencies[late] / FREQ - 1)
        assert tr.converged[late].all(), (seed, tr.converged[late].mean(axis=0))
        assert np.all(err < 0.001), (seed, err.max(axis=0))
    # a window the user gives keeps the rule's rows (W/8): the option is silent
    given = methods.track("gated_pencil", y, DT, prior, window_s=38.0)
    given_off = methods.track("gated_pencil", y, DT, prior, window_s=38.0, capped_rows=False)
    np.testing.assert_array_equal(given.frequencies, given_off.frequencies)
    # causal: the record changed after sample 4000 leaves the earlier estimates as they were
    changed = y.copy()
    changed[4001:] = bernoulli_pulsed(n - 4001, 160, seed=9)
    other = methods.track("gated_pencil", changed, DT, prior)
    early = tr.t_s <= 4000 * DT
    np.testing.assert_array_equal(other.frequencies[early], tr.frequencies[early])
    np.testing.assert_array_equal(other.std[early], tr.std[early])
    assert not np.array_equal(other.frequencies[~early], tr.frequencies[~early], equal_nan=True)


def test_shrink_rows_is_refused_in_one_line_unless_a_boolean():
    import pytest
    for key in ("shrink_rows", "capped_rows", "capped_either"):
        with pytest.raises(ValueError, match=f"{key} = 'yes'") as err:
            methods.check_track_options("gated_pencil", NEAR_DOUBLE, DT, {key: "yes"})
        assert "\n" not in str(err.value)


def stepped(n, step, mean, seed, before, after, noise=1e-4):
    """Free decays of the modes ``before`` up to sample ``step`` and ``after`` from it, restarted at the step
    and at pulses at random times (mean spacing ``mean`` samples), + white noise."""
    rng = np.random.default_rng(seed)
    pulses = np.union1d(np.flatnonzero(rng.random(n) < 1.0 / mean), [step])
    t = np.arange(n) * DT
    y = np.zeros(n)
    for a, b in zip(np.concatenate(([0], pulses)), np.concatenate((pulses, [n])), strict=True):
        tau = t[a:b] - t[a]
        for w in (before if a < step else after):
            amp, phase = rng.uniform(0.02, 0.1), rng.uniform(0, 2 * np.pi)
            y[a:b] += amp * np.exp(-ZETA * w * tau) * np.cos(w * np.sqrt(1 - ZETA ** 2) * tau + phase)
    return y + noise * rng.standard_normal(n)


def test_capped_either_shortens_the_window_when_one_mode_of_a_capped_prior_pair_is_found():
    # the prior's modes 2 and 3 0.3 % apart (window at the cap, 20 slowest periods = 38 s); the record has one
    # mode there: the other is never determined, so "every mode determined once" never holds and the window
    # stays at the cap; with capped_either the pair counts once one of its modes is, the estimates' closest
    # pair is 17 rad/s, and the window is five slowest periods (5 · 2π/3.3 = 9.5 s)
    prior = np.array([3.3, 20.9, 20.96, 55.0])
    before = np.array([3.23, 20.24, 56.67])
    after = before * np.array([1.05, 0.96, 1.04])
    det = np.array([True, True, False, True])
    np.testing.assert_array_equal(_gated_pencil.capped_determined(prior, det), [True, True, True, True])
    np.testing.assert_array_equal(_gated_pencil.capped_determined(prior, [True, False, False, True]),
                                  [True, False, False, True])
    wide = np.array([3.3, 20.5, 21.0, 55.0])                                       # not capped: unchanged
    np.testing.assert_array_equal(_gated_pencil.capped_determined(wide, det), det)
    ref = np.array([3.23, 20.24, 20.96, 56.67])
    cap = _gated_pencil.estimates_window_s(prior, ref, det)
    assert abs(cap - 20 * 2 * np.pi / 3.3) < 0.05, cap
    assert abs(_gated_pencil.estimates_window_s(prior, ref, det, True) - 5 * 2 * np.pi / 3.3) < 0.05
    n, step = 7000, 3500
    for seed in (1, 7):
        y = stepped(n, step, 160, seed, before, after)
        t_step = step * DT
        reconv = {}
        for opt in (False, True):
            tr = methods.track("gated_pencil", y, DT, prior, capped_either=opt)
            k = np.round(tr.t_s / DT).astype(int)
            truth = np.where((k >= step)[:, None], after, before)
            err = np.abs(tr.frequencies[:, [0, 1, 3]] / truth - 1).max(axis=1)
            bad = (tr.t_s >= t_step) & ~(err <= 0.005)
            assert not bad[-1], (seed, opt)
            reconv[opt] = tr.t_s[np.flatnonzero(bad)[-1] + 1] - t_step
            spans = tr.extra["window_span_s"][tr.t_s > 45.0]
            assert (spans.max() < 10.0) if opt else (spans.min() > 37.0), (seed, opt, spans.min(), spans.max())
        assert reconv[True] < 15.0 < 25.0 < reconv[False], (seed, reconv)
    # causal: the record changed after sample 5000 leaves the earlier estimates as they were
    changed = y.copy()
    changed[5001:] = stepped(n - 5001, 10, 160, 9, after, after)
    one = methods.track("gated_pencil", y, DT, prior, capped_either=True)
    other = methods.track("gated_pencil", changed, DT, prior, capped_either=True)
    early = one.t_s <= 5000 * DT
    np.testing.assert_array_equal(other.frequencies[early], one.frequencies[early])
    np.testing.assert_array_equal(other.std[early], one.std[early])
    assert not np.array_equal(other.frequencies[~early], one.frequencies[~early], equal_nan=True)
