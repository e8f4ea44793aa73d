"""The jobs' registration of their structured-config schemas in Hydra's ConfigStore.

The schemas themselves (``experiments.config_schema``) sit below every stage; here each app stores the ones it
needs before composition, with only the methods its command line names imported. A paper reproduction's
schema is generated from its ``Params`` (``experiments/paper/*.py``) as a method's is from its ``Options``.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import field

import yaml
from hydra.core.config_store import ConfigStore

import methods
from experiments import paths
from experiments.config_schema import (
    IdentifyConfig,
    ReproduceConfig,
    method_of_config,
    method_schema,
)
from experiments.simulate.datasets import DatasetConfig
from experiments.simulate.plant import PlantConfig

__all__ = ["METHOD_CONFIGS", "PLUGIN_PRIOR_FROM", "plugin_prior", "experiment_schema", "methods_named_on",
           "DEFAULT_METHOD", "register"]

METHOD_CONFIGS = paths.METHOD_CONFIGS
PLUGIN_PRIOR_FROM = "akf"     # a plugin without its own prior gets Table 3's (configs/method/akf.yaml)


def plugin_prior(name: str) -> list[float]:
    """The default prior of an installed plugin method: its module's ``PRIOR_RAD_S``, else Table 3's."""
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
