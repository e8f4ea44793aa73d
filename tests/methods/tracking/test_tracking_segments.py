"""The variable-projection fit over pulse-free segments (``methods.tracking._segments`` cut them,
``methods.pem.separable_fit`` fits them) against independent numbers: the exact poles of a noise-free record
restarted at pulses, pem's batch maximum-likelihood fit on a single free decay (the same least-squares problem with
one segment, solved by pem's own search), and the scatter of its estimates over noise draws (its reported std).
"""

import numpy as np
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
