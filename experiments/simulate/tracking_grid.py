"""A tracking grid (``configs/grid/tracking*.yaml``): its validation and its cells.

A grid names schedules and excitations (each a mapping of settings, see ``schedules.ScheduleConfig`` and
``tracking_data.ExcitationConfig``) and lists ``noise_ug`` and ``duration_s``; its cells are the product
schedule × excitation × noise × duration, named ``<schedule>_<excitation>_noise{x}ug_{T}s``. The grid is
checked whole before any work: the schema (``experiments/workflow/schemas/tracking_grid.yaml``), then every cell
(``tracking_data.check_cell_config``: a schedule that crosses modes or reaches Nyquist, an empty
excitation, a record too short), each failure one line naming the file, the cell and the value.
A grid's ``exclude`` lists (schedule, excitation) pairs left out of the product (a class of excitation
that only some schedules need); a pair that names no schedule or excitation of the grid is refused. An item
with a ``tracker`` leaves that tracker out of the cells its schedule and/or excitation select (a laboratory
cell's schedule is its name, its excitation ``laboratory``), e.g. a variant whose per-mode options fit only
the four-mode plant; they are kept as ``grid["tracker_exclude"]``, (tracker, schedule, excitation) with None
for "any". Which trackers run is the job's business (``experiments.jobs.track_job``); this module knows no
method.

A grid may also list ``laboratory`` cells (:mod:`experiments.simulate.laboratory`): name -> settings (the
fields of ``LaboratoryConfig``, and ``noise_ug``/``duration_s`` of the cell, defaults 300 µg and 12 s), one
cell each, named ``<name>_laboratory_noise{x}ug_{T}s`` (schedule = the name, excitation = ``laboratory``),
with the grid's replicates, seed and prior spread. :func:`make_grid_cell` simulates either kind.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import jsonschema
import yaml
from omegaconf import OmegaConf

from experiments import paths
from experiments.simulate.laboratory import LAB_KEYS, LaboratoryCellConfig, check_laboratory, make_lab_cell
from experiments.simulate.plant import PlantConfig
from experiments.simulate.schedules import ScheduleConfig
from experiments.simulate.tracking_data import (
    ExcitationConfig,
    TrackingCellConfig,
    cell_name,
    check_cell_config,
    make_cell,
)

__all__ = ["SCHEMA", "DEFAULTS", "LABORATORY", "grid_path", "load_grid", "make_grid_cell", "nominal_prior_rad_s",
           "paper_plant"]

LABORATORY = "laboratory"          # the excitation name of a laboratory cell (its moves ring the beam)

SCHEMA = paths.GRID_SCHEMAS / "tracking_grid.yaml"
# The schema's defaults (dt_s, prior_spread): their one home is the schema.
DEFAULTS = {k: v["default"] for k, v in yaml.safe_load(SCHEMA.read_text())["properties"].items() if "default" in v}


def grid_path(name_or_path: str) -> Path:
    """``configs/grid/<name>.yaml`` for a name, or the path itself."""
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml"):
        return p
    return paths.GRIDS / f"{name_or_path}.yaml"


def paper_plant() -> PlantConfig:
    """The grids' plant, configs/plant/paper.yaml (read by OmegaConf, whose YAML reads ``70.0e9`` as a number)."""

    values = OmegaConf.to_container(OmegaConf.load(paths.PLANT_CONFIG))
    return PlantConfig(**{k: v for k, v in values.items() if k != "defaults"})


