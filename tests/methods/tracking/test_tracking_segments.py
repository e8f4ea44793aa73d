"""The variable-projection fit over pulse-free segments (``methods.tracking._segments`` cut them,
``methods.pem.separable_fit`` fits them) against independent numbers: the exact poles of a noise-free record
restarted at pulses, pem's batch maximum-likelihood fit on a single free decay (the same least-squares problem with
one segment, solved by pem's own search), and the scatter of its estimates over noise draws (its reported std).
"""

import numpy as np
import pytest
import scipy.signal
import scipy.stats
from test_tracking_gated_pencil import DT, FREQ, pulsed_decays

import methods
from methods import pem
from methods.tracking import _gated_pencil, _segments

ZETA = 0.005


def test_segments_split_at_flagged_samples_and_drop_short_runs():
    flags = np.zeros(100, dtype=bool)
    flags[[10, 11, 50, 95]] = True
    assert _segments.segments(flags, min_length=5) == [(0, 10), (12, 50), (51, 95)]
    assert _segments.segments(flags, min_length=38) == [(12, 50), (51, 95)]
    assert _segments.segments(flags, min_length=39) == [(51, 95)]


def test_noise_free_pulsed_record_gives_the_exact_poles():
    n = 512
    y = pulsed_decays(n, np.array([130, 340]), seed=5, zeta=ZETA, noise=0.0)
    flags = _gated_pencil.pulse_flags(y - y.mean(), ar_order=24, cut=4.0)
    runs = _segments.segments(flags, 20)
    assert len(runs) >= 3
    w, z, std = pem.separable_fit(y, DT, runs, FREQ * np.array([1.01, 0.995, 1.005, 0.99]), np.full(4, 0.01), 30)
    np.testing.assert_allclose(w, FREQ, rtol=1e-6)
    np.testing.assert_allclose(z, ZETA, rtol=1e-4)
    assert np.all(std < 1e-6 * FREQ)


def test_one_segment_is_pems_maximum_likelihood_fit():
    n = 400
    y = pulsed_decays(n, np.array([], dtype=int), seed=6, zeta=ZETA, noise=3e-3)
    est = methods.get("pem")(y, DT, FREQ * 1.01)
    w, _, std = pem.separable_fit(y, DT, [(0, n)], FREQ * 1.01, np.full(4, 0.01), 50)
    assert np.all(np.abs(w - est.frequencies) <= 0.02 * std), (w - est.frequencies, std)
    np.testing.assert_allclose(std, est.std, rtol=0.01)


def test_the_reported_std_is_the_scatter_over_noise_draws():
    n, draws = 512, 40
    clean = pulsed_decays(n, np.array([170, 330]), seed=7, zeta=ZETA, noise=0.0)
    runs = [(0, 170), (170, 330), (330, n)]
    rng = np.random.default_rng(8)
    fits = [pem.separable_fit(clean + 0.01 * rng.standard_normal(n), DT, runs, FREQ, np.full(4, ZETA), 30)
            for _ in range(draws)]
    w = np.array([f[0] for f in fits])
    std = np.array([f[2] for f in fits])
    ratio = w.std(axis=0, ddof=1) / std.mean(axis=0)
    assert np.all((ratio > 0.65) & (ratio < 1.5)), ratio
    assert np.all(np.abs(w.mean(axis=0) - FREQ) < 3 * std.mean(axis=0) / np.sqrt(draws) + 1e-9)


def _kicked_decay(n, kick, rng, noise, kick_size):
    """Six modes at Δt = 0.1 s (0.8–5.5 rad/s): a free decay whose amplitudes change at sample ``kick`` by
    ``kick_size`` per coefficient, with a feed-through spike at the kick; white noise of std ``noise``."""
    w, z, dt = np.array([0.8, 1.3, 2.0, 2.9, 4.1, 5.5]), np.full(6, ZETA), 0.1
    c = rng.normal(size=13) * 0.01
    y = _segments.free_decay_basis(n, dt, w, z) @ c
    if kick is not None:
        c2 = c + rng.choice([-1.0, 1.0], size=13) * kick_size
        y[kick] += 4 * noise
        y[kick + 1:] = _segments.free_decay_basis(n - kick - 1, dt, w, z) @ c2
    return y + noise * rng.standard_normal(n), w, z, dt


