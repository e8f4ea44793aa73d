"""Run one of the Hydra apps on many override sets in one process: the workflow's batch jobs.

    python -m experiments.jobs.batch dataset  '[["noise_ug=10", "n_samples=64", ..., "out=a.npz"], ...]'
    python -m experiments.jobs.batch identify '[["method=pem", "data.dataset=a.npz", "out=a.csv"], ...]'

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

import json
import sys
import time
from pathlib import Path

from hydra import compose, initialize_config_module
from omegaconf import OmegaConf, open_dict

from experiments.jobs.app import CONFIG_MODULE, fail, one_line

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


def _compose(app: str, overrides: list[str]):
    """The job's config as ``hydra.main`` would pass it, and the method's config name (for identify)."""
    cfg = compose(config_name=app, overrides=overrides, return_hydra_config=True)
    choice = cfg.hydra.runtime.choices.get("method")
    with open_dict(cfg):
        del cfg["hydra"]
    OmegaConf.resolve(cfg)
    return cfg, choice


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or args[0] not in APPS:
        fail(f"usage: python -m experiments.jobs.batch {{{'|'.join(APPS)}}} JOBS_JSON (got {len(args)} arguments)")
    app = args[0]
    try:
        jobs = parse_jobs(args[1])
    except ValueError as exc:
        fail(str(exc))
    from experiments.jobs.config import methods_named_on, register

    if app == "dataset":
        from experiments.jobs import make_dataset as module

        register(dataset=True)
    else:
        from experiments.jobs import identify as module

        try:
            register(with_methods=sorted({m for j in jobs for m in methods_named_on(j)}))
        except ValueError as exc:
            fail(str(exc))
    configs = []
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        for i, overrides in enumerate(jobs):
            try:
                cfg, choice = _compose(app, overrides)
                module.check(cfg)
            except Exception as exc:  # noqa: BLE001 - every composition/validation error is bad input
                fail(f"{_label(i, len(jobs), overrides)}: {one_line(exc)}")
            configs.append((cfg, choice))
    t0 = time.perf_counter()
    for i, (cfg, choice) in enumerate(configs):
        if app == "dataset":
            module.task(cfg)
        else:
            module.run_job(cfg, Path(cfg.out).parent, choice)
        print(f"{_label(i, len(jobs), jobs[i])} done", flush=True)
    print(f"{len(jobs)} {app} jobs in {time.perf_counter() - t0:.3g} s", flush=True)


if __name__ == "__main__":
    main()
