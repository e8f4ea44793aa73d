"""A private PostgreSQL for the tests (Debian's postgresql): a fresh cluster in a scratch folder, one database.

Installs the package with apt-get when no server binaries are present (as root). PostgreSQL refuses to run as
root, so as root the cluster belongs to the ``postgres`` user the package creates.
"""

import glob
import os
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

from _apt import apt_lock


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def server_bindir() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"), key=lambda p: int(p.split("/")[4]))
    return Path(found[-1]).parent if found else None


def unavailable() -> str | None:
    """Why no PostgreSQL can be had here, or None (installing it with apt-get if needed)."""
    if server_bindir() is None:
        if os.geteuid() != 0 or not shutil.which("apt-get"):
            return "PostgreSQL is not installed, and installing it needs root and apt-get"
        env = os.environ | {"DEBIAN_FRONTEND": "noninteractive"}
        with apt_lock():
            subprocess.run(["apt-get", "update", "-qq"], check=True, env=env, capture_output=True)
            subprocess.run(["apt-get", "install", "-y", "-qq", "postgresql"], check=True, env=env,
                           capture_output=True)
    return None if server_bindir() is not None else "apt-get installed postgresql but no initdb was found"


class Postgres:
    """``start()`` a cluster on a free local port with database ``mlflow``; ``url`` for SQLAlchemy; ``stop()``."""

    def __init__(self):
        self.bindir = server_bindir()
        self.as_root = os.geteuid() == 0
        self.dir = Path(tempfile.mkdtemp(prefix="pg-"))   # not under pytest's 0700 folder: postgres must enter it
        self.port = free_port()
        self.url = f"postgresql+psycopg://mlflow@127.0.0.1:{self.port}/mlflow"

    def _run(self, *args: str):
        cmd = [str(self.bindir / args[0]), *args[1:]]
        if self.as_root:
            cmd = ["runuser", "-u", "postgres", "--", *cmd]
        return subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=120)

    def start(self) -> "Postgres":
        if self.as_root:
            shutil.chown(self.dir, "postgres", "postgres")
        data = self.dir / "data"
        self._run("initdb", "-D", str(data), "-U", "mlflow", "--auth=trust", "-E", "UTF8")
        self._run("pg_ctl", "-D", str(data), "-l", str(self.dir / "server.log"), "-w", "start",
                  "-o", f"-p {self.port} -k {self.dir} -c listen_addresses=127.0.0.1")
        self._run("createdb", "-h", "127.0.0.1", "-p", str(self.port), "-U", "mlflow", "mlflow")
        return self

    def stop(self) -> None:
        try:
            self._run("pg_ctl", "-D", str(self.dir / "data"), "-m", "fast", "-w", "stop")
        finally:
            shutil.rmtree(self.dir, ignore_errors=True)
