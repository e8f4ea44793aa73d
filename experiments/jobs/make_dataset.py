"""Hydra app: simulate one dataset cell (all replicates) and write it atomically.

    python -m experiments.jobs.make_dataset noise_ug=1000 n_samples=256 replicates=20 seed=20261121 out=cell.npz
"""

from __future__ import annotations

from omegaconf import OmegaConf

from experiments.jobs.app import run_app
from experiments.jobs.config import register
from experiments.simulate.datasets import DatasetConfig, check_dataset_config, write_cell


def to_config(cfg) -> DatasetConfig:
    return OmegaConf.to_object(cfg)


def check(cfg) -> None:
    check_dataset_config(to_config(cfg))


def task(cfg) -> None:
    path = write_cell(to_config(cfg))
    print(f"wrote {path}")


def main() -> None:
    """The console script ``modal-id-make-dataset`` (pyproject.toml) = ``python -m experiments.jobs.make_dataset``."""
    register(dataset=True)
    run_app("dataset", task, check)


if __name__ == "__main__":
    main()
