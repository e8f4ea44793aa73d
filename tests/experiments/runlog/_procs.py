"""Real processes of this environment for the tracking tests."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def run(*args, cwd, env_extra=None, check=True):
    """A real process of this environment, run in ``cwd`` (its own results/ and MLflow store)."""
    env = os.environ | {"GIT_PYTHON_REFRESH": "quiet", "OPENBLAS_NUM_THREADS": "1"} | (env_extra or {})
    env.pop("MLFLOW_TRACKING_URI", None)
    if env_extra and "MLFLOW_TRACKING_URI" in env_extra:
        env["MLFLOW_TRACKING_URI"] = env_extra["MLFLOW_TRACKING_URI"]
    proc = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)
    if check:
        assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


def identify(cwd, *overrides, **kw):
    return run("-m", "experiments.jobs.identify", "progress=false", *overrides, cwd=cwd, **kw)




def grid_jobs(cwd, dataset, grid, methods=("fft", "pll")):
    """The identify jobs of one cell of grid ``grid`` (one per method) run in ``cwd`` as the workflow runs
    them; their tables' paths, as a runlog step takes them."""
    tables = []
    for method in methods:
        out = Path(cwd) / "results" / grid / "identify" / method / "noise1000ug_n64.csv"
        identify(cwd, f"method={method}", f"data.dataset={dataset}", f"out={out}", f"grid_name={grid}",
                 "runlog.enabled=false", f"hydra.run.dir={Path(cwd) / 'runs' / method}")
        tables.append(str(out))
    return tables
