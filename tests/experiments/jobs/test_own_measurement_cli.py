"""Bad input on a user's measurement file: one ``error:`` line naming the file and the problem, exit 2,
nothing written."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("own")
    k = np.arange(4096)
    y = np.where(k > 1000, np.exp(-0.002 * (k - 1000)) * np.sin(0.3 * (k - 1000)), 0.0)
    (d / "two.csv").write_text("t,tip [g],root [g]\n" + "".join(f"{0.001 * i:.3f},{float(a)!r},{float(a) / 2!r}\n"
                                                               for i, a in enumerate(y)))
    (d / "beam.dat").write_text("1,2\n")
    (d / "fake.mat").write_text("t,accel\n0,1\n")
    return d


@pytest.mark.parametrize("args, fragments", [
    (["data.path=beam.dat"], ["beam.dat", "unknown extension '.dat'"]),
    (["data.path=fake.mat"], ["fake.mat", "not a readable MATLAB file"]),
    (["data.path=two.csv"], ["two.csv", "2 channels", "tip, root"]),
    (["data.path=two.csv", "data.channel=mid"], ["two.csv", "no channel 'mid'"]),
    (["data.path=two.csv", "data.channel=tip", "data.units=m/s2"], ["two.csv", "contradicts the file", "in g"]),
    (["data.path=two.csv", "data.channel=tip", "data.start_s=4.05"], ["two.csv", "at least 64 are needed"]),
    (["data.path=two.csv", "data.channel=tip", "data.band_hz=[1,900]"], ["two.csv", "above the Nyquist frequency 500"]),
])
def test_bad_measurement_is_one_error_line_and_nothing_written(workdir, args, fragments):
    proc = subprocess.run([sys.executable, "-m", "experiments.jobs.identify", "method=pem", *args,
                           "hydra.run.dir=out", "runlog.enabled=false"], cwd=workdir, capture_output=True,
                          text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for f in fragments:
        assert f in lines[0], lines[0]
    assert not (workdir / "out").exists()
