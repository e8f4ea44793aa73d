"""What a ``snakemake`` command line asks for, read before Snakemake builds the DAG: the grids its targets
name, the targets that name no rule, and a target inside a grid's results that names no cell or method;
each refusal one line (:class:`~experiments.workflow.grids.GridError`)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from experiments.workflow.grids import GridError, Grids, method_config

__all__ = ["requested_grids", "command_line_targets", "unknown_rule_targets", "check_target", "RENAMED_RULES",
           "renamed_rules"]


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
    from snakemake.cli import get_argument_parser  # Snakemake's parser: only the Snakefile's process needs it

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


def check_target(grids: Grids, target: str) -> None:
    """A target inside a grid's results names one of its cells or methods (``results/<grid>/data/<cell>.npz``,
    ``results/<grid>/identify/<method>``): else one line naming what the grid has, where Snakemake would
    print its "No rule to produce" over several lines."""
    parts = Path(target).parts
    if len(parts) < 4 or parts[0] != "results" or parts[1] not in grids.grid_names():
        return
    grid = parts[1]
    if parts[2] == "data":
        cells = grids.cells(grid)
        if Path(parts[3]).stem not in cells or len(parts) > 4 or not parts[3].endswith(".npz"):
            raise GridError(f"error: {target}: not a dataset of grid {grid}; its datasets are "
                            f"results/{grid}/data/<cell>.npz, cells: {', '.join(cells)}")
    elif parts[2] == "identify":
        configs = [method_config(m) for m in grids.load_grid(grid)["methods"]]
        if parts[3] not in configs:
            raise GridError(f"error: {target}: no method '{parts[3]}' in grid {grid}; its methods: "
                            f"{', '.join(configs)}")
        if len(parts) > 4:              # the batch's folder is its output: a file in it is no target
            raise GridError(f"error: {target}: one job writes every cell of {parts[3]} on grid {grid}; ask "
                            f"for the folder results/{grid}/identify/{parts[3]}")


# Rules renamed when the MLflow step was named for what it does (run logging), so that "track" names only
# frequency tracking: the old names work until the next release, with a note.
RENAMED_RULES = {"track": "runlog", "tracking_mlflow": "tracking_runlog"}


def renamed_rules(argv) -> list[str]:
    """The old rule names a command line uses (``--forcerun track``, ``--until tracking_mlflow``, ...), each
    with a one-line note on stderr naming the new spelling. Options' values are words of their own, so the
    words are looked at (a rule name is never a path)."""
    used = []
    for word in map(str, argv):
        for part in word.split(","):
            name = re.split(r"[=:]", part, maxsplit=1)[0]     # --set-threads track=2, --set-resources track:...
            if name in RENAMED_RULES and name not in used:
                used.append(name)
                print(f"note: rule '{name}' is now '{RENAMED_RULES[name]}'; the old name works until the next "
                      f"release", file=sys.stderr)
    return used
