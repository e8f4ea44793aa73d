"""The mismatch axes: records the methods' model does not describe (experiments/simulate/mismatch.py)."""

import numpy as np
import pytest

from experiments.simulate import mismatch, scenarios
from experiments.simulate.datasets import UG, DatasetConfig, ScenarioConfig, make_cell
from experiments.simulate.plant import build_plant


def test_ar1_noise_has_the_variance_and_lag_one_correlation_asked_for():
    x = mismatch.ar1_noise(np.random.default_rng(1), 40_000, 2.0, 0.8)
    assert np.std(x) == pytest.approx(2.0, rel=0.05)
    assert np.corrcoef(x[1:], x[:-1])[0, 1] == pytest.approx(0.8, abs=0.02)


def test_duffing_without_the_cubic_term_is_the_plant_modal_sum():
    plant = build_plant()
    truth = plant.truth()
    t = 0.02 * np.arange(512)
    y = mismatch.duffing_modes(t, truth["freq_rad_s"], truth["damping"], truth["amplitude_m_s2"],
                               truth["phase_rad"], 0.0)
    np.testing.assert_allclose(y, plant.modal_sum(t), atol=1e-6 * truth["amplitude_m_s2"].max())


def test_hardening_duffing_oscillates_at_its_backbone_frequency():
    """δ = 0.05, undamped: the period at amplitude 1 is 2π/(ω√(1 + 2δ)) (first order in δ)."""
    w, delta = 10.0, 0.05
    t = np.linspace(0.0, 20.0, 200_001)
    x = mismatch.duffing_modes(t, [w], [0.0], [1.0], [0.0], delta)
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    period = np.mean(np.diff(t[up]))
    assert 2 * np.pi / period == pytest.approx(mismatch.backbone_rad_s(w, 1.0, delta), rel=2e-3)
    assert 2 * np.pi / period > w * (1 + 0.8 * delta)           # and it did harden


def test_record_frequency_is_the_backbone_averaged_over_the_envelope():
    w, z, n, dt = np.array([3.0, 20.0]), np.array([0.0, 0.01]), 500, 0.02
    # linear structure: the eigenfrequency; undamped: the backbone at the starting amplitude
    np.testing.assert_allclose(mismatch.record_frequency_rad_s(w, z, 0.0, n, dt), w, rtol=1e-15)
    assert mismatch.record_frequency_rad_s(w, z, 0.01, n, dt)[0] == pytest.approx(
        mismatch.backbone_rad_s(3.0, 1.0, 0.01), rel=1e-12)
    # small δ: ω(1 + δ Σq²ᵏ/Σqᵏ), q = e^{−2ζωΔt} (geometric sums; the backbone to first order in δ)
    delta, q = 1e-4, np.exp(-2 * 0.01 * 20.0 * dt)
    first_order = 20.0 * (1 + delta * (1 - q ** (2 * n)) / (1 - q ** 2) * (1 - q) / (1 - q ** n))
    assert mismatch.record_frequency_rad_s(w, z, delta, n, dt)[1] == pytest.approx(first_order, rel=1e-8)


def _cell(**axes):
    return make_cell(DatasetConfig(noise_ug=1000, n_samples=256, replicates=3, seed=4,
                                   scenario=ScenarioConfig(**axes)))


def test_sensor_axes_clip_and_round_the_record():
    plain, clipped, rounded = _cell(), _cell(saturation=0.5), _cell(quantisation=3)
    limit = 0.5 * np.abs(plain["accel_clean_m_s2"]).max()
    assert np.abs(clipped["accel_m_s2"]).max() == pytest.approx(limit)
    step = 3 * 1000 * UG
    # each record on one grid of that step, offset by its own fraction of a step (a converter's zero)
    frac = np.mod(rounded["accel_m_s2"] / step, 1.0)
    offset = frac[:, :1]
    np.testing.assert_allclose(np.mod(frac - offset + 0.5, 1.0) - 0.5, 0, atol=1e-9)
    assert np.unique(np.round(offset, 6)).size == offset.size > 1
    # the same noise draws as the plain cell (common random numbers), and the truth is the plant's
    np.testing.assert_allclose(np.abs(rounded["accel_m_s2"] - plain["accel_m_s2"]), 0, atol=step / 2 + 1e-12)
    np.testing.assert_array_equal(clipped["truth_freq_rad_s"], plain["truth_freq_rad_s"])


def test_unmodelled_mode_adds_a_line_at_the_beams_next_mode():
    plain, extra = _cell(), _cell(unmodelled_mode=0.5)
    d = extra["accel_m_s2"][0] - plain["accel_m_s2"][0]
    spectrum = np.abs(np.fft.rfft(d))
    w = 2 * np.pi * np.fft.rfftfreq(d.size, 0.02)
    assert w[np.argmax(spectrum)] == pytest.approx(mismatch.UNMODELLED_RAD_S, abs=2 * np.pi / (d.size * 0.02))


def test_mismatch_axes_name_the_cell_and_bad_values_are_refused():
    assert scenarios.cell_name(1000, 512, {"ar1": 0.5}) == "noise1000ug_n512_ar0.5"
    with pytest.raises(ValueError, match="ar1 = 1.5 must be inside"):
        _cell(ar1=1.5)
    with pytest.raises(ValueError, match="saturation = 0"):
        mismatch.check_axes({"saturation": 0})