def test_the_kick_statistic_is_the_direct_chow_f_test():
    # the F statistic from the cumulative sums against a direct least-squares fit of both models: H₀ the free
    # decay with its first-order pole corrections t·e^{st} (p = 4m + 1 columns), H₁(k) also the amplitudes and
    # offset changed after k and a free sample k (q = 2m + 2 more)
    rng = np.random.default_rng(11)
    y, w, z, dt = _kicked_decay(300, 170, rng, 3e-3, 3e-3)
    k, F, q, dof = _segments.kick_statistic(y, dt, w, z, min_length=26)
    Z = _segments.free_decay_basis(y.size, dt, w, z, pole_corrections=True)
    X = Z[:, np.r_[0:12, 24]]
    p = Z.shape[1]
    assert p == 4 * w.size + 1 and q == 2 * w.size + 2
    rss0 = np.sum((y - Z @ np.linalg.lstsq(Z, y, rcond=None)[0]) ** 2)
    for kk in (40, 170, 250):
        spike = np.zeros((y.size, 1))
        spike[kk] = 1.0
        alt = np.hstack([Z, X * (np.arange(y.size) > kk)[:, None], spike])
        rss1 = np.sum((y - alt @ np.linalg.lstsq(alt, y, rcond=None)[0]) ** 2)
        direct = ((rss0 - rss1) / q) / (rss1 / (y.size - p - q))
        np.testing.assert_allclose(F[k == kk][0], direct, rtol=1e-5)
    assert dof == y.size - p - q and k[0] == 26 and k[-1] == y.size - 27
    assert k[np.argmax(F)] == 170


def test_a_kick_at_the_noise_level_is_found_at_its_sample():
    # a kick of the size that escapes the AR pulse detector at Δt = 0.1 s: amplitudes changed by the noise std
    rng = np.random.default_rng(12)
    hits = 0
    for _ in range(20):
        y, w, z, dt = _kicked_decay(387, 200, rng, 3e-3, 3e-3)
        runs, kicks = _segments.split_kicks(y, dt, [(0, 387)], w, z, 26, 0.01, 3)
        hits += kicks == [200] and runs == [(0, 200), (201, 387)]
    assert hits >= 16


def test_a_clean_free_decay_is_not_split_at_the_stated_level():
    # Bonferroni over the splits: at most the level's share of noise draws splits a clean decay
    rng = np.random.default_rng(13)
    split = 0
    for _ in range(200):
        y, w, z, dt = _kicked_decay(387, None, rng, 3e-3, 0.0)
        split += bool(_segments.split_kicks(y, dt, [(0, 387)], w, z, 26, 0.05, 3)[1])
    assert split <= 0.05 * 200


def test_a_pole_error_is_not_read_as_a_kick():
    # a clean decay tested with poles 0.3 % off (a window's poles a while after a step): the misfit grows along
    # the run; the pole-correction columns take it, so the run is split at about the stated level — and
    # without them (Chow's test of the amplitudes alone) the same runs are split as if kicked
    rng = np.random.default_rng(14)
    records = [_kicked_decay(387, None, rng, 3e-3, 0.0) for _ in range(40)]
    wrong = np.array([1.003, 0.997, 1.003, 0.997, 1.003, 0.997])

    def splits(corrections):
        # the first round's decision (split_kicks returns a run whose pieces reject again whole, as a force)
        return sum(_rejects(y, dt, w * wrong, z, 26, 0.05, corrections) for y, w, z, dt in records)

    with_corrections, without = splits(True), splits(False)
    assert with_corrections <= 4 and without >= 30, (with_corrections, without)


def _rejects(y, dt, w, z, min_length, level, corrections=True) -> bool:
    found = _segments.kick_statistic(y, dt, w, z, min_length, pole_corrections=corrections)
    if found is None:
        return False
    k, F, dfn, dof = found
    return bool(F.max() > scipy.stats.f.isf(level / k.size, dfn, dof))


def test_a_response_to_a_continuing_force_is_not_split_into_kicks():
    # two modes driven by a white force (each a resonator filtering white noise, scipy.signal.lfilter): every
    # sample is a kick, the test rejects the free decay at once and would go on splitting every piece; the
    # run is returned whole, with no kick, at every depth
    dt, w, z = 0.02, np.array([3.2, 20.0]), np.array([0.005, 0.005])
    rng = np.random.default_rng(3)
    y = np.zeros(512)
    for wi, zi in zip(w, z, strict=True):
        p = np.exp((-zi * wi + 1j * wi * np.sqrt(1 - zi ** 2)) * dt)
        y += scipy.signal.lfilter([1.0], np.poly([p, np.conj(p)]).real, rng.standard_normal(y.size))
    y += 0.01 * np.std(y) * rng.standard_normal(y.size)
    assert _rejects(y, dt, w, z, 20, 0.01)
    for rounds in (1, 2, 3):
        assert _segments.split_kicks(y, dt, [(0, y.size)], w, z, 20, 0.01, rounds) == ([(0, y.size)], [])


def test_the_kick_test_options_are_checked():
    prior = np.array([3.2, 20.0])
    for bad in ({"split_level": 0.0}, {"split_level": 1.5}, {"split_rounds": 0}, {"split_kicks": "yes"}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            methods.check_track_options("gated_pencil", prior, 0.02, bad)
