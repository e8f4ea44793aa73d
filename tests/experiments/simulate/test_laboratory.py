"""The laboratory cell class (experiments/simulate/laboratory.py): its schedule, its sensor and its decimation
checked against numbers computed here independently; its grid entry accepted and a bad one refused."""

import numpy as np
import pytest

from experiments.report.tracking_metrics import score_dwells
from experiments.simulate.laboratory import (
    G_M_S2,
    LaboratoryCellConfig,
    LaboratoryConfig,
    check_laboratory,
    lab_record,
    make_lab_cell,
    schedule,
)
from experiments.simulate.tracking_grid import load_grid, make_grid_cell


def _cfg(n_modes=1, seed=11, **lab):
    return LaboratoryCellConfig(lab=LaboratoryConfig(n_modes=n_modes, **lab), duration_s=12.0, replicates=2,
                                seed=seed)


@pytest.mark.parametrize("n_modes, seed", [(1, 11), (2, 12), (2, 13)])
def test_moves_keep_their_dwells_steps_and_band(n_modes, seed):
    cfg = _cfg(n_modes, seed)
    steps, levels = schedule(cfg)
    t = steps / cfg.lab.fs_hz
    dwells = np.diff(np.concatenate([[0.0], t]))
    assert steps.size >= 12 * 1 / 2.0 - 1                  # 12 s of dwells ≤ 2 s
    assert np.all(dwells >= 0.4 - 1e-3) and np.all(dwells <= 2.0 + 1e-3)
    ratio = levels[1:] / levels[:-1]                          # every mode scaled alike at every move
    assert np.allclose(ratio, ratio[:, :1], rtol=1e-12)
    size = np.abs(ratio[:, 0] - 1)
    assert np.all((size >= 0.05 - 1e-12) & (size <= 0.20 + 1e-12))
    f = levels / (2 * np.pi)
    assert f.min() >= 20.0 - 1e-9 and f.max() <= 60.0 + 1e-9
    if n_modes == 2:
        assert np.all(f[:, 1] / f[:, 0] >= 1.4 - 1e-9) and np.all(f[:, 1] / f[:, 0] <= 2.0 + 1e-9)


def test_each_dwell_rings_at_its_scheduled_frequency():
    """The noise-free record's spectral peak over each dwell longer than 1 s (a zero-padded FFT, parabolic
    peak) is the schedule's frequency: the moves happen where the schedule says and ring the beam."""
    cfg = _cfg(1, 21)
    rec = lab_record(cfg, 0)
    edges = np.concatenate([[0], rec.steps, [rec.clean_m_s2.size]])
    checked = 0
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if (b - a) / cfg.lab.fs_hz < 1.0:
            continue
        x = rec.clean_m_s2[a:b] * np.hanning(b - a)
        nfft = 1 << 20
        p = np.abs(np.fft.rfft(x, nfft))
        k = int(np.argmax(p[1:])) + 1
        d = 0.5 * (p[k - 1] - p[k + 1]) / (p[k - 1] - 2 * p[k] + p[k + 1])
        f_peak = (k + d) * cfg.lab.fs_hz / nfft
        f_true = rec.freq_rad_s[a, 0] / (2 * np.pi)
        assert abs(f_peak / f_true - 1) < 2e-3, (a, f_peak, f_true)
        # it rings: the first 20 ms after the move hold at least the smallest impulse's 0.1 g, less what a
        # previous ringing of at most 0.4 g can cancel... so only that it is far above the noise
        assert np.abs(rec.clean_m_s2[a:a + 100]).max() > 100 * cfg.noise_ug * 9.80665e-6
        checked += 1
    assert checked >= 3


def test_sensor_is_a_quantised_offset_accelerometer():
    cfg = _cfg(1, 31)
    rec = lab_record(cfg, 0)
    lsb = 2 * cfg.lab.range_v / 2**cfg.lab.bits                # 20 V / 4096 = 4.88 mV
    assert lsb == pytest.approx(20.0 / 4096)
    codes = rec.volts / lsb
    assert np.allclose(codes, np.round(codes), atol=1e-9)       # every sample on the converter's grid
    assert np.abs(rec.volts).max() <= cfg.lab.range_v
    # the sensor's error: offset + noise + rounding, mean = the offset (rounding dithered by the noise)
    err = rec.volts - rec.clean_m_s2 / G_M_S2 * cfg.lab.sensitivity_v_per_g
    assert np.mean(err) == pytest.approx(cfg.lab.offset_v, abs=0.5 * lsb)
    expected = np.hypot(cfg.noise_ug * 1e-6 * cfg.lab.sensitivity_v_per_g, lsb / np.sqrt(12))
    assert np.std(err) == pytest.approx(expected, rel=0.15)
    assert np.allclose(rec.accel_m_s2, rec.volts / cfg.lab.sensitivity_v_per_g * G_M_S2)


