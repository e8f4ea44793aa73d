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


