"""The workflow's Python: a grid (``configs/grid/<name>.yaml``) loaded, checked and turned into targets.

The Snakefile and ``experiments/rules/*.smk`` only call this module; everything here is plain Python with
unit tests (tests/experiments/jobs/test_workflow_grids.py). A grid is checked, before any job runs, for
everything a job would refuse, each refusal one line ``error: <grid file>: <what>`` (:class:`GridError`):

- the schema (``configs/grid/schema.yaml``, with the failing key) and finite numbers (no ``.nan``, ``.inf``);
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

import dataclasses
import functools
import json
import math
import os
import re
from pathlib import Path

import jsonschema
import yaml

import methods
from experiments.config_schema import method_of_config
from experiments.jobs.make_dataset import check_cell_memory
from experiments.simulate import scenarios
from experiments.simulate.datasets import check_noise_and_seed
from experiments.simulate.plant import PlantConfig
from experiments.tracking import provenance

__all__ = ["GridError", "Workflow", "method_config", "requested_grids"]

# Cost model of the cluster resources (see experiments/rules/common.smk for the measurement): CPU seconds per
# replicate × sample of the costliest method (pem) and of the dataset job.
CPU_S_PER_SAMPLE = 0.0035
DATASET_CPU_S_PER_SAMPLE = 0.0001


class GridError(ValueError):
    """A grid the workflow refuses; ``str()`` is the one line to print (``error: <file>: <what>``)."""


def method_config(entry: str) -> str:
    """The Hydra method config of a grid's methods entry: ``pem`` -> ``pem``, ``pem:paper`` -> ``pem_paper``."""
    return entry.replace(":", "_")


def _one_line(text) -> str:
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


def requested_grids(targets: list[str], known: list[str]) -> list[str]:
    """The grids a command line's targets ask for: a named rule (``smoke``) or a file ``results/<grid>/...``.

    Snakemake has not parsed its targets when it reads the Snakefile, so the words are looked at. A target
    under ``results/`` that climbs out (``..``) or names no grid file is refused (:class:`GridError`); other
    words (options, their values, rule names) are left to Snakemake.
    """
    names = set()
    for target in targets:
        target = str(target)
        if target in known:
            names.add(target)
            continue
        parts = Path(target).parts
        if not parts or parts[0] != "results":
            continue
        if ".." in parts:
            raise GridError(f"error: {target}: a target may not climb out of results/ with '..'")
        if len(parts) > 2 and parts[1] not in known:
            raise GridError(f"error: {target}: no grid '{parts[1]}' (configs/grid/{parts[1]}.yaml); "
                            f"known grids: {', '.join(known)}")
        if len(parts) > 1 and parts[1] in known:
            names.add(parts[1])
    return sorted(names)


def command_line_targets(argv) -> list[str]:
    """The targets of a ``snakemake`` command line, as Snakemake's own argument parser reads them (an
    option's value is never taken for a target); none when it cannot parse them (a cluster job's own line)."""
    from snakemake.cli import get_argument_parser

    try:
        return list(get_argument_parser().parse_args(list(argv)).targets or [])
    except (SystemExit, Exception):  # noqa: BLE001 - an unparsable line is Snakemake's to refuse, not ours
        return []


def unknown_rule_targets(targets, rules, root) -> list[str]:
    """The targets Snakemake would answer with its multi-line "No rule to produce": a bare word (a rule's
    shape, no path) that names no rule of the workflow and no file in ``root``."""
    return [str(t) for t in targets
            if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", str(t)) and str(t) not in rules
            and not (Path(root) / str(t)).exists()]