def test_decimation_keeps_the_mode():
    """The decimated record equals the full-rate record at the kept instants (the anti-alias FIR passes the
    mode at unit gain, zero phase), and the cell's truth is the schedule at those instants."""
    cfg = _cfg(2, 41)
    cell = make_lab_cell(cfg)
    rec = lab_record(cfg, 1)
    q = cfg.lab.decimate
    assert cell["dt_s"] == pytest.approx(q / cfg.lab.fs_hz)
    dec, raw = cell["accel_clean_m_s2"][1], rec.clean_m_s2[::q][:cell["t_s"].size]
    inner = slice(20, -20)                                      # away from the filter's edge transients
    # each move's impulse is broadband, and the filter spreads it over ±10 output samples: away from them
    near = np.zeros(dec.size, bool)
    for s in cell["step_times_s"]:
        k = int(round(s / cell["dt_s"]))
        near[max(0, k - 12):k + 12] = True
    keep = ~near
    keep[:20] = keep[-20:] = False
    assert np.sqrt(np.mean((dec[keep] - raw[keep]) ** 2)) < 0.02 * np.sqrt(np.mean(raw[inner] ** 2))
    assert np.array_equal(cell["truth_freq_rad_s"], rec.freq_rad_s[::q][:cell["t_s"].size])
    assert cell["accel_m_s2"].shape == (2, cell["t_s"].size)
    # the offset survives decimation (the FIR's unit gain at 0 Hz)
    assert np.mean(cell["accel_m_s2"][1] - cell["accel_clean_m_s2"][1]) == pytest.approx(
        cfg.lab.offset_v / cfg.lab.sensitivity_v_per_g * G_M_S2, rel=0.05)


def test_impossible_laboratory_is_one_line():
    with pytest.raises(ValueError, match="band_hz .* too narrow"):
        check_laboratory(_cfg(2, 1, band_hz=[20.0, 40.0], mode_ratio=[1.8, 2.0]))
    with pytest.raises(ValueError, match="pass band"):
        check_laboratory(_cfg(1, 1, decimate=60))               # 83 Hz: Nyquist 41.7 Hz below the band
    with pytest.raises(ValueError, match="n_modes"):
        check_laboratory(_cfg(4, 1))


GRID = """
name: tracking_labtest
noise_ug: [1000]
duration_s: [20]
replicates: 1
seed: 5
trackers: [next_era]
schedules:
  step: {step: [0.0, 0.0, 0.06, -0.04], step_time_s: 10.0}
excitations:
  thrusters: {thruster_torque_n_m: 100.0}
laboratory:
"""


def test_grid_accepts_a_laboratory_cell(tmp_path):
    path = tmp_path / "tracking_labtest.yaml"
    path.write_text(GRID + "  beam: {n_modes: 2, duration_s: 3.0, noise_ug: 500.0}\n")
    grid = load_grid(str(path))
    cell = grid["cells"]["beam_laboratory_noise500ug_3s"]
    assert cell["schedule"] == "beam" and cell["excitation"] == "laboratory"
    data = make_grid_cell(cell["config"])
    assert data["truth_freq_rad_s"].shape == (750, 2) and data["accel_m_s2"].shape == (1, 750)


@pytest.mark.parametrize("entry, fragment", [
    ("  beam: {n_mode: 2}", "laboratory.beam: Additional properties are not allowed ('n_mode'"),
    ("  beam: {n_modes: 5}", "laboratory.beam.n_modes: 5 is greater than the maximum of 3"),
    ("  beam: {band_hz: [20]}", "laboratory.beam.band_hz"),
    ("  beam: {band_hz: [20.0, 30.0], n_modes: 2}", "cell beam_laboratory_noise300ug_12s: laboratory.band_hz"),
])
def test_grid_refuses_a_bad_laboratory_cell_in_one_line(tmp_path, entry, fragment):
    path = tmp_path / "tracking_labtest.yaml"
    path.write_text(GRID + entry + "\n")
    with pytest.raises(ValueError) as err:
        load_grid(str(path))
    message = str(err.value)
    assert "\n" not in message and fragment in message, message


def test_dwell_scores_against_hand_numbers():
    """A track exact but 2 % off for 0.6 s after each move: the scored spans (from 10 periods of the dwell's
    mode after each move) hold the rest of those 0.6 s; re-convergence is 0.6 s after every move."""
    dt, w = 0.001, 2 * np.pi * 50.0                             # 50 Hz: a period is 20 samples
    n = 6000
    steps_s = np.array([2.0, 4.0])
    truth = np.full((n, 1), w)
    truth[2000:4000] *= 1.1
    truth[4000:] *= 1.1 * 0.9
    t = np.arange(n) * dt
    est = truth.copy()
    for a in (0, 2000, 4000):
        est[a:a + 600] *= 1.02                                  # 0.6 s: 30 periods of dwell 0's 50 Hz
    s = score_dwells(t, est, np.ones_like(est, bool), 0.0, truth, dt, steps_s)
    # per dwell: scored from 10 periods (200, 182, 202 samples) to its end, of which up to 600 samples bad
    period = 2 * np.pi / truth[[1000, 3000, 5000], 0]
    scored = [2000 - round(10 * p / dt) for p in period]
    bad = [600 - round(10 * p / dt) for p in period]
    assert s["share_within_1pct"] == pytest.approx(1 - sum(bad) / sum(scored), abs=2e-3)
    assert s["t_converge_s"] == pytest.approx(0.6)
    assert s["t_reconverge_s"] == pytest.approx(0.6)
    assert s["reconverge_periods"] == pytest.approx(np.median(0.6 / period[1:]), rel=1e-6)
    assert s["reconverged_share"] == 0.0                        # 30 periods > 10
    assert s["err_rel_median"] == pytest.approx(0.0, abs=1e-12)
    assert s["err_rel_p90"] == pytest.approx(0.02, rel=1e-6)
