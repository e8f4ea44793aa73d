"""Snakemake in a scratch working directory, for the end-to-end workflow tests."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def snakemake_in(workdir, *args, snakefile=ROOT / "Snakefile"):
    """Snakemake with any Snakefile (a scratch copy of the repository) in a scratch working directory."""
    bindir = Path(sys.executable).parent          # the rules call `python -m ...` of this environment
    env = os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    env.pop("MLFLOW_TRACKING_URI", None)
    return subprocess.run([str(bindir / "snakemake"), "-s", str(snakefile), "--directory", str(workdir),
                           "--cores", "2", *args], capture_output=True, text=True, timeout=900, env=env)
