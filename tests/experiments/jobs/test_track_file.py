"""The track job on a user's file (experiments/jobs/track_file.py): a CSV and a UFF file written here, the
track against the simulated schedule, the figure, the MLflow run; and its refusals, each one ``error:`` line,
exit 2, nothing written."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from experiments.simulate.laboratory import LaboratoryCellConfig, LaboratoryConfig, lab_record

ROOT = Path(__file__).resolve().parents[3]
FS_HZ = 2000.0


def _record(dwell_s, seed=3, duration_s=6.0, step_rel=(0.05, 0.2)):
    """One laboratory record at 2 kHz: a beam at 20-60 Hz (moves after dwell_s, each ringing it), in g,
    offset, 12 bits."""
    cfg = LaboratoryCellConfig(lab=LaboratoryConfig(n_modes=1, dwell_s=dwell_s, fs_hz=FS_HZ, decimate=8,
                                                    step_rel=list(step_rel)),
                               duration_s=duration_s, replicates=1, seed=seed)
    rec = lab_record(cfg, 0)
    t = np.arange(rec.volts.size) / FS_HZ
    return t, rec.volts / cfg.lab.sensitivity_v_per_g, rec


def _write_uff(path, t, accel_g):
    import pyuff

    data = pyuff.prepare_58(
        func_type=1, id1="tip", id2="moving support", id3="", id4="", id5="", ver_num=0, load_case_id=0,
        rsp_ent_name="beam", rsp_node=1, rsp_dir=2, ref_ent_name="none", ref_node=0, ref_dir=0,
        ord_data_type=4, abscissa_spacing=1, abscissa_min=0.0, abscissa_inc=1.0 / FS_HZ, z_axis_value=0.0,
        abscissa_spec_data_type=17, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0, abscissa_temp_unit_exp=0,
        abscissa_axis_units_lab="s", ordinate_spec_data_type=12, ordinate_len_unit_exp=1,
        ordinate_force_unit_exp=0, ordinate_temp_unit_exp=0, ordinate_axis_units_lab="g",
        orddenom_spec_data_type=0, orddenom_len_unit_exp=0, orddenom_force_unit_exp=0, orddenom_temp_unit_exp=0,
        orddenom_axis_units_lab="", z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0,
        z_axis_temp_unit_exp=0, z_axis_axis_units_lab="", x=t, data=accel_g, binary=0)
    pyuff.UFF(str(path)).write_sets([data], mode="overwrite")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("trackfile")
    # a held frequency: rung every 0.5-1 s by "moves" that change it by 1e-9 (no more), 20 s
    t, g, held = _record([0.5, 1.0], duration_s=20.0, step_rel=(1e-9, 2e-9))
    assert np.ptp(held.freq_rad_s) < 1e-6 * held.freq_rad_s[0, 0]
    (d / "held.csv").write_text("t,tip [g]\n" + "".join(f"{a:.6f},{b:.9g}\n" for a, b in zip(t, g, strict=True)))
    # moves every 0.8-1.5 s, as a UFF 58 file
    t2, g2, moving = _record([0.8, 1.5], seed=4)
    _write_uff(d / "moving.uff", t2, g2)
    return d, held, moving


def _run(cwd, *args, env=None):
    return subprocess.run([sys.executable, "-m", "experiments.jobs.track_file", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})})


def test_held_frequency_from_a_csv_is_tracked_and_logged(files, tmp_path):
    d, held, _ = files
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    prior = float(1.04 * held.freq_rad_s[0, 0])
    proc = _run(d, "data.path=held.csv", f"prior=[{prior!r}]", f"hydra.run.dir={tmp_path / 'run'}",
                "runlog.background=false", env={"MLFLOW_TRACKING_URI": uri, "GIT_PYTHON_REFRESH": "quiet"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    run = tmp_path / "run"
    out = json.loads((run / "track.json").read_text())
    f = np.asarray(out["frequencies_rad_s"], float)[:, 0]
    conv = np.asarray(out["converged"], bool)[:, 0]
    truth = held.freq_rad_s[0, 0]
    # the track's last half, converged: within 1 % of the simulated frequency (the prior was 4 % off)
    late = conv & (np.asarray(out["t_s"]) > 10.0)
    assert late.sum() > 3
    assert np.max(np.abs(f[late] / truth - 1)) < 0.01
    # the CSV holds the same track, in Hz and rad/s, at file times
    rows = np.genfromtxt(run / "track.csv", delimiter=",", names=True)
    assert rows.dtype.names == ("t_s", "mode1_freq_hz", "mode1_std_hz", "mode1_freq_rad_s", "mode1_std_rad_s",
                                "mode1_converged")
    assert np.allclose(rows["t_s"], out["t_s"]) and np.all(np.diff(rows["t_s"]) > 0)
    assert np.allclose(rows["mode1_freq_hz"] * 2 * np.pi, rows["mode1_freq_rad_s"], equal_nan=True)
    png = (run / "track.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000 and (run / "track.svg").is_file()
    logged = json.loads((run / "mlflow_run.json").read_text())          # the runlog stage logged it
    assert out["tracker"] == "gated_pencil" and out["options"] == {}
    assert logged["experiment"] == "measurement-tracks"
    assert logged["run_key"].startswith("measurement/track:gated_pencil/held.csv/")


def test_moving_support_from_a_uff_file_without_a_prior(files, tmp_path):
    d, _, moving = files
    proc = _run(d, "data.path=moving.uff", "tracker=era", "tracker.options.hop_samples=25",
                f"hydra.run.dir={tmp_path / 'run'}", "runlog.enabled=false")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "stabilisation diagram" in proc.stdout and "on the first" in proc.stdout
    out = json.loads((tmp_path / "run" / "track.json").read_text())
    assert out["tracker"] == "era" and out["options"] == {"hop_samples": 25}
    # the modes came from the first stretch: the first dwell's frequency, within the diagram's 1 %
    assert len(out["prior_rad_s"]) == 1
    assert abs(out["prior_rad_s"][0] / moving.freq_rad_s[0, 0] - 1) < 0.01
    # the record is tracked whole, from the file's first sample, decimated to its band
    assert out["segment"]["start_s"] == pytest.approx(0.0, abs=1e-9)
    assert out["segment"]["decimation"] > 1
    assert out["t_s"][-1] <= 6.0 and len(out["t_s"]) > 10
    assert (tmp_path / "run" / "track.png").stat().st_size > 20_000


@pytest.mark.parametrize("args, fragments", [
    (["data.path=nosuch.csv"], ["nosuch.csv", "does not exist"]),
    (["data.path=held.csv", "tracker=kalman9"], ["unknown tracker 'kalman9'", "gated_pencil"]),
    (["data.path=held.csv", "prior=[300,200]"], ["held.csv", "prior"]),
    (["data.path=held.csv", "prior=[1e9]"], ["held.csv", "Nyquist"]),
    (["data.path=held.csv", "tracker.options.no_such_option=3"], ["no_such_option"]),
    (["data.path=held.csv", "tracker=era", "tracker.options.window_samples=4"], ["tracker era", "window_samples = 4"]),
    (["data.path=held.csv", "tracker=era", "tracker.options.window_samples=999999"],
     ["tracker era", "longer than the record"]),
    (["data.path=held.csv", "data.channel=root"], ["held.csv", "no channel 'root'"]),
    (["data.path=held.csv", "data.units=m/s2"], ["held.csv", "contradicts the file"]),
    (["data.dataset=cell.npz"], ["data.dataset", "data.path"]),
])
def test_bad_input_is_one_error_line_and_nothing_written(files, args, fragments):
    d = files[0]
    proc = _run(d, *args, "hydra.run.dir=out", "runlog.enabled=false")
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for f in fragments:
        assert f in lines[0], lines[0]
    assert not (d / "out").exists()
