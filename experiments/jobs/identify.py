"""Hydra app: run one method on one dataset cell (all replicates) or on a user's CSV measurement.

    python -m experiments.jobs.identify method=pem data.dataset=results/smoke/data/noise1000ug_n256.npz
    python -m experiments.jobs.identify method=fft data.path=my.csv prior='[3.8,16,26,46]'

On a dataset cell it writes the per-replicate results table (``out``, or ``results.csv`` in the run
directory) and beside it ``<table>.json``, the job's record: its resolved config, the dataset's digest,
the code version and package versions (what the workflow's runlog step reads). On a CSV it prints the
estimates and writes ``estimate.json`` in the run directory. Either way the job is logged to MLflow unless
``runlog.enabled=false`` (the workflow logs in one serial step): a cell's job in the experiment
``runlog.experiment`` (default ``identify``), a user's CSV in the experiment ``measurements``.
"""

from __future__ import annotations

import csv
import io
import json
import sys
import time
from pathlib import Path

import numpy as np
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import OmegaConf
from tqdm import tqdm

import methods
from experiments import provenance
from experiments.config_schema import variant_label
from experiments.hydra_app.command_line import fail, run_app
from experiments.hydra_app.config_store import methods_named_on, register
from experiments.io import CHECKSUM_KEY, atomic_write_text, read_npz, write_json
from experiments.report.scoring import COLUMNS, replicate_rows
from experiments.runlog.store import check_store
from experiments.simulate.datasets import CELL_KEYS
from experiments.simulate.scenarios import AXES, result_columns

__all__ = ["load_data", "prior_of", "priors_of", "scenario_of", "check", "LONG_RECORD_SAMPLES", "run_records",
           "task", "run_job", "rows_to_csv", "job_record", "main"]


def load_data(cfg) -> dict:
    """The records to identify: ``y`` (R × N), ``dt`` and, for a dataset cell, the truth; for a measurement
    file, the segment chosen (:mod:`experiments.jobs._identify_file`)."""
    d = cfg.data
    if (d.dataset is None) == (d.path is None):
        raise ValueError("give exactly one of data.dataset (a generated cell) or data.path (a measurement file)")
    if d.path is not None:
        from experiments.jobs import _identify_file  # pandas and the readers: only for a user's file

        return _identify_file.load(d, None if cfg.prior is None else list(cfg.prior))

    cell = read_npz(d.dataset, required=CELL_KEYS)
    y = cell["accel_m_s2"]
    if d.replicates is not None:
        if d.replicates < 1:
            raise ValueError(f"data.replicates = {d.replicates} must be at least 1")
        y = y[: d.replicates]
    # a cell with a prior-error axis carries the harness's prior per replicate (never the truth)
    priors = cell["prior_rad_s"][: len(y)] if "prior_rad_s" in cell else None
    return {"y": y, "dt": float(cell["dt_s"]), "truth": cell, "source": str(d.dataset), "priors": priors}


def prior_of(cfg) -> np.ndarray:
    prior = cfg.prior if cfg.prior is not None else cfg.method.prior_rad_s
    return np.asarray(list(prior), dtype=float)


def priors_of(cfg, data: dict) -> np.ndarray:
    """One prior per record (R × m): the command line's ``prior`` if given, else the cell's harness prior
    (a prior-error scenario), else the method config's prior."""
    if cfg.prior is None and data.get("priors") is not None:
        return np.asarray(data["priors"], dtype=float)
    return np.tile(prior_of(cfg), (len(data["y"]), 1))


def scenario_of(cell) -> dict:
    """The cell's scenario axis values ({} for a plain noise × length cell)."""
    if cell is None or "scenario_json" not in cell:
        return {}
    return json.loads(str(cell["scenario_json"]))


def check(cfg) -> None:
    """Everything that can be known wrong before any work: data readable, every record and the prior
    sensible, the method's options possible (``methods.check_options``, the contract of methods/__init__.py)."""
    data = load_data(cfg)
    if data["truth"] is None and cfg.prior is None:
        # a measurement without a prior: its modes come from the stabilisation diagram in the job; here the
        # options are checked against one mode in the middle of the band
        if cfg.n_modes is not None and cfg.n_modes < 1:
            raise ValueError(f"n_modes = {cfg.n_modes} must be at least 1")
        mid = np.pi * sum(data["segment"].band_hz) or np.pi / (2 * data["dt"])
        methods.check_options(cfg.method.name, [min(mid, 0.9 * np.pi / data["dt"])], data["dt"],
                              OmegaConf.to_container(cfg.method.options, resolve=True))
        if cfg.runlog.enabled:
            check_store()      # here too: the run is logged by a background process, which no one watches
        return
    priors = priors_of(cfg, data)
    for prior in np.unique(priors, axis=0):
        if data["truth"] is not None and prior.size != data["truth"]["truth_freq_rad_s"].size:
            raise ValueError(f"prior {prior.tolist()} has {prior.size} entries; the dataset has "
                             f"{data['truth']['truth_freq_rad_s'].size} modes")
    for r, rec in enumerate(data["y"]):   # samples finite and physical, prior > 0, increasing, below Nyquist
        try:
            methods.check_inputs(rec, data["dt"], priors[r])
        except ValueError as exc:
            raise ValueError(f"{data['source']}: {exc}" if r == 0 else
                             f"{data['source']}, replicate {r}: {exc}") from None
    methods.check_options(cfg.method.name, priors[0], data["dt"],
                          OmegaConf.to_container(cfg.method.options, resolve=True))
    if cfg.runlog.enabled:
        check_store()          # an empty or corrupt MLflow store: one line now, not a traceback after the work


