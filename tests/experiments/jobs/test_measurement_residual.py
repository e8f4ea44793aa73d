"""The residual check of a decimated measurement judges the anti-alias filter's pass band only: a simulated
impact record with white noise passes it through the job, one with noise coloured inside the band fails."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.signal

from experiments.simulate.impact import NOISE_G, simulate

SEED = 3      # a test seed (the formats' acceptance test and the benchmark use 1)


def run_identify(path, run_dir):
    from hydra import compose, initialize_config_module

    from experiments.hydra_app.command_line import CONFIG_MODULE
    from experiments.hydra_app.config_store import register
    from experiments.jobs import identify

    register(with_methods=["pem"])
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        cfg = compose(config_name="identify", overrides=["method=pem", "runlog.enabled=false", "progress=false",
                                                         f"data.path={path}"])
    identify.check(cfg)
    identify.run_job(cfg, run_dir, "pem")
    return json.loads((run_dir / "estimate.json").read_text())


def write(path, t, accel_g):
    np.savetxt(path, np.column_stack([t, accel_g]), fmt=["%.6f", "%.7e"], delimiter=",", header="t,tip [g]",
               comments="")
    return path


def test_a_white_record_decimated_by_the_job_passes_the_residual_check(tmp_path):
    rec = simulate(SEED)
    out = run_identify(write(tmp_path / "white.csv", rec.t, rec.accel_g), tmp_path / "run")
    assert out["segment"]["decimation"] > 1
    check = out["residual_check"]
    nyquist = np.pi / out["segment"]["dt_s"]
    assert check["band_rad_s"] == pytest.approx(0.85 * nyquist, rel=0.02)       # the FIR's flat pass band
    assert check["white"], check
    assert "white_noise_std" not in out                                          # the white-noise std stands


def test_a_record_with_noise_coloured_inside_the_band_still_fails_it(tmp_path):
    rec = simulate(SEED)
    rng = np.random.default_rng(SEED + 100)
    # AR(1) noise, φ = 0.9 at the logger's rate: 3× the white noise's level, most of it far below the band's top
    ar = scipy.signal.lfilter([np.sqrt(1 - 0.81)], [1.0, -0.9], rng.standard_normal(rec.t.size + 500))[500:]
    out = run_identify(write(tmp_path / "coloured.csv", rec.t, rec.accel_g + 3 * NOISE_G * ar), tmp_path / "run")
    assert out["segment"]["decimation"] > 1
    check = out["residual_check"]
    assert check["band_rad_s"] is not None
    assert not check["white"], check
