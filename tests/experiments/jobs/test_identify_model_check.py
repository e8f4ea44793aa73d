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
                           "prior=[18]", "hydra.run.dir=coloured", "tracking.enabled=false"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "residual: NOT white" in proc.stdout and "robust std" in proc.stdout
    est = json.loads((tmp_path / "coloured" / "estimate.json").read_text())
    assert est["residual_check"]["white"] is False
    assert est["std_rad_s"][0] >= est["residual_check"]["robust_std_rad_s"][0]
    # the white-noise std is kept beside it (the job cuts and decimates the record to the mode's band, so
    # which of the two is larger depends on the noise's colour there, not asserted)
    assert np.isfinite(est["white_noise_std"][0]) and est["white_noise_std"][0] > 0