# A single record this long gets an info line (the progress bar counts records, and there is one).
LONG_RECORD_SAMPLES = 100_000


def run_records(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict, progress: bool):
    """Identify every record (``prior``: one for all, or one row per record); an exception on one record
    marks it failed and the job goes on.

    A method with an ``identify_batch`` (``methods.get_batch``) gets all records in one call; each
    record's runtime is then the batch's time divided by the number of records (the cost per fit in the
    tables is what a cell's fit costs), and any exception in the batch falls back to one call per record,
    where bad input raises and a failure is recorded against the record that raised it, as without it."""
    priors = np.broadcast_to(np.asarray(prior, dtype=float), (len(y), np.shape(prior)[-1]))
    batch = methods.get_batch(name) if len(y) > 1 else None
    if batch is not None:
        t0 = time.perf_counter()
        try:
            ests = batch(y, dt, priors, **options)
        except Exception:  # noqa: BLE001 - rerun per record below: bad input raises there, a failure is recorded
            ests = None
        if ests is not None:
            each = (time.perf_counter() - t0) / len(y)
            if progress:
                print(f"{name}: {len(y)} records in lock-step, {1e3 * each:.3g} ms each", file=sys.stderr,
                      flush=True)
            return [(est, each) for est in ests]
    identify = methods.get(name)
    out = []
    bar = None
    long_single = progress and len(y) == 1 and y.shape[1] >= LONG_RECORD_SAMPLES
    if long_single:
        print(f"info: {name} on one record of {y.shape[1]} samples ({y.shape[1] * dt:.6g} s)...",
              file=sys.stderr, flush=True)
    for r, rec in enumerate(y):
        prior = priors[r]
        t0 = time.perf_counter()
        try:
            est = identify(rec, dt, prior, **options)
        except ValueError:
            if r == 0:
                raise              # bad options: the same for every record, so it is bad input
            est = methods.failed(prior, f"ValueError on replicate {r}: {sys.exc_info()[1]}")
        except Exception as exc:  # noqa: BLE001 - a method bug must not stop the grid; it is recorded
            est = methods.failed(prior, f"{type(exc).__name__}: {exc}")
        out.append((est, time.perf_counter() - t0))
        if bar is None:            # after the first record: no bar fragment before a bad-input error
            bar = _progress(len(y), name, progress)
        bar.update(1)
    if bar is not None:
        bar.close()
    if long_single:
        print(f"info: {name} done in {out[0][1]:.3g} s", file=sys.stderr, flush=True)
    return out


def _progress(total: int, name: str, enabled: bool):
    return tqdm(total=total, desc=name, unit="rep", disable=not enabled or total < 2, file=sys.stderr,
                mininterval=2.0)


def task(cfg) -> float | None:
    """Identify every record; in a sweep (``-m``) or when tracking, return the cell's objective."""
    hydra_cfg = HydraConfig.get()
    return run_job(cfg, Path(hydra_cfg.runtime.output_dir), hydra_cfg.runtime.choices.get("method"),
                   sweep=hydra_cfg.mode == RunMode.MULTIRUN)


