"""One apt-get at a time across the test workers.

The suite runs in parallel (pytest-xdist, ``./run.sh test``); the tests that install Debian's packages
(chromium, PostgreSQL, SLURM) take this lock first, so that two workers wait for each other instead of one
failing on dpkg's lock.
"""
import tempfile
from pathlib import Path

from filelock import FileLock


def apt_lock() -> FileLock:
    return FileLock(Path(tempfile.gettempdir()) / "modal-id-tests-apt.lock", timeout=1800)
