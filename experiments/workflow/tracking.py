"""What the tracking rules (experiments/workflow/rules/tracking.smk) need to know of a tracking grid: its name, its
trackers' folders, a runtime request, and the check of a requested grid before the DAG is built (one
``error:`` line and exit status 2 for a bad grid, a bad cell or a bad tracker option)."""

from __future__ import annotations

import functools
import math
import os
import sys

from experiments import paths
from experiments.jobs.track_job import check_tracker, grid_trackers
from experiments.simulate.tracking_grid import load_grid
from experiments.workflow import resources

__all__ = ["CPU_S_PER_SAMPLE", "TRACKING_GRIDS", "check_requested_tracking_grids", "requested", "tracker_dirs",
           "tracking_grid", "tracking_priority", "tracking_runtime"]

TRACKING_GRIDS = sorted(f[: -len(".yaml")] for f in os.listdir(paths.GRIDS)
                        if f.startswith("tracking") and f.endswith(".yaml"))
# A cluster's request per tracker job: 4x a pessimistic 2 ms of CPU per sample, at least 5 minutes (a local
# run ignores it). The measured costs are in each grid's benchmarks/track/<tracker>.tsv.
CPU_S_PER_SAMPLE = 0.002


@functools.cache
def tracking_grid(name: str) -> dict:
    """The grid with its trackers resolved and each tracker's options checked on every cell."""
    grid = load_grid(name)
    grid["tracker_list"] = grid_trackers(grid)
    for tracker in grid["tracker_list"]:
        check_tracker(grid, tracker)
    return grid


def tracker_dirs(name: str) -> list[str]:
    return [f"results/{name}/track/{t}" for t in tracking_grid(name)["tracker_list"]]


def tracking_runtime(wildcards, attempt) -> int:
    grid = tracking_grid(wildcards.tgrid)
    samples = sum(c["config"].n_samples * c["config"].replicates for c in grid["cells"].values())
    return attempt * max(5, math.ceil(4 * CPU_S_PER_SAMPLE * samples / 60))


def tracking_priority(wildcards) -> int:
    """Snakemake priority of a tracker's run job: its known CPU seconds (its last run's benchmark file
    ``results/<grid>/benchmarks/track/<tracker>.tsv``, else the committed ``experiments/workflow/job_cpu_s.csv``,
    else 0), so that the longest trackers start first and the short ones fill both cores at the end: in a
    fresh clone, where every priority was 0, ``era`` (773 s of CPU) started last and ran 9 min alone."""
    return resources.job_priority(paths.ROOT, wildcards.tgrid, f"track/{wildcards.tracker}")


def requested(argv: list[str]) -> list[str]:
    """The tracking grids the command line names: the rule ``tracking`` or a results/<grid>/... file."""
    names = set()
    for target in argv:
        parts = os.path.normpath(str(target)).split(os.sep)
        if target == "tracking":
            names.add("tracking")
        elif len(parts) > 1 and parts[0] == "results" and parts[1] in TRACKING_GRIDS:
            names.add(parts[1])
    return sorted(names)


def check_requested_tracking_grids(argv: list[str]) -> None:
    for name in requested(argv):
        try:
            tracking_grid(name)
        except ValueError as exc:
            print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
            sys.exit(2)