def load_grid(name_or_path: str, *, check_cells: bool = True) -> dict:
    """The grid, validated, with ``cells``: name -> :class:`TrackingCellConfig`. ``ValueError`` (one line,
    naming the file and the key or the cell) for a bad grid."""

    path = grid_path(name_or_path)
    if not path.is_file():
        raise ValueError(f"{path}: no such tracking grid")
    try:
        grid = yaml.safe_load(path.read_text())
        if not isinstance(grid, dict):
            raise ValueError("the file must be a mapping of keys (name, noise_ug, schedules, ...)")
        jsonschema.validate(grid, yaml.safe_load(SCHEMA.read_text()))
    except jsonschema.ValidationError as exc:
        key = ".".join(map(str, exc.absolute_path)) or "(top level)"
        raise ValueError(f"{path}: {key}: {' '.join(exc.message.split())}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: {' '.join(str(exc).split())}") from None
    if path.stem != grid["name"] and path.parent == paths.GRIDS:
        raise ValueError(f"{path}: name: '{grid['name']}' must match the file name '{path.stem}'")
    for key, value in DEFAULTS.items():
        grid.setdefault(key, value)
    grid.setdefault("tracker_options", {})
    excluded, grid["tracker_exclude"] = set(), []
    labs = list(grid.get("laboratory") or {})
    for i, item in enumerate(grid.get("exclude") or []):
        tracker = item.get("tracker")
        knowns = (("schedule", [*grid["schedules"], *labs] if tracker else grid["schedules"]),
                  ("excitation", [*grid["excitations"], *([LABORATORY] if labs else [])] if tracker
                   else grid["excitations"]))
        if tracker and not ("schedule" in item or "excitation" in item):
            raise ValueError(f"{path}: exclude.{i}: tracker '{tracker}' needs a schedule or an excitation whose "
                             f"cells it leaves out")
        for key, known in knowns:
            if key in item and item[key] not in known:
                raise ValueError(f"{path}: exclude.{i}.{key}: '{item[key]}' names no {key} of this grid "
                                 f"({', '.join(known)})")
        if tracker:
            grid["tracker_exclude"].append((str(tracker), item.get("schedule"), item.get("excitation")))
        else:
            excluded.add((item["schedule"], item["excitation"]))
    plant = paper_plant()
    cells = {}
    for (sname, sched), (ename, exc_), noise, duration in itertools.product(
            grid["schedules"].items(), grid["excitations"].items(), grid["noise_ug"], grid["duration_s"]):
        if (sname, ename) in excluded:
            continue
        name = cell_name(sname, ename, noise, duration)
        cfg = TrackingCellConfig(schedule=ScheduleConfig(**(sched or {})), excitation=ExcitationConfig(**(exc_ or {})),
                                 noise_ug=float(noise), duration_s=float(duration), dt_s=float(grid["dt_s"]),
                                 replicates=int(grid["replicates"]), seed=int(grid["seed"]),
                                 prior_spread=float(grid["prior_spread"]), plant=plant)
        if check_cells:
            try:
                check_cell_config(cfg)
            except ValueError as exc:
                raise ValueError(f"{path}: cell {name}: {exc}") from None
        cells[name] = {"config": cfg, "schedule": sname, "excitation": ename, "noise_ug": float(noise),
                       "duration_s": float(duration)}
    for lname, settings in (grid.get("laboratory") or {}).items():
        settings = dict(settings or {})
        noise, duration = float(settings.pop("noise_ug", 300.0)), float(settings.pop("duration_s", 12.0))
        name = cell_name(lname, LABORATORY, noise, duration)
        cfg = LaboratoryCellConfig(lab={k: v for k, v in settings.items() if k in LAB_KEYS}, noise_ug=noise,
                                   duration_s=duration, replicates=int(grid["replicates"]), seed=int(grid["seed"]),
                                   prior_spread=float(grid["prior_spread"]))
        if check_cells:
            try:
                check_laboratory(cfg)
            except ValueError as exc:
                raise ValueError(f"{path}: cell {name}: {exc}") from None
        cells[name] = {"config": cfg, "schedule": lname, "excitation": LABORATORY, "noise_ug": noise,
                       "duration_s": duration}
    grid["cells"] = cells
    return grid


def make_grid_cell(cfg) -> dict:
    """The records of a grid's cell, either kind (a spacecraft cell or a laboratory cell)."""
    return make_lab_cell(cfg) if isinstance(cfg, LaboratoryCellConfig) else make_cell(cfg)


def nominal_prior_rad_s(cfg) -> list[float]:
    """A prior typical of the cell, for checking tracker options before any record exists."""
    if isinstance(cfg, LaboratoryCellConfig):
        return [float(w) for w in cfg.nominal_prior_rad_s]
    return [float(w) for w in cfg.plant.target_freq_rad_s]
