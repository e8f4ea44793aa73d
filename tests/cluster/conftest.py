import pytest
from _smoke import snakemake


@pytest.fixture(scope="session")
def local_smoke(tmp_path_factory):
    """The smoke grid run locally once (default SQLite store), the reference of the SLURM and server tests."""
    workdir = tmp_path_factory.mktemp("local_smoke")
    proc = snakemake(workdir, "--cores", "2", "smoke")
    assert proc.returncode == 0, proc.stderr[-3000:]
    return workdir