def run_job(cfg, run_dir: Path, config_name: str | None, sweep: bool = False) -> float | None:
    """The job of :func:`task` with what it takes from Hydra's runtime given: the run directory, the
    method's config name and whether it is one job of a sweep (also called per cell by the workflow's
    batches, :mod:`experiments.jobs.batch`)."""
    data = load_data(cfg)
    name = cfg.method.name
    label = variant_label(name, cfg.method.variant)
    options = OmegaConf.to_container(cfg.method.options, resolve=True)
    if data["truth"] is None:
        return _run_measurement(cfg, data, run_dir, config_name, options)
    priors = priors_of(cfg, data)
    results = run_records(name, data["y"], data["dt"], priors, options, cfg.progress)
    record = job_record(cfg, data, config_name)
    cell = data["truth"]
    scenario = scenario_of(cell)
    rows = []
    for r, (est, runtime) in enumerate(results):
        rows += replicate_rows(label, float(cell["noise_ug"]), int(cell["t_s"].size), r, priors[r],
                               cell["truth_freq_rad_s"], cell["crlb_std_rad_s"],
                               cell["crlb_offset_std_rad_s"], est, runtime)
    for row in rows:              # the cell's scenario axes, as columns after the standard ones
        row.update(result_columns(scenario, row["mode"]))
    out = Path(cfg.out) if cfg.out else run_dir / "results.csv"
    atomic_write_text(out, rows_to_csv(rows))
    record_path = write_json(out.with_suffix(".json"), record)
    print(f"wrote {out} and {record_path}")
    if cfg.runlog.enabled:
        from experiments.runlog.identify_runs import log_job  # pandas (0.4 s): jobs logged to MLflow only

        key, _, created = log_job(cfg.runlog.experiment, record, out, record_path)
        print(f"MLflow experiment {cfg.runlog.experiment}: run {key} ({'logged' if created else 'already there'})")
    if cfg.runlog.enabled or sweep:
        import pandas as pd  # 0.4 s of start-up: only a tracked or swept job scores its cell here

        from experiments.report.objective import cell_objective  # pandas, as above
        from experiments.report.summary import summarize  # pandas, as above

        # A sweeper's objective (any Hydra sweeper minimises what the job returns): log10 of the median
        # RMSE/CRLB over modes + a failure penalty, as the tuning command (experiments/report/objective.py)
        objective = cell_objective(summarize(pd.DataFrame(rows, columns=COLUMNS)))
        print(f"objective {objective['value']:.4g} (median RMSE/CRLB {objective['median_rmse_over_crlb']:.3g}, "
              f"failure rate {objective['failure_rate']:.2f})")
        return objective["value"]
    return None


def rows_to_csv(rows: list[dict]) -> str:
    """The results table as CSV text (the csv module: pandas costs a third of a second per job to import)."""
    buf = io.StringIO()
    extra = [a for a in AXES if rows and a in rows[0]]
    writer = csv.DictWriter(buf, fieldnames=COLUMNS + extra, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def _run_measurement(cfg, data: dict, run_dir: Path, config_name: str | None, options: dict) -> None:
    """A user's measurement: the notes on what was read and chosen, the modes (the prior, or the
    stabilisation diagram's), the method, then the answer, the figure and the MLflow run."""
    from experiments.jobs import _identify_file  # pandas and the readers: only for a user's file

    _identify_file.print_notes(data)
    diagram = None
    if cfg.prior is None:
        prior, diagram = _identify_file.find_modes(data, cfg.n_modes)
        print(f"{diagram.how}: {', '.join(f'{w / (2 * np.pi):.5g}' for w in prior)} Hz")
    else:
        prior = prior_of(cfg)
        methods.check_inputs(data["y"][0], data["dt"], prior)
    options = _identify_file.method_options(options, data)
    est = run_records(cfg.method.name, data["y"], data["dt"], prior, options, cfg.progress)[0][0]
    paths = _identify_file.report(cfg.method.name, prior, est, data, run_dir, diagram)
    if cfg.runlog.enabled:
        _identify_file.log(job_record(cfg, data, config_name), est, paths, run_dir, cfg.runlog.background)


def job_record(cfg, data, config_name: str | None) -> dict:
    """What determines this job's result, written beside its table and keyed in MLflow: the resolved
    config, the dataset (name, content digest, settings), the code version and the package versions."""
    config_name = config_name or cfg.method.name
    if data["truth"] is None:
        dataset = {"name": Path(data["source"]).name, "path": data["source"], "kind": "measurement",
                   "digest": provenance.file_digest(data["source"])}
    else:
        cell = data["truth"]
        dataset = {"name": Path(data["source"]).stem, "path": data["source"], "kind": "cell",
                   "digest": str(cell[CHECKSUM_KEY]),
                   "settings": {"noise_ug": float(cell["noise_ug"]), "n_samples": int(cell["t_s"].size),
                                "seed": int(cell["seed"]), "dt_s": float(cell["dt_s"]),
                                **{f"scenario.{k}": v for k, v in scenario_of(cell).items()}}}
    return {
        "grid": cfg.grid_name,
        "method": variant_label(cfg.method.name, cfg.method.variant),
        "method_config": config_name,
        "config": OmegaConf.to_container(cfg, resolve=True),
        "dataset": dataset,
        "code": {**provenance.git_state(), "method_files": provenance.code_digest(config_name)},
        "versions": json.loads(provenance.package_versions(config_name)),
    }


def main() -> None:
    """The console script ``modal-id-identify`` (pyproject.toml), same as ``python -m experiments.jobs.identify``."""
    try:
        register(with_methods=methods_named_on(sys.argv[1:]))
    except ValueError as exc:          # a method whose optional library is not installed
        fail(str(exc))
    run_app("identify", task, check)


if __name__ == "__main__":
    main()
