"""Hydra app: simulate one dataset cell (all replicates) and write it atomically.

    python -m experiments.jobs.make_dataset noise_ug=1000 n_samples=256 replicates=20 seed=20261121 out=cell.npz
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from experiments.hydra_app.command_line import run_app
from experiments.hydra_app.config_store import register
from experiments.simulate.datasets import DatasetConfig, check_dataset_config, write_cell

__all__ = ["to_config", "MAX_CELL_BYTES", "cell_bytes", "check", "check_cell_memory", "task", "main"]


def to_config(cfg) -> DatasetConfig:
    return OmegaConf.to_object(cfg)


# Largest cell accepted, bytes of float64 held at once: the R noisy records plus about 64 working columns of
# N samples (the clean response, the Cramér–Rao bound's N × 17 Jacobian and its SVD). 2 GiB leaves room for
# the job on a small machine; the full grid's largest cell (R = 100, N = 2048) needs 2.7 MB.
MAX_CELL_BYTES = 2 * 2**30


def cell_bytes(replicates: int, n_samples: int) -> int:
    """Memory a cell of ``replicates`` × ``n_samples`` needs while it is simulated (see MAX_CELL_BYTES)."""
    return 8 * int(n_samples) * (int(replicates) + 64)


def check(cfg) -> None:
    """Impossible or unaffordable cells, each in one line, before any work."""
    c = to_config(cfg)
    for name in ("noise_ug", "dt_s", "bias_m_s2"):
        value = getattr(c, name)
        if not np.isfinite(value):
            raise ValueError(f"{name} = {value} must be a finite number")
    check_dataset_config(c)
    check_cell_memory(c.replicates, c.n_samples)
    out = str(c.out)
    if not out or out.endswith(("/", os.sep)) or Path(out).is_dir():
        raise ValueError(f"out = '{out}' must name a file (e.g. out=cell.npz), not a folder")


def check_cell_memory(replicates: int, n_samples: int) -> None:
    """Refuse a cell above :data:`MAX_CELL_BYTES` (also checked by the workflow on a grid's cells)."""
    need = cell_bytes(replicates, n_samples)
    if need > MAX_CELL_BYTES:
        raise ValueError(f"replicates × n_samples = {replicates} × {n_samples} needs {need / 2**30:.3g} GiB "
                         f"of memory, above the limit of {MAX_CELL_BYTES / 2**30:g} GiB per cell "
                         f"(experiments/jobs/make_dataset.py): ask for fewer replicates or shorter records")


def task(cfg) -> None:
    path = write_cell(to_config(cfg))
    print(f"wrote {path}")


def main() -> None:
    """The console script ``modal-id-make-dataset`` (pyproject.toml) = ``python -m experiments.jobs.make_dataset``."""
    register(dataset=True)
    run_app("dataset", task, check)


if __name__ == "__main__":
    main()
