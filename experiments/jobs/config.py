"""Structured-config schemas (Hydra ConfigStore). YAML files under configs/ carry the values.

Each method's schema is generated from its ``Options`` dataclass in ``methods/<name>.py``, so a typo in
``method.options.*`` fails at composition with the key's name, and a new method needs no edit here.
The same holds for paper reproductions (``experiments/paper/*.py`` ``Params``).
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING

import methods


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
class TrackingConfig:
    enabled: bool = True             # log this job to MLflow
    experiment: str = "identify"     # MLflow experiment name


@dataclass
class IdentifyConfig:
    method: Any = MISSING
    data: DataConfig = field(default_factory=DataConfig)
    prior: list[float] | None = None     # a-priori frequencies, rad/s; None: the method config's prior_rad_s
    #                                      (a measurement file: found by a stabilisation diagram)
    n_modes: int | None = None           # a measurement without a prior: at most this many modes
    out: str | None = None               # per-replicate results table (CSV); Snakemake sets it
    grid_name: str = "adhoc"             # the grid this job belongs to (MLflow tags)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    progress: bool = True                # a progress bar over replicates


@dataclass
class ReproduceConfig:
    experiment: Any = MISSING
    out_dir: str = "results/reproduce/${experiment.name}"
    tracking: TrackingConfig = field(default_factory=lambda: TrackingConfig(experiment="paper"))


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


METHOD_CONFIGS = Path(__file__).resolve().parents[2] / "configs" / "method"
PLUGIN_PRIOR_FROM = "akf"     # a plugin without its own prior gets Table 3's (configs/method/akf.yaml)


def plugin_prior(name: str) -> list[float]:
    """The default prior of an installed plugin method: its module's ``PRIOR_RAD_S``, else Table 3's."""
    import yaml

    module = importlib.import_module(methods.plugins()[name])
    prior = getattr(module, "PRIOR_RAD_S", None)
    if prior is None:
        prior = yaml.safe_load((METHOD_CONFIGS / f"{PLUGIN_PRIOR_FROM}.yaml").read_text())["prior_rad_s"]
    return [float(w) for w in prior]


def experiment_schema(name: str, module: str):
    params_cls = importlib.import_module(module).Params
    return dataclasses.make_dataclass(
        f"{name}_experiment",
        [("name", str, field(default=name)),
         ("module", str, field(default=module)),
         ("params", params_cls, field(default_factory=params_cls))])


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


def methods_named_on(argv: list[str]) -> list[str]:
    """The methods a command line selects (``method=pem``, ``method=akf_tuned``), so that only their modules
    are imported; all of them for a sweep or when none is named but the default. Importing every method
    costs ~1 s per job."""
    named = [a.split("=", 1)[1] for a in argv if a.startswith("method=")]
    if any(a in ("-m", "--multirun") for a in argv) or any("," in n for n in named):
        return methods.names()
    method = method_of_config(named[-1]) if named else DEFAULT_METHOD
    return [method] if method else []


DEFAULT_METHOD = "fft"     # configs/identify.yaml


def register(*, dataset: bool = False, with_methods: list[str] | None = None,
             experiments: dict[str, str] | None = None) -> None:
    """Store the schemas an app needs in Hydra's ConfigStore (called once by each app before composition).

    Only what is asked for is imported: a job's start-up time is paid once per job of the grid.
    """
    cs = ConfigStore.instance()
    cs.store(name="identify_schema", node=IdentifyConfig)
    cs.store(name="reproduce_schema", node=ReproduceConfig)
    if dataset:
        from experiments.simulate.datasets import DatasetConfig
        from experiments.simulate.plant import PlantConfig

        cs.store(name="dataset_schema", node=DatasetConfig)
        cs.store(group="plant", name="plant_schema", node=PlantConfig)
    for name in with_methods or []:
        if name not in methods.names():
            continue            # reported by Hydra as an unknown option of the group, with the known names
        try:
            methods.require(name)   # ValueError (one line) when an optional library is missing
        except ValueError:
            if len(with_methods) == 1:
                raise
            continue            # a sweep over every method: those that cannot run are not offered
        node = method_schema(name)
        cs.store(group="method", name=f"{name}_schema", node=node)
        if name in methods.plugins() and not (METHOD_CONFIGS / f"{name}.yaml").exists():
            # a method of another installed package: its config is its schema with a default prior, so that
            # `method=<name>` works (and any grid can name it) without a YAML file in this repository
            cs.store(group="method", name=name, node=method_schema(name, plugin_prior(name)))
    for name, module in (experiments or {}).items():
        cs.store(group="experiment", name=f"{name}_schema", node=experiment_schema(name, module))
