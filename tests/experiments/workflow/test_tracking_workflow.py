"""The tracking_smoke grid through Snakemake (records -> trackers -> report -> MLflow) with the stand-in
tracker installed in every process (stand_in_site/sitecustomize.py), in a scratch working directory."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[3]
SITE = Path(__file__).resolve().parents[1] / "jobs" / "stand_in_site"   # the stand-in tracker, beside its tests
pytestmark = pytest.mark.slow


def test_tracking_smoke_grid_runs_end_to_end(tmp_path):
    bindir = Path(sys.executable).parent
    env = os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}",
                        "PYTHONPATH": f"{SITE}{os.pathsep}{ROOT}",
                        "MLFLOW_TRACKING_URI": f"sqlite:///{tmp_path / 'mlflow.db'}"}
    proc = subprocess.run([str(bindir / "snakemake"), "-s", str(ROOT / "Snakefile"), "--directory", str(tmp_path),
                           "--cores", "2", "results/tracking_smoke/README.md"], capture_output=True, text=True,
                          timeout=600, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = tmp_path / "results" / "tracking_smoke"
    table = pd.read_csv(out / "tables" / "tracking_table.csv")
    from experiments.simulate.tracking_grid import load_grid
    from tests.experiments.jobs._stand_in_tracker import track_names

    cells = len(load_grid("tracking_smoke", check_cells=False)["cells"])      # 2 spacecraft + 1 laboratory
    assert set(table["tracker"]) == set(track_names()) and len(table) == len(track_names()) * cells
    assert (out / "figures" / "tracking_estimates_step.png").exists()
    assert (out / "figures" / "tracking_estimates_step.rst").exists()
    assert "## Tracking" in (out / "README.md").read_text()
    assert len(json.loads((out / "mlflow_runs.json").read_text())["runs"]) == 1 + len(track_names()) * cells
    assert len(list((out / "benchmarks" / "track").glob("*.tsv"))) == len(track_names())
