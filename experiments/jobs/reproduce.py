"""Hydra app: reproduce one of the paper's figures or tables.

    python -m experiments.jobs.reproduce experiment=paper_fig3
    python -m experiments.jobs.reproduce experiment=paper_table5 experiment.params.replicates=50

Each experiment is a module with a ``Params`` dataclass and ``run(params, out_dir) -> list[Path]``; its
config is ``configs/experiment/<name>.yaml``. The files it writes are logged to MLflow (experiment
``paper``) unless ``runlog.enabled=false``.
"""

from __future__ import annotations

import importlib
from pathlib import Path

from omegaconf import OmegaConf

from experiments.hydra_app.command_line import run_app
from experiments.hydra_app.config_store import register
from experiments.provenance import canonical_json, digest, git_state
from experiments.runlog.store import log_run, source_tags

__all__ = ["EXPERIMENTS", "task", "flatten", "main"]

# experiment name -> module (configs/experiment/<name>.yaml names the same module)
EXPERIMENTS = {
    "paper_fig3": "experiments.paper.fig3",
    "paper_table5": "experiments.paper.table5",
    "paper_fig4": "experiments.paper.pll_figs",
    "paper_fig5": "experiments.paper.pll_figs",
    "paper_fig6": "experiments.paper.pll_figs",
}


def task(cfg) -> None:
    exp = OmegaConf.to_object(cfg.experiment)
    module = importlib.import_module(cfg.experiment.module)
    out_dir = Path(cfg.out_dir)
    files = module.run(exp.params, out_dir)
    for f in files:
        print(f"wrote {f}")
    if cfg.runlog.enabled:
        params = flatten(OmegaConf.to_container(cfg.experiment.params, resolve=True), "param")
        code = git_state()
        key = f"{cfg.experiment.name}/{digest(canonical_json({'params': params, 'code': code}))}"
        log_run(cfg.runlog.experiment, key, params=params, artifacts=files,
                texts={"config.yaml": OmegaConf.to_yaml(cfg)},
                tags={**source_tags("experiments/jobs/reproduce.py", code), "kind": "paper"})


def flatten(tree: dict, prefix: str) -> dict:
    """Nested config values as flat MLflow parameters: {"a": {"b": 1}} -> {"prefix.a.b": 1}."""
    out = {}
    for key, value in tree.items():
        name = f"{prefix}.{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name))
        else:
            out[name] = value
    return out


def main() -> None:
    """The console script ``modal-id-reproduce`` (pyproject.toml), same as ``python -m experiments.jobs.reproduce``."""
    register(experiments=EXPERIMENTS)
    run_app("reproduce", task)


if __name__ == "__main__":
    main()
