"""A grid (``configs/grid/<name>.yaml``) loaded and checked: :class:`Grids`, the grids of one checkout.

The rules (``experiments/workflow/rules/*.smk``) call this package; everything here is plain Python with unit
tests (tests/experiments/workflow/test_grids.py). What a loaded grid runs is :mod:`.targets`, what a
command line asks for :mod:`.command_line`, what a job's result depends on :mod:`.triggers`, the cluster
requests :mod:`.resources`, the tracking grids :mod:`.tracking`. A grid is checked, before any job runs, for
everything a job would refuse, each refusal one line ``error: <grid file>: <what>`` (:class:`GridError`):

- the schema (``experiments/workflow/schemas/grid.yaml``, with the failing key) and finite numbers (no
  ``.nan``, ``.inf``);
- its name matches its file, each method it names is registered (or an installed plugin) with its library;
- every cell is possible (``experiments.simulate.scenarios.check_grid``) and affordable: the 2 GiB bound of a
  dataset job (``experiments.jobs.make_dataset.check_cell_memory``), a physical noise level and a seed that
  fits an int64 (``experiments.simulate.datasets.check_noise_and_seed``);
- the options a grid's ``method_overrides`` set, composed by Hydra with the method's config and checked by
  the method's own ``check_options`` (an unknown key, ``n_starts=-1``) at each sample interval of the grid,
  with the prior the overrides give (``prior=...``, resolved) or the method's.

A method's options are asked of the registry (``methods.options_class``), never read from its YAML files.
"""

from __future__ import annotations

import functools
import json
import math
import os
from pathlib import Path

import jsonschema
import yaml

import methods
from experiments import paths, provenance
from experiments.config_schema import method_of_config
from experiments.jobs.make_dataset import check_cell_memory
from experiments.simulate import scenarios
from experiments.simulate.datasets import check_noise_and_seed
from experiments.simulate.plant import PlantConfig
from experiments.workflow.triggers import resolved_config

__all__ = ["GridError", "Grids", "method_config", "one_line"]

SCHEMA = paths.GRID_SCHEMAS / "grid.yaml"


class GridError(ValueError):
    """A grid the workflow refuses; ``str()`` is the one line to print (``error: <file>: <what>``)."""


def method_config(entry: str) -> str:
    """The Hydra method config of a grid's methods entry: ``pem`` -> ``pem``, ``pem:paper`` -> ``pem_paper``."""
    return entry.replace(":", "_")


def one_line(text) -> str:
    return " ".join(str(text).split())


def _non_finite(value, where: str = ""):
    """The key path of the first NaN or infinity in a YAML value (None when every number is finite)."""
    if isinstance(value, float) and not math.isfinite(value):
        return where or "(top level)"
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return None
    for key, item in items:
        found = _non_finite(item, f"{where}.{key}" if where else str(key))
        if found:
            return found
    return None


