"""The identify job on a user's record says whether the model explains it (pem's residual check)."""

import json
import subprocess
import sys

import numpy as np


def test_identify_on_a_coloured_noise_csv_says_the_model_does_not_explain_it(tmp_path):
    """pem on a user's record in AR(1) noise: the residual check, the robust std and the drift notes on the
    terminal, and the same in estimate.json."""
    t = np.arange(1024) * 0.02
    w = np.random.default_rng(9).standard_normal(t.size)
    noise = np.zeros(t.size)
    for k in range(1, t.size):
        noise[k] = 0.9 * noise[k - 1] + 0.44 * 0.01 * w[k]
    y = np.exp(-0.05 * t) * np.cos(20.3 * t) + noise
    rows = "".join(f"{a:.2f},{b:.6f}\n" for a, b in zip(t, y, strict=True))
    (tmp_path / "coloured.csv").write_text("t,accel\n" + rows)
    proc = subprocess.run([sys.executable, "-m", "experiments.jobs.identify", "method=pem", "data.path=coloured.csv",
                           "prior=[18]", "hydra.run.dir=coloured", "runlog.enabled=false"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "residual: NOT white" in proc.stdout and "robust std" in proc.stdout
    est = json.loads((tmp_path / "coloured" / "estimate.json").read_text())
    assert est["residual_check"]["white"] is False
    assert est["std_rad_s"][0] >= est["residual_check"]["robust_std_rad_s"][0]
    # the white-noise std is kept beside it (the job cuts and decimates the record to the mode's band, so
    # which of the two is larger depends on the noise's colour there, not asserted)
    assert np.isfinite(est["white_noise_std"][0]) and est["white_noise_std"][0] > 0


def test_identify_on_a_clipped_csv_says_the_sensor_clipped(tmp_path):
    """A record clipped at ±1.5 m/s²: the terminal and estimate.json name the plateaus (counted here from the
    unclipped record) and the sample the fit starts from; a bad skip_clipped is one error line, exit 2."""
    t = np.arange(512) * 0.02
    raw = 3.0 * np.exp(-0.1 * t) * np.cos(20.0 * t) + 0.01 * np.random.default_rng(10).standard_normal(t.size)
    y = np.clip(raw, -1.5, 1.5)
    rows = "".join(f"{a:.2f},{b:.6f}\n" for a, b in zip(t, y, strict=True))
    (tmp_path / "clipped.csv").write_text("t,accel\n" + rows)
    run = [sys.executable, "-m", "experiments.jobs.identify", "method=pem", "data.path=clipped.csv", "prior=[18]",
           "runlog.enabled=false"]
    proc = subprocess.run([*run, "hydra.run.dir=clipped"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "saturation: the sensor clipped" in proc.stdout
    sat = json.loads((tmp_path / "clipped" / "estimate.json").read_text())["saturation"]
    assert sorted(sat["plateau_samples"]) == sorted([int((raw >= 1.5).sum()), int((raw <= -1.5).sum())])
    assert sat["fit_start"] == int(np.flatnonzero(np.abs(raw) >= 1.5).max()) + 1
    bad = subprocess.run([*run, "hydra.run.dir=bad", "method.options.skip_clipped=maybe"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2
    assert bad.stderr.strip().startswith("error:") and len(bad.stderr.strip().splitlines()) == 1
    assert "skip_clipped" in bad.stderr and not (tmp_path / "bad").exists()
