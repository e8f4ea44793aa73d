"""The installed package works without the repository: a non-editable wheel in a fresh venv, run elsewhere.

Builds the wheel of this repository, installs it (``--no-deps``) into a new virtual environment whose only
other packages are this environment's site-packages (added by a ``.pth`` line, which does not run this
environment's editable-install hook, so the repository itself is not importable there), and from a scratch
directory runs the console script ``modal-id-identify`` on a CSV of the simulated tip acceleration. Checks that
the code and the Hydra configs come from the wheel (``pkg://experiments.configs``), and that the fft estimate
is within 1 % of the truth for four well-separated modes at low noise.
"""

import json
import shutil
import site
import subprocess
import sys
import venv
from pathlib import Path

import numpy as np
import pytest

from experiments.simulate.plant import PlantConfig, build_plant

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wheel")
    # built from a copy: setuptools writes build/ and *.egg-info beside the sources
    src = tmp / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src)
    for name in ("methods", "experiments", "configs"):
        shutil.copytree(ROOT / name, src / name, symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(tmp / "dist"),
                           str(src)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    wheel = next((tmp / "dist").glob("spacecraft_modal_id-*.whl"))
    env_dir = tmp / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    py = env_dir / "bin" / "python"
    target = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                            capture_output=True, text=True, check=True).stdout.strip()
    (Path(target) / "host_env.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    proc = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--quiet",
                           str(wheel)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    yield env_dir
    shutil.rmtree(tmp, ignore_errors=True)


def test_the_wheel_holds_code_and_configs_and_imports_from_site_packages(installed, tmp_path):
    py = installed / "bin" / "python"
    code = ("import experiments, methods; from importlib import resources; "
            "print(experiments.__file__); print(methods.__file__); "
            "print(resources.files('experiments.configs').joinpath('identify.yaml').is_file())")
    out = subprocess.run([str(py), "-c", code], capture_output=True, text=True, check=True, cwd=tmp_path)
    exp_file, meth_file, has_config = out.stdout.split()
    assert str(installed) in exp_file and str(installed) in meth_file       # not the repository's copy
    assert has_config == "True"


def test_identify_console_script_runs_on_a_csv_outside_the_repository(installed, tmp_path):
    plant = build_plant(PlantConfig())
    dt, n = 0.02, 1024
    t = dt * np.arange(n)
    accel = plant.tip_acceleration(n, dt) + 10 * 9.80665e-6 * np.random.default_rng(5).standard_normal(n)
    np.savetxt(tmp_path / "my.csv", np.column_stack([t, accel]), delimiter=",", header="t,accel", comments="")
    proc = subprocess.run([str(installed / "bin" / "modal-id-identify"), "method=fft", "data.path=my.csv",
                           "prior=[3.5,19.5,22.5,55]"], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    estimate = json.loads(next(tmp_path.glob("results/runs/*_fft/estimate.json")).read_text())
    assert np.allclose(estimate["frequencies_rad_s"], plant.truth()["freq_rad_s"], rtol=0.01)


def test_an_unknown_method_is_one_line_from_the_installed_script(installed, tmp_path):
    proc = subprocess.run([str(installed / "bin" / "modal-id-identify"), "method=nosuch"], capture_output=True,
                          text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: unknown method 'nosuch'; known: ") and "fft" in proc.stderr
    assert not (tmp_path / "results").exists()
