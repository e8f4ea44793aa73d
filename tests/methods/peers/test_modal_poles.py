"""The shared mode picker (methods/peers/_mode_picker.py) on hand-made pole sets with known answers.

A record made of known damped sinusoids and poles given by hand: the picker must keep oscillatory, not
growing, below-Nyquist poles, fold conjugate pairs, rank by least-squares energy (a weak noise pole loses
to a real mode), assign to the prior by log-frequency, and say NaN / not found when too few remain.
"""

import numpy as np

from methods.peers._mode_picker import continuous_poles, energies, physical, pick_modes

DT = 0.02
T = np.arange(256) * DT


def pole(w, zeta=0.005):
    return w * (-zeta + 1j * np.sqrt(1 - zeta**2))


def record(poles, amps):
    return sum(a * np.exp(p.real * T) * np.cos(p.imag * T) for p, a in zip(poles, amps, strict=True))


MODES = [pole(3.23), pole(20.24), pole(22.0), pole(56.67)]
Y = record(MODES, [1.0, 2.0, 2.0, 3.0])
PRIOR = [3.8, 16.0, 26.0, 46.0]


def test_exact_poles_are_assigned_in_prior_order():
    got = pick_modes(MODES[::-1], Y, DT, PRIOR)
    np.testing.assert_allclose(got.frequencies, [3.23, 20.24, 22.0, 56.67], rtol=1e-12)
    np.testing.assert_allclose(got.damping, 0.005, rtol=1e-9)
    assert got.found.all()


def test_conjugates_fold_onto_one_mode():
    both = MODES + [np.conj(p) for p in MODES]
    assert physical(both, DT).size == 4
    got = pick_modes(both, Y, DT, PRIOR)
    np.testing.assert_allclose(got.frequencies, [3.23, 20.24, 22.0, 56.67], rtol=1e-12)


def test_a_spurious_weak_pole_loses_to_the_modes():
    """A pole at 18 rad/s (in the band of prior 16) that carries no signal: the energies rank it last."""
    spurious = pole(18.0, 0.05)
    e = energies(MODES + [spurious], Y, DT)
    assert e[-1] < 1e-12 * e[:4].min()
    got = pick_modes(MODES + [spurious], Y, DT, PRIOR)
    np.testing.assert_allclose(got.frequencies, [3.23, 20.24, 22.0, 56.67], rtol=1e-12)


def test_growing_overdamped_real_and_above_nyquist_poles_are_not_physical():
    nyquist = np.pi / DT
    growing = pole(20.0, -0.2)
    overdamped = pole(20.0, 0.5)
    real = -1.0 + 0j
    offset = 0j
    above = pole(1.2 * nyquist, 0.01)
    assert physical([growing, overdamped, real, offset, above], DT).size == 0
    assert physical([pole(20.0, -0.01)], DT).size == 1      # within the tolerance for ζ ≈ 0.005 modes


def test_discrete_poles_convert_and_the_offset_pole_is_dropped():
    z = np.exp(np.array(MODES + [0j]) * DT)                  # z = 1: the sensor offset
    s = continuous_poles(np.r_[z, np.conj(z)], DT)
    got = pick_modes(s, Y + 0.3, DT, PRIOR)
    np.testing.assert_allclose(got.frequencies, [3.23, 20.24, 22.0, 56.67], rtol=1e-9)


def test_too_few_physical_poles_leave_nan_and_not_found():
    got = pick_modes([MODES[0], MODES[3], pole(30.0, -0.3)], Y, DT, PRIOR)
    np.testing.assert_allclose(got.frequencies[[0, 3]], [3.23, 56.67], rtol=1e-12)
    assert np.isnan(got.frequencies[[1, 2]]).all()
    assert got.found.tolist() == [True, False, False, True]
    assert "too few physical poles" in got.message


def test_a_pole_outside_every_band_is_no_match():
    """A strong pole at 100 rad/s is more than 1.5× away from every prior: not assigned."""
    y = record([pole(100.0)], [5.0])
    got = pick_modes([pole(100.0)], y, DT, PRIOR)
    assert not got.found.any()


def test_only_the_m_most_energetic_are_assigned():
    """Two poles near prior 46: the strong one (the mode) wins over a weaker one close to the prior."""
    weak = pole(47.0, 0.01)
    y = Y + record([weak], [0.05])
    got = pick_modes(MODES + [weak], y, DT, PRIOR)
    np.testing.assert_allclose(got.frequencies[3], 56.67, rtol=1e-12)
