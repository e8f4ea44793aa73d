"""Shared by the cluster tests: the smoke grid through Snakemake in a scratch directory, and its tables.

Snakemake is started as ``<this interpreter> -m snakemake`` with a PATH that does *not* hold the environment's
``bin``: the jobs must find their interpreter themselves (experiments/workflow/rules/common.smk), as on a cluster.
"""

import csv
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SYSTEM_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"


def _command(workdir: Path, args, env: dict | None):
    base = {k: v for k, v in os.environ.items() if k not in ("MLFLOW_TRACKING_URI", "VIRTUAL_ENV")}
    base["PATH"] = SYSTEM_PATH
    cmd = [sys.executable, "-m", "snakemake", "-s", str(ROOT / "Snakefile"), "--directory", str(workdir), *args]
    return cmd, base | (env or {})


def snakemake(workdir: Path, *args: str, env: dict | None = None, timeout: int = 1200):
    """Run the workflow of this repository in ``workdir``; the PATH is the system's, not the venv's."""
    cmd, env = _command(workdir, args, env)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT)


def start_snakemake(workdir: Path, *args: str, env: dict | None = None) -> subprocess.Popen:
    """Like ``snakemake`` but in the background (output in ``workdir``/snakemake.out)."""
    cmd, env = _command(workdir, args, env)
    return subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=open(workdir / "snakemake.out", "w"),
                            stderr=subprocess.STDOUT)


def table_without_runtimes(path: Path) -> list[list[str]]:
    """A CSV's cells as text, runtime columns (wall-clock, never reproducible) removed: equal text = equal bits."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, name in enumerate(rows[0]) if "runtime" not in name and "ms_per_fit" not in name]
    return [[row[i] for i in keep] for row in rows]


def result_tables(workdir: Path, grid: str = "smoke") -> dict[str, list[list[str]]]:
    """Every per-job result CSV and every summary table of a grid, keyed by the path below results/<grid>/."""
    out = workdir / "results" / grid
    files = sorted(out.glob("identify/*/*.csv")) + sorted(out.glob("tables/*.csv"))
    return {str(p.relative_to(out)): table_without_runtimes(p) for p in files}