class Workflow:
    """The grids of one checkout (``root``: the folder of the Snakefile and of ``configs/``)."""

    def __init__(self, root):
        self.root = Path(root)
        self.grid_dir = self.root / "configs" / "grid"
        self.method_dir = self.root / "configs" / "method"
        self.schema = yaml.safe_load((self.grid_dir / "schema.yaml").read_text())

    # ---- loading and checking -----------------------------------------------------------------------------

    def grid_names(self) -> list[str]:
        """Grid names are the file names; a grid is read only when a target asks for it, so one malformed
        file never breaks the other grids. The tracking grids (``tracking*.yaml``) have their own schema and
        rules (experiments/rules/tracking.smk, experiments/jobs/tracking_targets.py)."""
        return sorted(p.stem for p in self.grid_dir.glob("*.yaml")
                      if not p.name.startswith(("schema", "tracking")))

    @functools.cache  # noqa: B019 - one Workflow per Snakemake process; the cache is its lifetime
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
            raise GridError(f"error: {path}: {_one_line(exc)}") from None
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
                raise GridError(f"error: {path}: yardstick_prior: {_one_line(exc)}") from None
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
                node = json.loads(self.resolved_config(config, tuple(overrides)))
                prior = provenance.overridden_prior(config, tuple(overrides), str(self.root))
                for dt in dts:
                    methods.check_options(method_of_config(config), node["prior_rad_s"] if prior is None else prior,
                                          dt, node["options"])
            except Exception as exc:  # noqa: BLE001 - Hydra's and the method's refusals alike become one line
                raise GridError(f"error: {path}: method_overrides of {entry}: {_one_line(exc)}") from None

    def _plant_config(self) -> PlantConfig:
        """The grids' base plant (configs/plant/paper.yaml), to check scenario cells against it."""
        values = yaml.safe_load((self.root / "configs" / "plant" / "paper.yaml").read_text())
        return PlantConfig(**{k: v for k, v in values.items() if k != "defaults"})

    def check_target(self, target: str) -> None:
        """A target inside a grid's results names one of its cells or methods (``results/<grid>/data/<cell>.npz``,
        ``results/<grid>/identify/<method>``): else one line naming what the grid has, where Snakemake would
        print its "No rule to produce" over several lines."""
        parts = Path(target).parts
        if len(parts) < 4 or parts[0] != "results" or parts[1] not in self.grid_names():
            return
        grid = parts[1]
        if parts[2] == "data":
            cells = self.cells(grid)
            if Path(parts[3]).stem not in cells or len(parts) > 4 or not parts[3].endswith(".npz"):
                raise GridError(f"error: {target}: not a dataset of grid {grid}; its datasets are "
                                f"results/{grid}/data/<cell>.npz, cells: {', '.join(cells)}")
        elif parts[2] == "identify":
            configs = [method_config(m) for m in self.load_grid(grid)["methods"]]
            if parts[3] not in configs:
                raise GridError(f"error: {target}: no method '{parts[3]}' in grid {grid}; its methods: "
                                f"{', '.join(configs)}")
            if len(parts) > 4:              # the batch's folder is its output: a file in it is no target
                raise GridError(f"error: {target}: one job writes every cell of {parts[3]} on grid {grid}; ask "
                                f"for the folder results/{grid}/identify/{parts[3]}")

    # ---- what a grid runs ---------------------------------------------------------------------------------

    def cells(self, grid: str) -> list[str]:
        return list(self.load_grid(grid)["cells"])

    @staticmethod
    @functools.cache
    def has_option(config: str, option: str) -> bool:
        """Whether the method of a config has the keyword option (asked of the registry's ``Options``)."""
        fields = dataclasses.fields(methods.options_class(method_of_config(config)))
        return option in {f.name for f in fields}

    def runs_cell(self, grid: str, config: str, cell: str) -> bool:
        """Whether a method runs on a cell: a ``measurement`` cell only for methods with that option."""
        measurement = self.load_grid(grid)["cells"][cell]["axes"].get("measurement")
        return measurement is None or self.has_option(config, "measurement")

    def method_cells(self, grid: str, config: str) -> list[str]:
        return [c for c in self.cells(grid) if self.runs_cell(grid, config, c)]

    def result_files(self, grid: str) -> list[str]:
        g = self.load_grid(grid)
        return [f"results/{grid}/identify/{method_config(m)}/{c}.csv" for m in g["methods"]
                for c in self.method_cells(grid, method_config(m))]

    def identify_dirs(self, grid: str) -> list[str]:
        """The identify batches' folders of a grid (each holds the tables and records of its method)."""
        return [f"results/{grid}/identify/{method_config(m)}" for m in self.load_grid(grid)["methods"]]

    def experiment_dirs(self, grid: str) -> list[str]:
        return [f"results/{grid}/paper/{e}" for e in self.load_grid(grid).get("experiments", [])]

    @staticmethod
    def grid_targets(grid: str) -> list[str]:
        return [f"results/{grid}/README.md", f"results/{grid}/mlflow_runs.json"]

    def dataset_args(self, grid: str, cell_name: str) -> list[str]:
        """make_dataset's command-line overrides of one cell (the plain cells: exactly those of before)."""
        g = self.load_grid(grid)
        cell = g["cells"][cell_name]
        axes = cell["axes"]
        args = [f"noise_ug={cell['noise_ug']}", f"n_samples={cell['n_samples']}", f"replicates={g['replicates']}",
                f"seed={g['seed']}", f"dt_s={axes.get('dt_s', g['dt_s'])}",
                f"bias_m_s2={axes.get('bias_m_s2', g['bias_m_s2'])}"]
        for axis, value in axes.items():
            if axis not in ("dt_s", "bias_m_s2"):
                text = "[" + ",".join(str(v) for v in value) + "]" if isinstance(value, list) else str(value)
                args.append(f"scenario.{axis}={text}")
        named = [a for a in ("dt_s", "bias_m_s2") if a in axes]
        if named:
            args.append(f"scenario.axes=[{','.join(named)}]")
        return args

    def dataset_jobs(self, grid: str) -> list[list[str]]:
        """The datasets batch: one make_dataset command line per cell (experiments/jobs/batch.py)."""
        return [self.dataset_args(grid, c) + [f"out=results/{grid}/data/{c}.npz"] for c in self.cells(grid)]

    def grid_method_overrides(self, grid: str, config: str, loaded: dict | None = None) -> list[str]:
        """The grid's extra overrides of a method (keyed by its grid entry or config name)."""
        g = loaded if loaded is not None else self.load_grid(grid)
        extra = g.get("method_overrides") or {}
        out = list(extra.get(config, []))
        for entry in g["methods"]:
            if method_config(entry) == config and entry != config:
                out += extra.get(entry, [])
        return out

    def cell_overrides(self, grid: str, config: str, cell: str) -> list[str]:
        """The method's overrides on one cell: the grid's, and the cell's measurement axis."""
        out = self.grid_method_overrides(grid, config)
        measurement = self.load_grid(grid)["cells"][cell]["axes"].get("measurement")
        if measurement is not None:
            out.append(f"method.options.measurement={measurement}")
        return out

    def identify_jobs(self, grid: str, config: str) -> list[list[str]]:
        """The identify batch of a (grid, method): one identify command line per cell."""
        jobs = [[f"method={config}", f"data.dataset=results/{grid}/data/{c}.npz",
                 f"out=results/{grid}/identify/{config}/{c}.csv", f"grid_name={grid}", "tracking.enabled=false",
                 *self.cell_overrides(grid, config, c)] for c in self.method_cells(grid, config)]
        if not jobs:
            raise GridError(f"error: grid {grid}: method {config} runs on none of its cells")
        return jobs

    # ---- the Bayesian yardstick (experiments/simulate/yardstick.py) ----------------------------------------

    @functools.cache  # noqa: B019 - one Workflow per Snakemake process
    def yardstick_prior(self, config: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(μ, s) of the yardstick: the method config's ``prior_rad_s`` and ``options.prior_std_rad_s``, one
        home for the prior a grid is scored against (the paper grid: pem_map's)."""
        if not (self.method_dir / f"{config}.yaml").exists():
            raise ValueError(f"'{config}': no configs/method/{config}.yaml")
        node = json.loads(self.resolved_config(config))
        mu = node.get("prior_rad_s")
        std = (node.get("options") or {}).get("prior_std_rad_s")
        if mu is None or std is None:
            raise ValueError(f"'{config}' states no prior_rad_s and options.prior_std_rad_s")
        std = [float(std)] * len(mu) if isinstance(std, (int, float)) else std
        if len(std) != len(mu):
            raise ValueError(f"'{config}': {len(mu)} prior frequencies but {len(std)} prior_std_rad_s")
        return tuple(map(float, mu)), tuple(map(float, std))

    def yardstick_files(self, grid: str) -> list[str]:
        """The grid's yardstick table, or none when the grid names no ``yardstick_prior``."""
        return [f"results/{grid}/yardstick.csv"] if "yardstick_prior" in self.load_grid(grid) else []

    def yardstick_cells(self, grid: str) -> list[str]:
        """The dataset files the yardstick reads: the grid's plain cells (no scenario axis)."""
        g = self.load_grid(grid)
        return [f"results/{grid}/data/{c}.npz" for c, cell in g["cells"].items() if not cell["axes"]]

    def yardstick_args(self, grid: str) -> str:
        """The yardstick job's prior options."""
        mu, std = self.yardstick_prior(self.load_grid(grid)["yardstick_prior"])
        return (f"--prior-rad-s {' '.join(f'{v:g}' for v in mu)} "
                f"--prior-std-rad-s {' '.join(f'{v:g}' for v in std)}")

    # ---- what a job's result depends on (Snakemake's rerun triggers) --------------------------------------

    def method_code(self, config: str) -> list[str]:
        return [str(self.root / f) for f in provenance.method_code_files(config, str(self.root))]

    def resolved_config(self, config: str, overrides: tuple[str, ...] = ()) -> str:
        if not (self.method_dir / f"{config}.yaml").exists():
            return provenance.canonical_json({"plugin": config, "overrides": overrides})
        return provenance.resolved_method_config(config, tuple(overrides), str(self.root))

    def method_versions(self, config: str) -> str:
        return provenance.package_versions(config, str(self.root))

    # ---- cluster resources ----------------------------------------------------------------------------------

    def _samples(self, grid: str, cell_names: list[str]) -> int:
        g = self.load_grid(grid)
        return sum(g["replicates"] * int(g["cells"][c]["n_samples"]) for c in cell_names)

    def identify_runtime(self, grid: str, config: str, attempt: int) -> int:
        """Minutes for one identify batch: 4x the measured cost of its cells, at least 2 min, doubled per retry."""
        work = self._samples(grid, self.method_cells(grid, config))
        return attempt * max(2, math.ceil(4 * CPU_S_PER_SAMPLE * work / 60))

    def dataset_runtime(self, grid: str, attempt: int) -> int:
        """Minutes for the datasets batch: 4x its measured cost, at least 5 min, doubled per retry."""
        work = self._samples(grid, self.cells(grid))
        return attempt * max(5, math.ceil(4 * DATASET_CPU_S_PER_SAMPLE * work / 60))
