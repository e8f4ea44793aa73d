"""A method from another installed package joins the benchmark through the entry-point group
``spacecraft_modal_id.methods``: it appears in ``methods.names()`` and runs through
``python -m experiments.jobs.identify method=<name>`` with no file of this repository edited.

The test builds a tiny package in tmp_path (pyproject.toml + one module), pip-installs it into the running
environment, and uninstalls it afterwards.
"""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from experiments.simulate.datasets import DatasetConfig, write_cell

ROOT = Path(__file__).resolve().parents[3]
NAME = "tinyplugin_for_tests"

MODULE = '''
"""A toy identifier: the frequencies of the largest periodogram peaks near each prior, no window."""
from dataclasses import dataclass

import numpy as np

from methods.estimate import Estimate, check_inputs, make_options

PRIOR_RAD_S = [3.5, 19.0, 23.0, 55.0]


@dataclass
class Options:
    halfwidth: float = 0.2


def identify(y, dt, prior, **options):
    y, dt, prior = check_inputs(y, dt, prior)
    opts = make_options(Options, options, "{name}")
    n = 1 << 16
    w = 2 * np.pi * np.fft.rfftfreq(n, dt)
    p = np.abs(np.fft.rfft(y - y.mean(), n))
    freq = [w[(w > f * (1 - opts.halfwidth)) & (w < f * (1 + opts.halfwidth))][
            np.argmax(p[(w > f * (1 - opts.halfwidth)) & (w < f * (1 + opts.halfwidth))])] for f in prior]
    return Estimate(np.array(freq), np.full(prior.size, np.nan), message="toy plugin")
'''.replace("{name}", NAME)


@pytest.fixture(scope="module")
def installed_plugin(tmp_path_factory):
    src = tmp_path_factory.mktemp("plugin")
    (src / "pyproject.toml").write_text(textwrap.dedent(f"""
        [build-system]
        requires = ["setuptools>=69"]
        build-backend = "setuptools.build_meta"

        [project]
        name = "{NAME}"
        version = "0.1.0"

        [project.entry-points."spacecraft_modal_id.methods"]
        {NAME} = "{NAME}"
        """))
    (src / f"{NAME}.py").write_text(MODULE)
    pip = [sys.executable, "-m", "pip"]
    proc = subprocess.run([*pip, "install", "--quiet", str(src)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    yield NAME
    subprocess.run([*pip, "uninstall", "--yes", "--quiet", NAME], capture_output=True, timeout=120)


def python(*args, cwd=ROOT):
    return subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_an_installed_plugin_joins_the_registry_and_runs_in_a_job(installed_plugin, tmp_path):
    proc = python("-c", "import methods; print(methods.names()); print(methods.options_class("
                        f"'{installed_plugin}')())")
    assert proc.returncode == 0, proc.stderr
    assert f"'{installed_plugin}'" in proc.stdout and "halfwidth=0.2" in proc.stdout

    cell = tmp_path / "cell.npz"
    write_cell(DatasetConfig(noise_ug=10, n_samples=256, replicates=2, seed=7, out=str(cell)))
    out = tmp_path / "results.csv"
    proc = python("-m", "experiments.jobs.identify", f"method={installed_plugin}", f"data.dataset={cell}",
                  f"out={out}", "runlog.enabled=false", "progress=false", f"hydra.run.dir={tmp_path / 'run'}",
                  "method.options.halfwidth=0.15")
    assert proc.returncode == 0, proc.stderr
    lines = out.read_text().splitlines()
    assert len(lines) == 1 + 2 * 4                                  # header + 2 replicates × 4 modes
    assert all(line.startswith(f"{installed_plugin},") for line in lines[1:])
    # its own default prior (PRIOR_RAD_S); the toy's unwindowed peaks within 2 rad/s of the truth at 10 µg
    import pandas as pd

    table = pd.read_csv(out)
    assert table["prior_rad_s"].tolist()[:4] == [3.5, 19.0, 23.0, 55.0]
    assert (table["error_rad_s"].abs() < 2.0).all()


def test_a_missing_peer_library_is_one_line():
    """A peer whose optional library is absent: one message naming the library (hidden from the import
    system by a None entry in sys.modules, which is how Python marks a module as not importable)."""
    code = ("import sys; sys.modules['control'] = None; "
            "import methods\ntry:\n    methods.require('era')\nexcept ValueError as e:\n    print(e)")
    proc = python("-c", code)
    assert proc.returncode == 0, proc.stderr
    assert "needs the library 'control'" in proc.stdout