class Grids:
    """The grids of one checkout (``root``: the folder of the Snakefile and of ``configs/``), each read and
    checked once, when first asked for."""

    def __init__(self, root=paths.ROOT):
        self.root = Path(root)
        self.grid_dir = self.root / "configs" / "grid"
        self.method_dir = self.root / "configs" / "method"
        self.schema = yaml.safe_load(SCHEMA.read_text())

    def grid_names(self) -> list[str]:
        """Grid names are the file names; a grid is read only when a target asks for it, so one malformed
        file never breaks the other grids. The tracking grids (``tracking*.yaml``) have their own schema and
        rules (experiments/workflow/rules/tracking.smk, :mod:`experiments.workflow.tracking`)."""
        return sorted(p.stem for p in self.grid_dir.glob("*.yaml")
                      if not p.name.startswith("tracking"))

    @functools.cache  # noqa: B019 - one Grids per Snakemake process; the cache is its lifetime
    def load_grid(self, name: str) -> dict:
        """The grid ``configs/grid/<name>.yaml``, checked (see the module's docstring), with its cells."""
        path = os.path.relpath(self.grid_dir / f"{name}.yaml")
        if name not in self.grid_names():
            raise GridError(f"error: {path}: no such grid; known grids: {', '.join(self.grid_names())}")
        try:
            with open(path) as f:
                grid = yaml.safe_load(f)
            if not isinstance(grid, dict):
                raise ValueError("the file must be a mapping of keys (name, noise_ug, n_samples, ...)")
        except (OSError, ValueError, yaml.YAMLError) as exc:
            raise GridError(f"error: {path}: {one_line(exc)}") from None
        bad = _non_finite(grid)
        if bad:
            raise GridError(f"error: {path}: {bad}: not a finite number")
        try:
            jsonschema.validate(grid, self.schema)
        except jsonschema.ValidationError as exc:
            key = ".".join(map(str, exc.absolute_path)) or "(top level)"
            raise GridError(f"error: {path}: {key}: {exc.message}") from None
        for key, spec in self.schema["properties"].items():     # the schema's defaults (dt_s, bias_m_s2)
            if "default" in spec:
                grid.setdefault(key, spec["default"])
        if grid["name"] != name:
            raise GridError(f"error: {path}: name: '{grid['name']}' must match the file name '{name}'")
        self._check_methods(path, grid)
        try:
            grid["cells"] = scenarios.check_grid(grid, self._plant_config())
            for cell_name, cell in grid["cells"].items():
                try:
                    check_cell_memory(grid["replicates"], cell["n_samples"])
                    check_noise_and_seed(cell["noise_ug"], grid["seed"])
                except ValueError as exc:
                    raise ValueError(f"cell {cell_name}: {exc}") from None
        except ValueError as exc:
            raise GridError(f"error: {path}: {exc}") from None
        self._check_overrides(path, grid)
        if "yardstick_prior" in grid:
            try:
                self.yardstick_prior(grid["yardstick_prior"])
            except ValueError as exc:
                raise GridError(f"error: {path}: yardstick_prior: {one_line(exc)}") from None
        return grid

    def _check_methods(self, path: str, grid: dict) -> None:
        """Each method a grid names must have a config (or be an installed plugin) and its library."""
        for entry in grid["methods"]:
            config = method_config(entry)
            method = method_of_config(config)
            has_config = (self.method_dir / f"{config}.yaml").exists()
            if method is None or not (has_config or config in methods.plugins()):
                raise GridError(f"error: {path}: unknown method '{entry}' (no configs/method/{config}.yaml "
                                f"and no installed plugin of that name)")
            try:
                methods.require(method)
            except ValueError as exc:
                raise GridError(f"error: {path}: {exc}") from None

    def _check_overrides(self, path: str, grid: dict) -> None:
        """The options each method runs with, after the grid's overrides, checked as its job would."""
        for name in grid.get("method_overrides") or {}:
            if name not in grid["methods"] and name not in map(method_config, grid["methods"]):
                raise GridError(f"error: {path}: method_overrides.{name}: not a method of the grid")
        dts = sorted({float(c["axes"].get("dt_s", grid["dt_s"])) for c in grid["cells"].values()})
        for entry in grid["methods"]:
            config = method_config(entry)
            overrides = self.grid_method_overrides(grid["name"], config, grid)
            if not overrides or not (self.method_dir / f"{config}.yaml").exists():
                continue
            try:
                node = json.loads(resolved_config(self.root, config, tuple(overrides)))
                prior = provenance.overridden_prior(config, tuple(overrides), str(self.root))
                for dt in dts:
                    methods.check_options(method_of_config(config), node["prior_rad_s"] if prior is None else prior,
                                          dt, node["options"])
            except Exception as exc:  # noqa: BLE001 - Hydra's and the method's refusals alike become one line
                raise GridError(f"error: {path}: method_overrides of {entry}: {one_line(exc)}") from None

    def _plant_config(self) -> PlantConfig:
        """The grids' base plant (configs/plant/paper.yaml), to check scenario cells against it."""
        values = yaml.safe_load((self.root / "configs" / "plant" / "paper.yaml").read_text())
        return PlantConfig(**{k: v for k, v in values.items() if k != "defaults"})

    def cells(self, grid: str) -> list[str]:
        return list(self.load_grid(grid)["cells"])

    def grid_method_overrides(self, grid: str, config: str, loaded: dict | None = None) -> list[str]:
        """The grid's extra overrides of a method (keyed by its grid entry or config name)."""
        g = loaded if loaded is not None else self.load_grid(grid)
        extra = g.get("method_overrides") or {}
        out = list(extra.get(config, []))
        for entry in g["methods"]:
            if method_config(entry) == config and entry != config:
                out += extra.get(entry, [])
        return out

    @functools.cache  # noqa: B019 - one Grids per Snakemake process
    def yardstick_prior(self, config: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(μ, s) of the yardstick: the method config's ``prior_rad_s`` and ``options.prior_std_rad_s``, one
        home for the prior a grid is scored against (the paper grid: pem_map's)."""
        if not (self.method_dir / f"{config}.yaml").exists():
            raise ValueError(f"'{config}': no configs/method/{config}.yaml")
        node = json.loads(resolved_config(self.root, config))
        mu = node.get("prior_rad_s")
        std = (node.get("options") or {}).get("prior_std_rad_s")
        if mu is None or std is None:
            raise ValueError(f"'{config}' states no prior_rad_s and options.prior_std_rad_s")
        std = [float(std)] * len(mu) if isinstance(std, (int, float)) else std
        if len(std) != len(mu):
            raise ValueError(f"'{config}': {len(mu)} prior frequencies but {len(std)} prior_std_rad_s")
        return tuple(map(float, mu)), tuple(map(float, std))
