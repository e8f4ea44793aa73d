"""Frequency schedules: drift, fuel (from the plant's mass), step, slosh, and the refusals."""

import dataclasses

import numpy as np
import pytest

from experiments.simulate.plant import Plant, PlantConfig, build_plant
from experiments.simulate.schedules import ScheduleConfig, events, frequencies

T = np.arange(3000) * 0.02
NOMINAL = np.array([3.23, 20.24, 22.00, 56.67])


def test_constant_schedule_is_the_calibrated_plant():
    w = frequencies(ScheduleConfig(), PlantConfig(), T, dt_s=0.02)
    np.testing.assert_allclose(w, np.tile(NOMINAL, (T.size, 1)), rtol=1e-9)


def test_drift_reaches_its_per_mode_scaling_linearly():
    w = frequencies(ScheduleConfig(drift=[0.3, 0.2, 0.2, 0.1]), PlantConfig(), T, dt_s=0.02)
    np.testing.assert_allclose(w[-1], NOMINAL * [1.3, 1.2, 1.2, 1.1], rtol=1e-9)
    np.testing.assert_allclose(w[T.size // 2 - 1] / NOMINAL - 1, [0.15, 0.1, 0.1, 0.05], atol=2e-4)


def test_fuel_schedule_is_the_plants_eigenfrequencies_at_the_burnt_mass():
    cfg = PlantConfig()
    w = frequencies(ScheduleConfig(propellant_kg=135.0), cfg, T, dt_s=0.02)
    half = Plant(dataclasses.replace(cfg, body_mass_kg=135.0, calibrate=False),
                 build_plant(cfg).cantilever_freq_rad_s).freq_rad_s
    np.testing.assert_allclose(w[-1], half, rtol=1e-9)
    # a lighter body moves more with the beam: every frequency rises, mode 1 by 2.6 % (PHYSICS.md coupling)
    assert np.all(np.diff(w[:, 0]) >= 0) and w[-1, 0] / w[0, 0] - 1 == pytest.approx(0.0255, abs=1e-3)
    k = int(round(0.37 * (T.size - 1)))
    mid = Plant(dataclasses.replace(cfg, body_mass_kg=270.0 - 135.0 * T[k] / T[-1], calibrate=False),
                build_plant(cfg).cantilever_freq_rad_s).freq_rad_s
    np.testing.assert_allclose(w[k], mid, rtol=1e-7)             # the spline between exact masses


def test_step_changes_chosen_modes_at_one_instant():
    w = frequencies(ScheduleConfig(step=[0.0, 0.0, 0.05, -0.05], step_time_s=30.0), PlantConfig(), T, dt_s=0.02)
    k = int(np.searchsorted(T, 30.0))
    np.testing.assert_allclose(w[k - 1], NOMINAL)
    np.testing.assert_allclose(w[k], NOMINAL * [1, 1, 1.05, 0.95])
    assert events(ScheduleConfig(step=0.05, step_time_s=30.0), T)["step_time_s"] == 30.0


def test_slosh_modulates_at_the_slosh_frequency():
    w = frequencies(ScheduleConfig(slosh=0.03, slosh_hz=0.1), PlantConfig(), T, dt_s=0.02)
    rel = w[:, 0] / NOMINAL[0] - 1
    assert rel.max() == pytest.approx(0.03, abs=1e-4) and rel.min() == pytest.approx(-0.03, abs=1e-4)
    spectrum = np.abs(np.fft.rfft(rel))
    assert np.fft.rfftfreq(T.size, 0.02)[np.argmax(spectrum)] == pytest.approx(0.1, abs=1 / 60)


def test_schedule_crossing_two_modes_is_refused():
    with pytest.raises(ValueError, match="crosses modes 2 and 3"):
        frequencies(ScheduleConfig(drift=[0.0, 0.2, 0.05, 0.0]), PlantConfig(), T, dt_s=0.02)


def test_schedule_above_nyquist_is_refused():
    with pytest.raises(ValueError, match="Nyquist"):
        frequencies(ScheduleConfig(drift=[0, 0, 0, 1.0]), PlantConfig(), T, dt_s=0.03)


def test_per_mode_list_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match="schedule.step"):
        frequencies(ScheduleConfig(step=[0.1, 0.2]), PlantConfig(), T, dt_s=0.02)
