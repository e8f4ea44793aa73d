"""The record and segment a job on a user's file works on (experiments/recordings/load.py): the identify job's
free decay after the largest impulse, the track job's whole record, read once per version of the file."""

from __future__ import annotations

import os
from types import SimpleNamespace

import numpy as np
import pytest

from experiments.recordings.load import load_segment

DT_S = 0.01
OMEGA_RAD_S = 2 * np.pi * 3.0


def data_config(path, **over):
    d = dict(path=str(path), channel=None, units=None, dt=None, start_s=None, stop_s=None, band_hz=None)
    return SimpleNamespace(**{**d, **over})


@pytest.fixture
def decay_csv(tmp_path):
    """2 s of quiet, then a free decay rung at t = 2 s (3 Hz, ζ = 0.01), 12 s in all, in m/s²."""
    t = np.arange(1200) * DT_S
    rng = np.random.default_rng(0)
    y = np.where(t >= 2.0, np.exp(-0.01 * OMEGA_RAD_S * (t - 2.0)) * np.sin(OMEGA_RAD_S * (t - 2.0)), 0.0)
    y = y + 1e-4 * rng.standard_normal(t.size)
    path = tmp_path / "decay.csv"
    path.write_text("t,accel\n" + "".join(f"{a:.4f},{b:.8g}\n" for a, b in zip(t, y, strict=True)))
    return path


def test_the_identify_segment_starts_at_the_impulse_the_track_segment_at_the_record_start(decay_csv):
    rec, seg = load_segment(data_config(decay_csv), cover_hz=4.0)
    assert rec.t0_s == pytest.approx(0.0)
    assert 1.9 <= seg.t0 <= 2.2                              # the free decay after the ring at 2 s
    rec_w, seg_w = load_segment(data_config(decay_csv), cover_hz=4.0, whole_record=True)
    assert seg_w.t0 == pytest.approx(rec_w.t0_s)             # the whole record, from its first sample
    assert "the record's start; set data.start_s= to choose" in seg_w.notes[0]
    assert seg_w.y.size * seg_w.dt > seg.y.size * seg.dt


def test_a_start_given_is_kept_by_both(decay_csv):
    _, seg = load_segment(data_config(decay_csv, start_s=5.0), cover_hz=4.0)
    _, seg_w = load_segment(data_config(decay_csv, start_s=5.0), cover_hz=4.0, whole_record=True)
    assert seg.t0 == pytest.approx(5.0, abs=DT_S) and seg_w.t0 == pytest.approx(5.0, abs=DT_S)
    assert "(data.start_s)" in seg_w.notes[0]


def test_the_file_is_read_once_per_version(decay_csv):
    first = load_segment(data_config(decay_csv), cover_hz=4.0)
    assert load_segment(data_config(decay_csv), cover_hz=4.0)[1] is first[1]    # the pre-check's, reused
    stat = decay_csv.stat()
    os.utime(decay_csv, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))          # the file changed
    assert load_segment(data_config(decay_csv), cover_hz=4.0)[1] is not first[1]


def test_a_missing_file_is_one_line(tmp_path):
    with pytest.raises((ValueError, FileNotFoundError), match="nosuch.csv"):
        load_segment(data_config(tmp_path / "nosuch.csv"))
