"""Where the project's files are: the one module that knows (every other module asks it).

``configs/`` travels with the code as the package data ``experiments.configs`` (``experiments/configs`` links
to it in the repository; a wheel holds a copy), so Hydra finds it as ``pkg://experiments.configs`` from any
working directory, installed or not, and code that reads a YAML file directly reads it from :data:`CONFIGS`.
The grid schemas are the workflow's (``experiments/workflow/schemas/``).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["PACKAGE", "ROOT", "CONFIG_MODULE", "CONFIGS", "GRIDS", "METHOD_CONFIGS", "TRACKER_CONFIGS",
           "PLANT_CONFIG", "GRID_SCHEMAS"]

PACKAGE = Path(__file__).resolve().parent         # experiments/
ROOT = PACKAGE.parent                              # the checkout: the code's files and its git state
CONFIG_MODULE = "experiments.configs"
CONFIGS = PACKAGE / "configs"                      # the link to configs/ (package data in a wheel)
GRIDS = CONFIGS / "grid"                           # configs/grid/<name>.yaml
METHOD_CONFIGS = CONFIGS / "method"                # configs/method/<config>.yaml
TRACKER_CONFIGS = CONFIGS / "tracker"              # configs/tracker/<tracker>_<variant>.yaml
PLANT_CONFIG = CONFIGS / "plant" / "paper.yaml"    # the grids' base plant
GRID_SCHEMAS = PACKAGE / "workflow" / "schemas"    # grid.yaml, tracking_grid.yaml
