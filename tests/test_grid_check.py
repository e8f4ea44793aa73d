"""The workflow checks every method a grid names when it loads the grid: an unknown name stops it with one
line naming the grid file and the name; a variant ``name:variant`` whose config exists is accepted.

Runs ``snakemake --dry-run`` on a copy of the workflow (Snakefile, code, configs) in tmp_path, so that a
test grid never enters the repository's configs/grid/.
"""

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GRID = "name: {name}\nnoise_ug: [10]\nn_samples: [64]\nreplicates: 1\nseed: 5\nmethods: {methods}\n"


def dry_run(tmp_path, methods):
    shutil.copy(ROOT / "Snakefile", tmp_path / "Snakefile")
    for code in ("experiments", "methods"):            # the rules call the workflow module of this checkout
        shutil.copytree(ROOT / code, tmp_path / code, symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "configs", tmp_path / "configs", ignore=shutil.ignore_patterns("grid"))
    (tmp_path / "configs" / "grid").mkdir()
    for name in ("paper", "smoke", "full"):            # the Snakefile's named targets
        (tmp_path / "configs" / "grid" / f"{name}.yaml").write_text(GRID.format(name=name, methods="[fft]"))
    (tmp_path / "configs" / "grid" / "mine.yaml").write_text(GRID.format(name="mine", methods=methods))
    bindir = Path(sys.executable).parent
    env = os.environ | {"PATH": f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}"}
    return subprocess.run([str(bindir / "snakemake"), "-s", str(tmp_path / "Snakefile"), "--directory",
                           str(tmp_path), "--cores", "1", "--dry-run", "results/mine/README.md"],
                          capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path)


def test_an_unknown_method_is_named_with_the_grid_file(tmp_path):
    proc = dry_run(tmp_path, "[fft, no_such_method]")
    assert proc.returncode != 0
    errors = [ln for ln in (proc.stdout + proc.stderr).splitlines() if ln.startswith("error: ")]
    assert len(errors) == 1, proc.stderr[-2000:]
    assert "mine.yaml" in errors[0] and "'no_such_method'" in errors[0]


def test_peers_and_a_variant_are_accepted(tmp_path):
    proc = dry_run(tmp_path, '[era, hdmd, "pem:paper"]')
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "identify/pem_paper" in proc.stdout + proc.stderr
