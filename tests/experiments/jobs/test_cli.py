"""Bad input to the command-line jobs: one clear line, exit status 2, no output left behind."""

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from experiments.simulate.datasets import DatasetConfig, write_cell

ROOT = Path(__file__).resolve().parents[3]


def run(module, *args, cwd):
    return subprocess.run([sys.executable, "-m", module, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=120)


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    write_cell(DatasetConfig(noise_ug=1000, n_samples=64, replicates=2, seed=5, out=str(d / "cell.npz")))
    t = np.arange(256) * 0.02
    (d / "ok.csv").write_text("t,accel\n" + "".join(f"{x:.2f},{np.cos(3 * x):.6f}\n" for x in t))
    (d / "huge.csv").write_text("t,accel\n" + "".join(f"{0.02 * k:.2f},{1e300 if k == 5 else 0.1 * k}\n"
                                                      for k in range(16)))
    (d / "bad.csv").write_text("t,accel\n0,1\n0.02,2\n0.04,oops\n" + "".join(f"{0.06 + 0.02 * k:.2f},1\n"
                                                                          for k in range(8)))
    return d


def assert_one_line_error(proc, *fragments):
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ")
    for f in fragments:
        assert f in lines[0], lines[0]


@pytest.mark.parametrize("args, fragments", [
    (["method=nope"], ["unknown method 'nope'", "fft"]),
    (["method=fft", "data.dataset=cell.npz", "colour=red"], ["colour"]),
    (["method=fft", "data.dataset=cell.npz", "method.options.windw=hann"], ["windw"]),
    (["method=fft", "data.dataset=cell.npz", "method.options.zero_pad_factor=lots"], ["zero_pad_factor", "lots"]),
    (["method=fft", "data.dataset=cell.npz", "prior=[3.8,16,26]"], ["3 entries", "4 modes"]),
    (["method=fft", "data.dataset=cell.npz", "prior=[3.8,0,26,46]"], ["prior[1] = 0.0"]),
    (["method=fft", "data.dataset=cell.npz", "prior=[3.8,16,26,460]"], ["460", "Nyquist"]),
    (["method=fft", "data.path=bad.csv"], ["row 3", "oops"]),
    (["method=fft", "data.path=missing.csv"], ["missing.csv", "does not exist"]),
    (["method=fft", "data.dataset=cell.npz", "prior=[19,19,23,55]"], ["prior[1] = 19", "increasing"]),
    (["method=fft", "data.path=huge.csv", "prior=[2.5]"], ["row 6", "1e+300", "not a physical acceleration"]),
    # option errors of every method: one line, before the first replicate (no progress-bar fragment)
    (["method=pem", "data.dataset=cell.npz", "method.options.n_starts=0"], ["n_starts = 0"]),
    (["method=pem", "data.dataset=cell.npz", "method.options.predictor=bogus"], ["predictor = 'bogus'"]),
    (["method=pem", "data.dataset=cell.npz", "method.options.damping_bounds=[0.5,-0.5]"], ["damping_bounds"]),
    (["method=pem", "data.dataset=cell.npz", "method.options.predictor=kalman", "method.options.tip_mode_shape=[1,2]"],
     ["tip_mode_shape has 2 entries"]),
    (["method=fft", "data.dataset=cell.npz", "method.options.window=bogus"], ["window = 'bogus'"]),
    (["method=akf", "data.dataset=cell.npz", "method.options.measurement=velocity"], ["measurement", "velocity"]),
    (["method=wkf", "data.dataset=cell.npz", "method.options.weight_gain=-1"], ["weight_gain = -1"]),
    (["method=pll", "data.dataset=cell.npz", "method.options.filter_order=0"], ["filter_order = 0"]),
])
def test_identify_rejects_bad_input_with_one_line(workdir, args, fragments):
    before = set(workdir.rglob("*"))
    proc = run("experiments.jobs.identify", *args, "out=res.csv", "hydra.run.dir=run", cwd=workdir)
    assert_one_line_error(proc, *fragments)
    assert set(workdir.rglob("*")) == before          # nothing written, not even Hydra's run folder


@pytest.mark.parametrize("args, fragments", [
    (["noise_ug=0"], ["noise_ug = 0.0 must be positive"]),
    (["noise_ug=-3"], ["noise_ug = -3.0"]),
    (["n_samples=7"], ["n_samples = 7 is too short"]),
    (["n_samples=ten"], ["n_samples", "ten"]),
    (["noise_ug=inf"], ["noise_ug = inf must be a finite number"]),
    (["replicates=1000000000"], ["replicates × n_samples = 1000000000 × 256", "GiB"]),
    (["noise_ug=1e308"], ["noise_ug = 1e+308 is above", "physical"]),
    (["seed=36893488147419103232"], ["seed = 36893488147419103232 must be an integer from 0 to"]),
])
def test_make_dataset_rejects_bad_input_with_one_line(workdir, args, fragments):
    proc = run("experiments.jobs.make_dataset", *args, "out=new.npz", cwd=workdir)
    assert_one_line_error(proc, *fragments)
    assert not (workdir / "new.npz").exists()


@pytest.mark.parametrize("out", ["", "folder/"])
def test_make_dataset_refuses_an_output_that_names_no_file(workdir, out):
    before = set(workdir.rglob("*"))
    proc = run("experiments.jobs.make_dataset", "n_samples=64", "replicates=2", f"out={out}", cwd=workdir)
    assert_one_line_error(proc, f"out = '{out}' must name a file")
    assert set(workdir.rglob("*")) == before


def test_identify_on_a_users_csv_writes_estimate_json(workdir):
    proc = run("experiments.jobs.identify", "method=fft", "data.path=ok.csv", "prior=[2.5]", "hydra.run.dir=mine",
               "runlog.enabled=false", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    import json
    est = json.loads((workdir / "mine" / "estimate.json").read_text())
    assert est["method"] == "fft"
    assert est["frequencies_rad_s"][0] == pytest.approx(3.0, rel=0.01)
    assert set(est) >= {"method", "frequencies_rad_s", "std_rad_s", "converged"}
    assert "mode 1:" in proc.stdout


def test_a_long_single_record_says_what_it_is_doing(workdir):
    """10⁵ samples through fft: an info line before and after (the progress bar counts records, and there is
    one), and the answer."""
    t = np.arange(100_000) * 0.02
    y = np.cos(3.0 * t) + 0.1 * np.random.default_rng(6).standard_normal(t.size)
    (workdir / "long.csv").write_text("t,accel\n" + "".join(f"{a:.2f},{b:.6f}\n" for a, b in zip(t, y, strict=True)))
    # the band up to Nyquist: without it the job would decimate this record to its 0.6-Hz band first
    proc = run("experiments.jobs.identify", "method=fft", "data.path=long.csv", "prior=[2.5]", "hydra.run.dir=long",
               "data.band_hz=25", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    info = [ln for ln in proc.stderr.splitlines() if ln.startswith("info: ")]
    assert len(info) == 2 and "100000 samples" in info[0] and "done in" in info[1], proc.stderr
    assert "mode 1: 3 rad/s" in proc.stdout
    # the job's MLflow run is logged after the answer by a detached logger, into this module's folder: log it
    # now (the command waits for that logger's lock) so that no later test sees files appear in the folder
    done = run("experiments.runlog.pending", cwd=workdir)
    assert done.returncode == 0, done.stderr
    deadline = time.time() + 120
    while (workdir / "long" / "mlflow_pending.json").exists() and time.time() < deadline:
        time.sleep(0.2)
    assert (workdir / "long" / "mlflow_run.json").exists()


def test_an_unbalanced_override_names_it_and_how_to_quote(workdir):
    proc = run("experiments.jobs.identify", "method=fft", "data.dataset=cell.npz", "prior=[1,2",
               "runlog.enabled=false", cwd=workdir)
    assert_one_line_error(proc, "cannot read the override prior=[1,2", "prior='[3.8,16,26,46]'")


def test_a_path_with_non_ascii_letters_is_read(workdir):
    (workdir / "mesure_été.csv").write_text((workdir / "ok.csv").read_text())
    proc = run("experiments.jobs.identify", "method=fft", "data.path=mesure_été.csv", "prior=[3.5]",
               "runlog.enabled=false", "hydra.run.dir=run_été", cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    assert "mode 1: 2.99" in proc.stdout and (workdir / "run_été" / "estimate.json").exists()


def test_quoting_leaves_the_users_own_syntax_alone():
    from experiments.hydra_app.command_line import quote_unicode_value

    assert quote_unicode_value("data.path=été.csv") == "data.path='été.csv'"
    assert quote_unicode_value("data.path='été.csv'") == "data.path='été.csv'"
    assert quote_unicode_value("data.path=plain.csv") == "data.path=plain.csv"
    assert quote_unicode_value("prior=[1,2]") == "prior=[1,2]"
    assert quote_unicode_value("method.options.x=a,é") == "method.options.x=a,é"     # a sweep stands


@pytest.mark.parametrize("args, fragments", [
    (["--nosuch", "method=fft"], ["unknown option --nosuch"]),
    (["method=fft", "data.dataset=cell.npz", "+method._target_=os.system"], ["the job has no key method._target_"]),
    (["method=fft", "data.dataset=cell.npz", "+colour=red"], ["+colour=red: the job has no key colour"]),
    (["method=pem", "method=fft", "data.dataset=cell.npz"], ["method is given twice", "method=pem", "method=fft"]),
    (["-m", "method=fft,nosuch", "data.dataset=cell.npz", "runlog.enabled=false"],
     ["method=nosuch (of the sweep method=fft,nosuch)", "unknown method 'nosuch'"]),
    (["method=fft", "data.dataset=cell.npz", "out=" + "d/" * 1500 + "x.csv"], ["folders deep (at most 200)"]),
    (["method=fft", "data.dataset=cell.npz", "out=" + "é" * 200 + ".csv"], ["too long a path"]),
])
def test_a_bad_command_line_is_one_line_and_leaves_nothing(workdir, args, fragments):
    before = set(workdir.rglob("*"))
    proc = run("experiments.jobs.identify", *args, cwd=workdir)
    assert_one_line_error(proc, *fragments)
    assert set(workdir.rglob("*")) == before          # no run folder, no multirun folder


@pytest.mark.parametrize("module, args, fragments", [
    ("experiments.jobs.track_job", [], ["the following arguments are required: step, grid, --out"]),
    ("experiments.runlog.identify_runs", ["--nosuch"], ["the following arguments are required: --grid"]),
    ("experiments.report.aggregate", [], ["required"]),
    ("experiments.tuning.compare", ["--methods"], ["--methods"]),
])
def test_a_bad_command_line_of_an_argparse_command_is_one_line(workdir, module, args, fragments):
    proc = run(module, *args, cwd=workdir)
    assert_one_line_error(proc, *fragments, "--help")
