"""The jobs' structured-config schemas (Hydra ConfigStore nodes) and how method configs are named.

Below every stage: the jobs register these schemas, and the provenance (``experiments.provenance``)
composes a method's config with them to key its runs. YAML files under configs/ carry the values; each
method's node is generated from its ``Options`` dataclass (:func:`method_schema`), so a typo in
``method.options.*`` fails at composition with the key's name, and a removed YAML value falls back to the
very ``Options`` default.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import yaml
from omegaconf import MISSING

import methods
from experiments import paths

__all__ = ["DataConfig", "RunlogConfig", "IdentifyConfig", "ReproduceConfig", "method_schema",
           "method_of_config", "variant_label", "stated_options", "METHOD_CONFIG_DIR"]

# configs/ travels with the code as experiments/configs (a link in the repository, package data when installed)
METHOD_CONFIG_DIR = paths.METHOD_CONFIGS


@dataclass
class DataConfig:
    """Where the measurements come from: a generated dataset cell, or a user's measurement file
    (docs/measurements.md: .csv, .uff/.unv, .lvm, .tdms, .mat, chosen by extension)."""

    dataset: str | None = None       # a .npz cell written by experiments.jobs.make_dataset
    path: str | None = None          # a measurement file (experiments/recordings/read.py)
    replicates: int | None = None    # use only the first k replicates of a cell (None: all)
    channel: str | None = None       # the channel of a multi-channel file
    units: str | None = None         # g, m/s^2 or mm/s^2, for a file that names no unit
    dt: float | None = None          # sample interval, s, for a file without time stamps
    start_s: float | None = None     # span to identify (file time); None: after the largest impulse
    stop_s: float | None = None      # None: the end of the record
    band_hz: Any = None              # hi or [lo, hi], Hz; None: from the spectrum


@dataclass
class RunlogConfig:
    enabled: bool = True             # log this job to MLflow
    experiment: str = "identify"     # MLflow experiment name
    background: bool = True          # a measurement's run: logged by a detached process after the answer
    #                                  (experiments/runlog/pending.py); false: by the job itself


@dataclass
class IdentifyConfig:
    method: Any = MISSING
    data: DataConfig = field(default_factory=DataConfig)
    prior: list[float] | None = None     # a-priori frequencies, rad/s; None: the method config's prior_rad_s
    #                                      (a measurement file: found by a stabilisation diagram)
    n_modes: int | None = None           # a measurement without a prior: at most this many modes
    out: str | None = None               # per-replicate results table (CSV); Snakemake sets it
    grid_name: str = "adhoc"             # the grid this job belongs to (MLflow tags)
    runlog: RunlogConfig = field(default_factory=RunlogConfig)
    progress: bool = True                # a progress bar over replicates


@dataclass
class ReproduceConfig:
    experiment: Any = MISSING
    out_dir: str = "results/reproduce/${experiment.name}"
    runlog: RunlogConfig = field(default_factory=lambda: RunlogConfig(experiment="paper"))


def method_schema(name: str, prior=MISSING):
    """The config node of method ``name``: its name, its prior, and its Options."""
    options_cls = methods.options_class(name)
    return dataclasses.make_dataclass(
        f"{name}_method",
        [("name", str, field(default=name)),
         ("variant", str, field(default="default")),
         ("prior_rad_s", list[float], field(default_factory=lambda: prior) if prior is not MISSING
          else field(default=MISSING)),
         ("options", options_cls, field(default_factory=options_cls))])


def method_of_config(config_name: str) -> str | None:
    """The registered method a method config names: ``akf`` for ``akf`` and for a variant ``akf_tuned``
    (``configs/method/<method>_<variant>.yaml``; the longest registered prefix wins), None if none does."""
    known = methods.names()
    if config_name in known:
        return config_name
    prefixes = [m for m in known if config_name.startswith(m + "_")]
    return max(prefixes, key=len) if prefixes else None


def variant_label(method: str, variant: str) -> str:
    """How tables, figures and MLflow name a method variant: ``akf`` (default config) or ``akf:tuned``."""
    return method if variant in ("", "default") else f"{method}:{variant}"


def stated_options(config_name: str) -> dict:
    """The options a method config sets itself: the ``options:`` mapping of ``configs/method/<name>.yaml``,
    in file order. For a variant (``pem_paper``) that is what it changes from its method's ``Options``
    defaults; for a method's own config, what differs from them (the paper's per-mode tables).

    Raises
    ------
    ValueError
        When no such config file exists.
    """
    path = METHOD_CONFIG_DIR / f"{config_name}.yaml"
    if not path.is_file():
        raise ValueError(f"method config '{config_name}': no file configs/method/{config_name}.yaml")
    return dict((yaml.safe_load(path.read_text()) or {}).get("options") or {})
