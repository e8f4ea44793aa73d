"""The readers: channels, units, and the time step of stamps a logger rounded."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.recordings import choose_segment, read_record
from experiments.recordings.read import G_M_S2

TRUE_STEP = 0.00060546875          # 1651.6 Hz: the step of a real impact record, not printable in 6 decimals


def csv(tmp_path, t_text, y, header="t,accel [g]"):
    p = tmp_path / "beam.csv"
    p.write_text(header + "\n" + "".join(f"{a},{b!r}\n" for a, b in zip(t_text, y, strict=True)))
    return p


@pytest.mark.parametrize("fmt", ["{:.6f}", "{:.9g}"])
def test_logger_rounded_stamps_give_the_true_step(tmp_path, fmt):
    k = np.arange(4000)
    t = 0.25 + k * TRUE_STEP
    rec = read_record(csv(tmp_path, [fmt.format(x) for x in t], np.sin(k * 0.1).tolist()))
    # least squares over 4000 stamps each within 0.5 µs (or 0.5e-9 s): the step to ~1e-9 relative
    assert rec.dt_s == pytest.approx(TRUE_STEP, rel=2e-9)
    assert rec.t0_s == pytest.approx(0.25, abs=1e-6)
    assert rec.unit == "g"
    assert rec.accel_m_s2[1] == pytest.approx(np.sin(0.1) * G_M_S2)
    assert any("fitted to 4000 time stamps" in n for n in rec.notes)


@pytest.mark.parametrize("change, message", [
    (lambda t: np.r_[t[:100], t[101:]], "row 101: t = .* a gap"),
    (lambda t: t + np.where(np.arange(t.size) == 50, 3e-6, 0.0), r"row 51: .* breaks the uniform sampling \(step"),
    # a clock that runs 0.2 % slow after half the record: every step within the stamps' precision, the drift not
    (lambda t: t + np.where(np.arange(t.size) > 200, 0.002 * (t - t[200]), 0.0), "off the fitted step"),
    (lambda t: np.where(np.arange(t.size) == 7, t[6], t), "row 8: .* does not increase"),
])
def test_a_real_gap_or_jitter_is_refused(tmp_path, change, message):
    t = change(np.arange(400) * TRUE_STEP)
    with pytest.raises(ValueError, match=message):
        read_record(csv(tmp_path, [f"{x:.6f}" for x in t], np.ones(t.size).tolist()))


def test_several_channels_need_a_choice_and_the_error_lists_them(tmp_path):
    p = tmp_path / "two.csv"
    p.write_text("time [s],tip [g],root [m/s^2]\n" + "".join(f"{0.001 * k:.3f},{k % 3},{k % 5}\n" for k in range(50)))
    with pytest.raises(ValueError, match=r"2 channels; choose one with data.channel= \(channels: tip, root\)"):
        read_record(p)
    with pytest.raises(ValueError, match=r"no channel 'mid' \(channels: tip, root\)"):
        read_record(p, channel="mid")
    assert read_record(p, channel="root").accel_m_s2[3] == 3.0
    assert read_record(p, channel="tip", units="g").unit == "g"
    with pytest.raises(ValueError, match=r"data.units=m/s\^2 contradicts the file, whose channel 'tip' is in g"):
        read_record(p, channel="tip", units="m/s²")


def test_units_from_the_user_when_the_file_names_none(tmp_path):
    import scipy.io

    p = tmp_path / "r.mat"
    scipy.io.savemat(str(p), {"acc": np.arange(20.0)})
    with pytest.raises(ValueError, match="names no unit .* data.units="):
        read_record(p, dt=0.001)
    with pytest.raises(ValueError, match="no time column or sample interval; give data.dt="):
        read_record(p, units="mm/s^2")
    rec = read_record(p, units="mm/s^2", dt=0.001)
    assert rec.accel_m_s2[5] == pytest.approx(5e-3)
    assert rec.dt_s == 0.001


@pytest.mark.parametrize("name, content, message", [
    ("r.xlsx", b"x", "unknown extension '.xlsx'"),
    ("r.mat", b"this is text, not MATLAB", "not a readable MATLAB file"),
    ("r.tdms", b"TDSm garbage" * 10, "not a readable TDMS file"),
    ("r.uff", b"    -1\n    58\nnonsense\n    -1\n", "not a readable UFF file|no acceleration"),
    ("r.lvm", b"\x00\x01binary", "not a readable LabVIEW measurement file"),
    ("r.csv", b"", "not a readable CSV"),
])
def test_wrong_content_is_one_error_naming_the_file(tmp_path, name, content, message):
    p = tmp_path / name
    p.write_bytes(content)
    with pytest.raises(ValueError, match=message) as err:
        read_record(p, units="g", dt=0.001)
    assert str(p) in str(err.value) and "\n" not in str(err.value)


def test_segment_starts_after_the_impulse_and_refuses_a_band_above_nyquist():
    dt = 1e-3
    t = np.arange(8000) * dt
    y = np.where(t >= 1.0, np.exp(-3 * (t - 1.0)) * np.sin(2 * np.pi * 40 * (t - 1.0) + 0.3), 0.0)
    seg = choose_segment(y, dt, band_hz=100.0)
    assert seg.decimation == 4                            # 1000 Hz / (2.5 × 100 Hz)
    assert seg.impulse_s == pytest.approx(1.0, abs=0.01)  # the largest |y| is in the first cycle
    assert seg.t0 > seg.impulse_s
    with pytest.raises(ValueError, match="reaches above the Nyquist frequency 500 Hz"):
        choose_segment(y, dt, band_hz=[10, 600])
    with pytest.raises(ValueError, match="samples from .* at least 64"):
        choose_segment(y, dt, start_s=7.95)


def test_a_record_that_starts_in_its_decay_is_kept_whole_and_a_short_pretrigger_is_found():
    dt = 0.02
    t = np.arange(256) * dt        # the spacecraft's free decay from release: its largest sample comes later
    y = sum(a * np.cos(w * t) for a, w in [(1.04, 3.32), (-4.10, 20.36), (-4.84, 22.02), (6.42, 56.78)])
    assert np.argmax(np.abs(y)) > 0
    seg = choose_segment(y, dt, band_hz=[0.1, 24.0])
    assert seg.impulse_s is None and seg.t0 == 0.0 and seg.y.size == 256
    rng = np.random.default_rng(5)
    hit = np.r_[0.001 * rng.standard_normal(64), 2 * np.exp(-0.5 * t[:192]) * np.sin(20 * t[:192] + 0.5)]
    seg = choose_segment(hit, dt, band_hz=20.0)
    assert seg.impulse_s is not None and seg.t0 > 64 * dt


def test_a_byte_order_mark_is_not_part_of_the_time_columns_name(tmp_path):
    t = np.arange(64) * 0.001
    p = csv(tmp_path, [f"{x:.3f}" for x in t], np.cos(300 * t).tolist())
    p.write_text("\ufeff" + p.read_text(), encoding="utf-8")
    rec = read_record(p, units="g")
    assert rec.dt_s == pytest.approx(0.001) and rec.accel_m_s2.size == 64


@pytest.mark.parametrize("text, message", [
    ("t,accel\n", "no columns or no rows"),
    ("t,accel\n" + "".join(f"{1e300 * (k + 1):.6e},{k}\n" for k in range(16)), "1e\\+300"),
])
def test_an_empty_or_absurdly_stamped_csv_is_one_line_without_a_warning(tmp_path, text, message):
    p = tmp_path / "r.csv"
    p.write_text(text)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")                   # a warning would be a second line on stderr
        with pytest.raises(ValueError, match=message) as err:
            rec = read_record(p, units="g")
            if rec.dt_s > 1e299:                          # a step of 1e300 s is read; the job refuses the prior
                raise ValueError(f"dt = {rec.dt_s:g}")
    assert "\n" not in str(err.value)
