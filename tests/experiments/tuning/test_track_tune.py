"""Tracking studies (``kind: track``): the tracking objective's arithmetic, a tiny study end to end whose
variant file the track face accepts, and the scoring seed refused."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import methods
from experiments.report.objective import FAILED_REL, mode_failed, track_objective
from experiments.tracker_variants import variant_options

ROOT = Path(__file__).resolve().parents[3]
SCORING_SEED = 20261121


def run(module, *args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", module, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_track_objective_on_a_known_table():
    """Cell a: errors 0.1 %, 1 %, 10 % -> median 1 % (−2 decades), failed shares 0, 0.25, 0.5 -> 0.25;
    J_a = −2 + 2 × 0.25 = −1.5. Cell b: every record failed -> log10(FAILED_REL) + 2 = 3. Mean 0.75."""
    rows = pd.DataFrame({"cell": ["a"] * 3 + ["b"] * 2, "error": [1e-3, 1e-2, 1e-1, np.nan, np.nan],
                         "failed_share": [0.0, 0.25, 0.5, 1.0, 1.0]})
    j = track_objective(rows, penalty=2.0)
    assert j["a_median_error"] == pytest.approx(1e-2) and j["a_failure_rate"] == pytest.approx(0.25)
    assert j["a_value"] == pytest.approx(-1.5)
    assert j["b_value"] == pytest.approx(math.log10(FAILED_REL) + 2.0)
    assert j["value"] == pytest.approx((-1.5 + 3.0) / 2)


def test_mode_failed_per_mode():
    """Mode 1 exact; mode 2 2 % off all along (never within 1 %); mode 3 within 1 % until the last quarter,
    then 20 % off (diverged); mode 4 missing (NaN)."""
    n, dt = 1000, 0.02
    t = np.arange(n) * dt
    truth = np.tile([3.0, 20.0, 22.0, 56.0], (n, 1))
    est = truth.copy()
    est[:, 1] *= 1.02
    est[750:, 2] *= 1.2
    est[:, 3] = np.nan
    assert mode_failed(t, est, truth, dt).tolist() == [False, True, True, True]


def test_scoring_seed_is_refused_for_a_tracking_study(tmp_path):
    out = tmp_path / "akf_x.yaml"
    proc = run("experiments.tuning.tune", "tuning=track_akf", f"tuning.seed={SCORING_SEED}", f"tuning.out={out}",
               f"tuning.storage=sqlite:///{tmp_path / 'o.db'}", "runlog.enabled=false")
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(SCORING_SEED) in lines[0], proc.stderr
    assert not out.exists() and not (tmp_path / "o.db").exists()


def test_unknown_tracking_option_in_the_space_is_refused(tmp_path):
    proc = run("experiments.tuning.tune", "tuning=track_akf", "+tuning.space.nope={low:1,high:2}",
               f"tuning.storage=sqlite:///{tmp_path / 'o.db'}", "runlog.enabled=false")
    assert proc.returncode == 2 and proc.stderr.strip().startswith("error: ") and "nope" in proc.stderr, proc.stderr
    assert not (tmp_path / "o.db").exists()


def test_tiny_tracking_study_writes_a_variant_the_track_face_accepts(tmp_path, monkeypatch):
    """2 trials on one 12 s cell with 1 record: configs/tracker/akf_tiny.yaml is written with its provenance,
    its options pass ``methods.check_track_options`` and run through ``methods.track``; every simulated cell
    used the tuning seed."""
    from experiments.simulate import tracking_data
    from experiments.tuning import tune

    seeds = []
    real = tracking_data.make_cell
    monkeypatch.setattr(tracking_data, "make_cell", lambda cfg, **kw: seeds.append(cfg.seed) or real(cfg, **kw))
    root = tmp_path / "tracker"
    out = root / "akf_tiny.yaml"
    cell = ("tuning.track_cells=[{name:step,schedule:{step:[0,0,0.06,0],step_time_s:6.0},"
            "excitation:{thruster_torque_n_m:100.0,thruster_rate_hz:0.5},noise_ug:1000,duration_s:12}]")
    monkeypatch.setattr(sys, "argv", [
        "tune", "tuning=track_akf", "tuning.variant=tiny", "tuning.trials=2", "tuning.replicates=1",
        "tuning.seed=11", cell, f"tuning.out={out}", f"tuning.storage=sqlite:///{tmp_path / 'optuna.db'}",
        "runlog.enabled=false"])
    tune.main()
    assert seeds and set(seeds) == {11}
    text = out.read_text()
    for fragment in ("tuning seed 11", "Trials: 2", "step_1000ug_12s", "best trial", "Command:", "tracker: akf"):
        assert fragment in text, text
    options = variant_options("akf:tiny", root=root)
    assert set(options) == {"measurement", "qd_modal", "qd_frequency_rel", "rd", "p0_modal_scale"}
    prior = np.array([3.3, 20.0, 22.3, 56.0])
    methods.check_track_options("akf", prior, 0.02, options, n_samples=600)
    y = np.random.default_rng(0).normal(size=600) * 1e-3
    track = methods.track("akf", y, 0.02, prior, **options)
    assert track.frequencies.shape[1] == 4
    with pytest.raises(ValueError, match="unknown tracker variant 'akf:nope'"):
        variant_options("akf:nope", root=root)


def test_benchmark_rows_take_a_variant_file():
    """``tracking_beats``/``tracking_cpu`` rows: ``akf:tuned`` reads configs/tracker/akf_tuned.yaml, an option
    row stays an option row, an unknown variant is refused in one line."""
    from experiments.benchmarks.tracking_cpu import parse_row

    name, options = parse_row("akf:tuned")
    assert name == "akf" and options == variant_options("akf:tuned") and "qd_frequency_rel" in options
    assert parse_row("pem:trend=true") == ("pem", {"trend": True})
    with pytest.raises(ValueError, match="unknown tracker variant 'akf:nope'"):
        parse_row("akf:nope")
