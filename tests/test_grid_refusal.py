"""A grid with a bad axis value is refused by the workflow in one line, exit 2, before any job runs."""

import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(("axes", "message"), [
    ("gap_rad_s: [0.3, 40]", "cell noise1000ug_n256_gap40: gap_rad_s = 40 puts mode 3 at 60.24 rad/s"),
    ("damping: [-0.01]",
     "configs/grid/bad.yaml: scenarios.0.damping.0: -0.01 is less than or equal to the minimum of 0"),
    ("dt_s: [0.06]", "dt_s = 0.06 s puts Nyquist at 52.36 rad/s"),
])
def test_bad_axis_value_is_one_line_and_exit_2(tmp_path, axes, message):
    # the checkout's layout, profiles/ included: a workflow profile Snakemake finds by itself would print its
    # "Using workflow specific profile ..." line before the refusal
    for part in ("Snakefile", "experiments", "configs", "methods", "profiles"):
        src = ROOT / part
        (shutil.copytree if src.is_dir() else shutil.copy)(src, tmp_path / part)
    (tmp_path / "configs" / "grid" / "bad.yaml").write_text(
        "name: bad\nnoise_ug: [1000]\nn_samples: [256]\nreplicates: 2\nseed: 1\nmethods: [fft]\n"
        f"scenarios:\n  - {axes}\n")
    bindir = Path(sys.executable).parent
    proc = subprocess.run([str(bindir / "snakemake"), "-n", "--cores", "1", "results/bad/README.md"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          env=os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ['PATH']}"})
    assert proc.returncode == 2
    lines = (proc.stdout + proc.stderr).splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0], proc.stdout + proc.stderr
    assert not (tmp_path / "results").exists()


@pytest.mark.parametrize(("grid", "target", "message"), [
    ("method_overrides: {fft: [method.options.zero_pad_factor=0]}\n", "results/bad/README.md",
     "configs/grid/bad.yaml: method_overrides of fft: fft: zero_pad_factor = 0 must be an integer of at least 1"),
    ("", "results/nosuch/README.md", "error: results/nosuch/README.md: no grid 'nosuch'"),
    ("", "papr", "error: no rule 'papr'; the targets are the rules"),
])
def test_a_bad_override_or_target_is_one_line_before_any_job(tmp_path, grid, target, message):
    for part in ("Snakefile", "experiments", "configs", "methods"):
        src = ROOT / part
        (shutil.copytree(src, tmp_path / part, symlinks=True) if src.is_dir() else shutil.copy(src, tmp_path / part))
    (tmp_path / "configs" / "grid" / "bad.yaml").write_text(
        "name: bad\nnoise_ug: [1000]\nn_samples: [256]\nreplicates: 2\nseed: 1\nmethods: [fft]\n" + grid)
    bindir = Path(sys.executable).parent
    proc = subprocess.run([str(bindir / "snakemake"), "-n", "--cores", "1", target],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          env=os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ['PATH']}"})
    assert proc.returncode == 2
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and message in errors[0], proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "results").exists()


@pytest.mark.parametrize("damage", ["empty", "half"])
def test_a_broken_mlflow_store_is_one_line_before_any_job(tmp_path, damage):
    for part in ("Snakefile", "experiments", "configs", "methods", "profiles"):
        src = ROOT / part
        (shutil.copytree(src, tmp_path / part, symlinks=True) if src.is_dir() else shutil.copy(src, tmp_path / part))
    (tmp_path / "configs" / "grid" / "tiny.yaml").write_text(
        "name: tiny\nnoise_ug: [1000]\nn_samples: [64]\nreplicates: 2\nseed: 1\nmethods: [fft]\n")
    store = tmp_path / "results" / "mlflow.db"
    store.parent.mkdir()
    with sqlite3.connect(store) as con:                   # a real SQLite file of a few pages, then damaged
        con.execute("create table runs (blob)")
        con.execute("insert into runs values (?)", (b"x" * 65536,))
    store.write_bytes(b"" if damage == "empty" else store.read_bytes()[: store.stat().st_size // 2])
    bindir = Path(sys.executable).parent
    proc = subprocess.run([str(bindir / "snakemake"), "-n", "--cores", "1", "results/tiny/README.md"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          env={k: v for k, v in os.environ.items() if k != "MLFLOW_TRACKING_URI"}
                          | {"PATH": f"{bindir}{os.pathsep}{os.environ['PATH']}"})
    assert proc.returncode == 2
    lines = (proc.stdout + proc.stderr).splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: the MLflow store {store}"), proc.stdout + proc.stderr
    assert ("empty (0 bytes)" if damage == "empty" else "truncated") in lines[0]
    # nothing beside the store but its inter-process lock (experiments/runlog/store.py)
    assert {p.name for p in (tmp_path / "results").iterdir()} <= {"mlflow.db", "mlflow.db.lock"}
