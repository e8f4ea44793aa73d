"""Tracking cells: the records, the stored truth, seeding, refusals."""

import numpy as np
import pytest

from experiments.io import read_npz
from experiments.simulate.schedules import ScheduleConfig
from experiments.simulate.tracking_data import (
    ExcitationConfig,
    TrackingCellConfig,
    cell_name,
    inputs,
    make_cell,
    write_cell,
)

UG = 9.80665e-6


def small(**kw):
    base = dict(schedule=ScheduleConfig(step=[0, 0, 0.05, 0.0], step_time_s=4.0),
                excitation=ExcitationConfig(thruster_torque_n_m=100.0, thruster_period_s=2.0), noise_ug=100.0,
                duration_s=8.0, replicates=2)
    base.update(kw)
    return TrackingCellConfig(**base)


def test_cell_stores_the_schedule_as_truth_and_noise_of_the_stated_level(tmp_path):
    cfg = small(replicates=3)
    write_cell(cfg, tmp_path / "c.npz")
    c = read_npz(tmp_path / "c.npz")
    n = 400
    assert c["accel_m_s2"].shape == (3, n) and c["truth_freq_rad_s"].shape == (n, 4)
    assert c["truth_freq_rad_s"][-1, 2] == pytest.approx(22.0 * 1.05)
    assert float(c["step_time_s"]) == 4.0
    resid = c["accel_m_s2"] - c["accel_clean_m_s2"]
    assert resid.std() == pytest.approx(100 * UG, rel=0.1)
    assert c["pcrb_std_rad_s"].shape == (3, n, 4) and np.all(np.isfinite(c["pcrb_std_rad_s"]))
    # periodic pulses every 2 s: 4 pulses, the same times in every replicate
    starts = np.flatnonzero(c["inputs"][0, :, 0])
    np.testing.assert_array_equal(starts, [0, 100, 200, 300])


def test_replicates_are_a_prefix_and_deterministic():
    a = make_cell(small(replicates=2), bounds=False)
    b = make_cell(small(replicates=3), bounds=False)
    np.testing.assert_array_equal(a["accel_m_s2"], b["accel_m_s2"][:2])
    np.testing.assert_array_equal(a["prior_rad_s"], b["prior_rad_s"][:2])


def test_random_pulses_at_the_stated_rate():
    cfg = small(excitation=ExcitationConfig(thruster_torque_n_m=50.0, thruster_rate_hz=0.5), duration_s=400.0,
                replicates=1, schedule=ScheduleConfig())
    u = inputs(cfg)
    assert np.count_nonzero(u[0, :, 0]) == pytest.approx(200, rel=0.25)
    assert set(np.unique(u[0, :, 0])) <= {-50.0, 0.0, 50.0}


def test_prior_within_its_spread_of_the_initial_truth():
    c = make_cell(small(prior_spread=0.1, replicates=4), bounds=False)
    rel = c["prior_rad_s"] / c["truth_freq_rad_s"][0] - 1
    assert np.all(np.abs(rel) <= 0.1 + 1e-12) and np.any(np.abs(rel) > 0.01)


@pytest.mark.parametrize("change, message", [
    (dict(excitation=ExcitationConfig()), "excitation is empty"),
    (dict(schedule=ScheduleConfig(drift=[0, 0.2, 0, 0])), "crosses modes 2 and 3"),
    (dict(dt_s=0.06), "Nyquist"),
    (dict(duration_s=0.5), "duration_s"),
    (dict(noise_ug=0.0), "noise_ug"),
])
def test_impossible_cells_are_refused_in_one_line(change, message):
    with pytest.raises(ValueError, match=message) as err:
        make_cell(small(**change), bounds=False)
    assert "\n" not in str(err.value)


def test_cell_name():
    assert cell_name("drift", "thrusters", 1000, 120) == "drift_thrusters_noise1000ug_120s"
