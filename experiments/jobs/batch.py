"""Run one of the Hydra apps on many override sets in one process: the workflow's batch jobs.

    python -m experiments.jobs.batch dataset  '[["noise_ug=10", "n_samples=64", ..., "out=a.npz"], ...]'
    python -m experiments.jobs.batch identify '[["method=pem", "data.dataset=a.npz", "out=a.csv"], ...]'
    python -m experiments.jobs.batch identify JOBS_JSON --workers 2    # jobs shared by 2 worker processes

Each inner list is exactly the command line of one ``python -m experiments.jobs.make_dataset`` or
``python -m experiments.jobs.identify`` job, and gives the same files: the config is composed by Hydra's
compose API from the same config module, checked by the app's own ``check`` and run by its own job
function. What a batch saves is the process around each job: start-up and imports took ~1.2 s per job
(0.7 s of it ``import scipy.signal``), 37 % of the full grid's job time when every (method, cell) was a
process of its own (measured: ``python -m experiments.benchmarks.pipeline``).

Every job is composed and checked before the first one runs, so bad input gets one line naming the job
(``error: job 3 of 8 (out=...): ...``), exit status 2, and nothing written. An exception inside a method is
recorded per replicate by the app (``experiments.jobs.identify.run_records``), as in a single job.
"""

from __future__ import annotations

import copy
import json
import multiprocessing
import sys
import time
from pathlib import Path

from hydra import compose, initialize_config_module
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf, open_dict

from experiments.hydra_app.command_line import CONFIG_MODULE, fail, one_line
from experiments.hydra_app.config_store import methods_named_on, register

__all__ = ["APPS", "parse_jobs", "PER_JOB_KEYS", "Composer", "main"]

APPS = ("dataset", "identify")


def parse_jobs(text: str) -> list[list[str]]:
    """The jobs' override lists from JSON text: a non-empty list of lists of strings."""
    try:
        jobs = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"the jobs are not JSON ({exc})") from None
    if not (isinstance(jobs, list) and jobs and all(isinstance(j, list) and all(isinstance(o, str) for o in j)
                                                    for j in jobs)):
        raise ValueError("the jobs must be a non-empty JSON list of lists of override strings")
    return jobs


def _label(i: int, n: int, overrides: list[str]) -> str:
    out = [o for o in overrides if o.startswith("out=")]
    return f"job {i + 1} of {n}" + (f" ({out[0]})" if out else "")


def _compose(app: str, overrides: list[str], resolve: bool = True):
    """The job's config as ``hydra.main`` would pass it, and the method's config name (for identify)."""
    cfg = compose(config_name=app, overrides=overrides, return_hydra_config=True)
    choice = cfg.hydra.runtime.choices.get("method")
    with open_dict(cfg):
        del cfg["hydra"]
    if resolve:
        OmegaConf.resolve(cfg)
    return cfg, choice


# The overrides that change from job to job in the workflow's batches: plain values, no config group. A
# batch composes each distinct rest of the overrides once and sets these on a copy, as Hydra applies a
# ``key=value`` override to the composed config (``OmegaConf.update(cfg, key, value, merge=True)``, type-
# checked against the schema), then resolves. Composing every job took 0.1-0.2 s, 10 s of a 56-cell batch.
PER_JOB_KEYS = ("data.dataset", "out")


class Composer:
    """:func:`_compose` for many jobs, each distinct set of the other overrides composed once."""

    def __init__(self, app: str):
        self.app = app
        self.cache: dict[tuple[str, ...], tuple] = {}
        self.parser = OverridesParser.create()

    def __call__(self, overrides: list[str]):
        keys = [o.split("=", 1)[0] for o in overrides]
        mine = [o for o, k in zip(overrides, keys, strict=True) if k in PER_JOB_KEYS]
        if len({k for k in keys if k in PER_JOB_KEYS}) != len(mine):
            return _compose(self.app, overrides)       # a key given twice: Hydra's own verdict
        base = tuple(o for o, k in zip(overrides, keys, strict=True) if k not in PER_JOB_KEYS)
        if base not in self.cache:
            self.cache[base] = _compose(self.app, list(base), resolve=False)
        cfg, choice = self.cache[base]
        cfg = copy.deepcopy(cfg)
        for override in self.parser.parse_overrides(mine):
            OmegaConf.update(cfg, override.key_or_group, override.value(), merge=True)
        OmegaConf.resolve(cfg)
        return cfg, choice


def main(argv: list[str] | None = None) -> None:
    args = list(sys.argv[1:] if argv is None else argv)
    workers = 1
    if len(args) == 4 and args[2] == "--workers":
        try:
            workers = int(args[3])
        except ValueError:
            workers = 0
        if workers < 1:
            fail(f"--workers {args[3]}: the number of worker processes must be a positive integer")
        args = args[:2]
    if len(args) != 2 or args[0] not in APPS:
        fail(f"usage: python -m experiments.jobs.batch {{{'|'.join(APPS)}}} JOBS_JSON [--workers N] "
             f"(got {len(args)} arguments)")
    app = args[0]
    try:
        jobs = parse_jobs(args[1])
    except ValueError as exc:
        fail(str(exc))

    if app == "dataset":
        from experiments.jobs import make_dataset as module  # only the app asked for: its imports are start-up time

        register(dataset=True)
    else:
        from experiments.jobs import identify as module  # only the app asked for: its imports are start-up time

        try:
            register(with_methods=sorted({m for j in jobs for m in methods_named_on(j)}))
        except ValueError as exc:
            fail(str(exc))
    configs = []
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        composer = Composer(app)
        for i, overrides in enumerate(jobs):
            try:
                cfg, choice = composer(overrides)
                module.check(cfg)
            except Exception as exc:  # noqa: BLE001 - every composition/validation error is bad input
                fail(f"{_label(i, len(jobs), overrides)}: {one_line(exc)}")
            configs.append((cfg, choice))
    t0 = time.perf_counter()
    global _RUN
    _RUN = (app, module, configs, jobs)
    workers = min(workers, len(jobs))
    if workers > 1 and "fork" in multiprocessing.get_all_start_methods():
        # forked workers inherit the checked configs and the imported libraries; each job writes its own
        # files atomically, one job at a time per worker, handed out as workers free up
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            for _ in pool.imap_unordered(_run_one, range(len(jobs)), chunksize=1):
                pass
    else:
        for i in range(len(jobs)):
            _run_one(i)
    print(f"{len(jobs)} {app} jobs in {time.perf_counter() - t0:.3g} s ({workers} worker"
          f"{'s' if workers > 1 else ''})", flush=True)


_RUN: tuple = ()


def _run_one(i: int) -> None:
    """Job ``i`` of the batch being run (``_RUN``, set before the workers fork)."""
    app, module, configs, jobs = _RUN
    cfg, choice = configs[i]
    if app == "dataset":
        module.task(cfg)
    else:
        module.run_job(cfg, Path(cfg.out).parent, choice)
    print(f"{_label(i, len(jobs), jobs[i])} done", flush=True)


if __name__ == "__main__":
    main()
