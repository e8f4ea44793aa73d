"""The stabilisation diagram counts the modes a record holds, and no more."""

import numpy as np
import pytest

from methods.peers.stabilisation import stabilisation_diagram

DT = 1e-3


def decay(modes, n=3000, noise=0.01, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    y = sum(a * np.exp(-z * w * t) * np.cos(w * np.sqrt(1 - z**2) * t + 0.4) for w, z, a in modes)
    return y + noise * rng.standard_normal(n)


MODES = [(2 * np.pi * 23.0, 0.01, 1.0), (2 * np.pi * 61.0, 0.005, 0.3), (2 * np.pi * 140.0, 0.003, 0.6)]


def test_three_decaying_modes_are_three_modes_near_their_frequencies():
    d = stabilisation_diagram(decay(MODES), DT)
    assert d.modes_rad_s.size == 3
    assert d.modes_rad_s == pytest.approx([w for w, _, _ in MODES], rel=1e-3)
    assert d.modes_damping == pytest.approx([z for _, z, _ in MODES], abs=1e-3)
    assert d.stable.any() and d.order.max() <= 40


def test_white_noise_holds_no_mode():
    d = stabilisation_diagram(decay([], noise=1.0), DT)
    assert d.modes_rad_s.size == 0


def test_n_modes_keeps_the_most_energetic_and_a_band_narrows_the_search():
    d = stabilisation_diagram(decay(MODES), DT, n_modes=2)
    assert d.modes_rad_s == pytest.approx([MODES[0][0], MODES[2][0]], rel=1e-3)   # amplitudes 1.0 and 0.6
    d = stabilisation_diagram(decay(MODES), DT, band_rad_s=(2 * np.pi * 40, 2 * np.pi * 100))
    assert d.modes_rad_s == pytest.approx([MODES[1][0]], rel=1e-3)
