"""Outputs that cannot be written are one `error:` line before any work, with nothing left behind: a
read-only results folder (a read-only bind mount, since root ignores permission bits), an output path
under a file."""

from __future__ import annotations

import shlex
import subprocess
import sys

import numpy as np
import pytest

from experiments.simulate.datasets import DatasetConfig, write_cell

JOBS = {
    "identify a cell": "-m experiments.jobs.identify method=fft data.dataset=cell.npz runlog.enabled=false",
    "identify a CSV": "-m experiments.jobs.identify method=fft data.path=my.csv prior=[20,56] runlog.enabled=false",
    "make a dataset": "-m experiments.jobs.make_dataset noise_ug=10 n_samples=64 replicates=2 out=results/c.npz",
}


@pytest.fixture
def folder(tmp_path):
    write_cell(DatasetConfig(noise_ug=1000, n_samples=64, replicates=2, seed=3, out=str(tmp_path / "cell.npz")))
    t = 0.02 * np.arange(128)
    y = np.cos(20.3 * t) + np.cos(56.7 * t)
    (tmp_path / "my.csv").write_text("t,accel\n" + "".join(f"{a:.6f},{b:.9e}\n" for a, b in zip(t, y, strict=True)))
    return tmp_path


def _read_only_run(folder, args: str) -> subprocess.CompletedProcess:
    """Run a job in ``folder`` made read-only by a bind mount in a private mount namespace."""
    script = (f"mount --bind {shlex.quote(str(folder))} {shlex.quote(str(folder))} && "
              f"mount -o remount,bind,ro {shlex.quote(str(folder))} && cd {shlex.quote(str(folder))} && "
              f"{shlex.quote(sys.executable)} {args}")
    return subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True, timeout=120)


def _can_mount_read_only(tmp_path) -> bool:
    probe = subprocess.run(["unshare", "-m", "sh", "-c", f"mount --bind {tmp_path} {tmp_path} && "
                            f"mount -o remount,bind,ro {tmp_path} && ! touch {tmp_path}/x"],
                           capture_output=True, text=True)
    return probe.returncode == 0


@pytest.mark.parametrize("job", JOBS)
def test_a_read_only_folder_is_one_line_and_nothing_written(folder, job):
    if not _can_mount_read_only(folder):
        pytest.skip("this machine does not allow a read-only bind mount in a private mount namespace "
                    "(needs root with CAP_SYS_ADMIN); the check itself is tested below with a path under a file")
    before = sorted(p.name for p in folder.rglob("*"))
    proc = _read_only_run(folder, JOBS[job])
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1, proc.stderr
    assert "read-only or no permission" in proc.stderr
    assert sorted(p.name for p in folder.rglob("*")) == before


@pytest.mark.parametrize("override", ["hydra.run.dir=afile/run", "out=afile/cell.npz"])
def test_an_output_under_a_file_is_one_line_and_nothing_written(folder, override):
    (folder / "afile").write_text("a file, not a folder\n")
    job = ("experiments.jobs.make_dataset noise_ug=10 n_samples=64 replicates=2" if override.startswith("out")
           else "experiments.jobs.identify method=fft data.dataset=cell.npz runlog.enabled=false") + " " + override
    before = sorted(p.name for p in folder.rglob("*"))
    proc = subprocess.run([sys.executable, "-m", *job.split()], cwd=folder, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "afile is a file, not a folder" in proc.stderr, proc.stderr
    assert sorted(p.name for p in folder.rglob("*")) == before
