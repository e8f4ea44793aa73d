"""Automatic tuning of a method's numeric options: Optuna's TPE sampler over a search space declared in
``configs/tuning/<method>.yaml``, on cells simulated with a tuning seed that is never a scoring seed.

    OPENBLAS_NUM_THREADS=1 python -m experiments.tuning.tune tuning=akf
    python -m experiments.tuning.tune tuning=wkf tuning.trials=80 tuning.replicates=10

Objective (``experiments.report.objective``): mean over the cells of log10(median over modes of RMSE/CRLB)
+ penalty × failure rate. Writes ``configs/method/<method>_<variant>.yaml`` (``defaults: [<method>,
_self_]``, ``variant: <variant>``, the tuned options) with the study's provenance in its header; grids name
it ``<method>:<variant>``. A tracking study (``kind: track``, ``configs/tuning/track_<tracker>.yaml``) tunes a
tracker's tracking options on ``track_cells`` (schedule, excitation, noise, duration) with
``experiments.report.objective.track_objective`` and writes ``configs/tracker/<tracker>_<variant>.yaml``,
which tracking grids name ``<tracker>:<variant>`` (``experiments.tracker_variants``).
Every trial is an MLflow child run of one study run (experiment ``tuning``). The
study lives in Optuna's RDB storage (``results/optuna.db``, beside the MLflow store): run the same command
again and it resumes, running only the trials still missing. Why not hydra-optuna-sweeper: it pins
optuna < 3, and a sweep of the identify job scores one cell per job, where a trial here scores several.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from omegaconf import MISSING, OmegaConf

import methods
from experiments import paths
from experiments.config_schema import RunlogConfig, method_of_config, variant_label
from experiments.hydra_app.command_line import run_app
from experiments.hydra_app.config_store import register
from experiments.io import atomic_write_text
from experiments.jobs.identify import run_records
from experiments.jobs.track_job import track_record
from experiments.report.objective import mode_failed, objective, track_objective
from experiments.report.scoring import COLUMNS, replicate_rows
from experiments.report.summary import summarize
from experiments.report.tracking_metrics import score_track
from experiments.runlog.store import DEFAULT_DB, git_commit, log_run
from experiments.simulate import tracking_data
from experiments.simulate.datasets import DatasetConfig, make_cell
from experiments.simulate.tracking_data import TrackingCellConfig, check_cell_config
from experiments.simulate.tracking_grid import DEFAULTS as TRACKING_DEFAULTS
from experiments.simulate.tracking_grid import paper_plant
from experiments.tuning.space import base_params, check_space, suggest_options

__all__ = ["CellConfig", "TrackCellConfig", "TuningConfig", "TuneApp", "scoring_seeds", "check",
           "check_track", "track_base_options", "track_cell_configs", "simulate_track_cells", "evaluate_track",
           "track_cell_label", "track_config_text", "base_method",
           "simulate_cells", "evaluate", "study_name", "storage_url", "task", "config_text", "main"]


@dataclass
class CellConfig:
    noise_ug: float = MISSING
    n_samples: int = MISSING


@dataclass
class TrackCellConfig:
    """A tracking cell of a ``kind: track`` study (``experiments.simulate.tracking_data.TrackingCellConfig``)."""

    name: str = ""                       # the cell's label in the objective's parts (default cell<i>)
    schedule: dict[str, Any] = field(default_factory=dict)
    excitation: dict[str, Any] = field(default_factory=dict)
    noise_ug: float = MISSING
    duration_s: float = 60.0


@dataclass
class TuningConfig:
    """One study. ``method`` is a method config (``configs/method/<method>.yaml``) whose options are the
    starting point; the result is the variant ``<method>:<variant>``."""

    method: str = MISSING
    variant: str = "tuned"
    kind: str = "identify"               # identify: free-decay cells, method options; track: tracking cells
    cells: list[CellConfig] = field(default_factory=list)
    track_cells: list[TrackCellConfig] = field(default_factory=list)   # kind: track
    prior_spread: float = TRACKING_DEFAULTS["prior_spread"]   # kind: track, as the tracking grids
    replicates: int = 10                 # tuning replicates per cell
    seed: int = 1                        # the tuning noise seed; never a grid's scoring seed
    dt_s: float = 0.02
    trials: int = 60                     # total trials of the study (a resumed study runs the rest)
    penalty: float = 4.0                 # decades of RMSE/CRLB per unit failure rate
    sampler_seed: int = 0                # TPE's own random stream
    enqueue_base: bool = True            # trial 0 = the base config's values (where inside the space)
    fixed: dict[str, Any] = field(default_factory=dict)     # options set for every trial
    space: dict[str, Any] = field(default_factory=dict)     # see experiments/tuning/space.py
    out: str | None = None               # default configs/method/<method>_<variant>.yaml (track: configs/tracker/)
    storage: str | None = None           # default sqlite:///results/optuna.db


@dataclass
class TuneApp:
    tuning: Any = MISSING
    runlog: RunlogConfig = field(default_factory=lambda: RunlogConfig(experiment="tuning"))


def scoring_seeds() -> dict[int, list[str]]:
    """The seeds the grids score on (configs/grid/*.yaml ``seed``), with the grids using each."""
    seeds: dict[int, list[str]] = {}
    for path in sorted(paths.GRIDS.glob("*.yaml")):
        seed = OmegaConf.load(path).get("seed")
        if seed is not None:
            seeds.setdefault(int(seed), []).append(path.stem)
    return seeds


def check(cfg) -> None:
    t = cfg.tuning
    used = scoring_seeds()
    if int(t.seed) in used:
        raise ValueError(f"tuning.seed = {t.seed} is the scoring seed of grid(s) {', '.join(used[int(t.seed)])}: "
                         "tune on another seed")
    if t.kind not in ("identify", "track"):
        raise ValueError(f"tuning.kind = '{t.kind}': must be identify or track")
    if t.kind == "track":
        check_track(t)
        return
    if method_of_config(t.method) is None:
        raise ValueError(f"tuning.method = '{t.method}' is not a method config; known methods: "
                         f"{', '.join(methods.names())}")
    if not t.cells:
        raise ValueError("tuning.cells is empty: give at least one {noise_ug, n_samples}")
    for c in t.cells:
        if not (c.noise_ug > 0 and c.n_samples >= 8):
            raise ValueError(f"tuning.cells: noise_ug = {c.noise_ug} must be > 0 and n_samples = {c.n_samples} ≥ 8")
    if t.replicates < 1 or t.trials < 1:
        raise ValueError(f"tuning.replicates = {t.replicates} and tuning.trials = {t.trials} must be ≥ 1")
    base = base_method(t.method)
    options = OmegaConf.to_container(base.options, resolve=True)
    check_space(OmegaConf.to_container(t.space, resolve=True), set(options), len(base.prior_rad_s), options)
    unknown = set(t.fixed) - set(options)
    if unknown:
        raise ValueError(f"tuning.fixed: {sorted(unknown)} are not options of {t.method}")


def track_base_options(t) -> dict:
    """A tracking study's starting point: the tracker's defaults (the grids' plain row) with ``fixed`` over."""

    defaults = dataclasses.asdict(methods.track_options_class(t.method)())
    return {**defaults, **OmegaConf.to_container(t.fixed, resolve=True)}


def track_cell_configs(t) -> list:

    plant = paper_plant()
    return [TrackingCellConfig(schedule=OmegaConf.to_container(c.schedule, resolve=True),
                               excitation=OmegaConf.to_container(c.excitation, resolve=True),
                               noise_ug=float(c.noise_ug), duration_s=float(c.duration_s), dt_s=float(t.dt_s),
                               replicates=int(t.replicates), seed=int(t.seed), prior_spread=float(t.prior_spread),
                               plant=plant)
            for c in t.track_cells]


def check_track(t) -> None:

    if t.method not in methods.track_names():
        raise ValueError(f"tuning.method = '{t.method}' is not a tracker; known: {', '.join(methods.track_names())}")
    if not t.track_cells:
        raise ValueError("tuning.track_cells is empty: give at least one {schedule, excitation, noise_ug, duration_s}")
    if t.replicates < 1 or t.trials < 1:
        raise ValueError(f"tuning.replicates = {t.replicates} and tuning.trials = {t.trials} must be ≥ 1")
    unknown = set(t.fixed) - {f for f in methods.track_options_class(t.method).__dataclass_fields__}
    if unknown:
        raise ValueError(f"tuning.fixed: {sorted(unknown)} are not tracking options of {t.method}")
    base = track_base_options(t)
    cfgs = []
    for i, cfg in enumerate(track_cell_configs(t)):
        try:
            check_cell_config(cfg)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"tuning.track_cells[{i}]: {' '.join(str(exc).split())}") from None
        cfgs.append(cfg)
    nominal = np.asarray(cfgs[0].plant.target_freq_rad_s, dtype=float)
    check_space(OmegaConf.to_container(t.space, resolve=True), set(base), nominal.size, base)
    for cfg in cfgs:
        methods.check_track_options(t.method, nominal, cfg.dt_s, base, n_samples=cfg.n_samples)


def base_method(config_name: str):
    """The composed method config (its prior and options) the study starts from."""
    if GlobalHydra.instance().is_initialized():        # inside the Hydra app
        return compose(config_name="identify", overrides=[f"method={config_name}"]).method
    with initialize_config_dir(config_dir=str(paths.CONFIGS), version_base="1.3"):   # the pre-check
        return compose(config_name="identify", overrides=[f"method={config_name}"]).method


def simulate_cells(t) -> list[dict]:
    return [make_cell(DatasetConfig(noise_ug=float(c.noise_ug), n_samples=int(c.n_samples),
                                    replicates=int(t.replicates), dt_s=float(t.dt_s), seed=int(t.seed)))
            for c in t.cells]


def evaluate(name: str, label: str, prior, options: dict, cells: list[dict], penalty: float):
    """Run the method on every replicate of every cell; the objective's parts and the summary table."""
    rows = []
    for cell in cells:
        results = run_records(name, cell["accel_m_s2"], float(cell["dt_s"]), prior, options, progress=False)
        for r, (est, runtime) in enumerate(results):
            rows += replicate_rows(label, float(cell["noise_ug"]), int(cell["t_s"].size), r, prior,
                                   cell["truth_freq_rad_s"], cell["crlb_std_rad_s"],
                                   cell["crlb_offset_std_rad_s"], est, runtime)
    summary = summarize(pd.DataFrame(rows, columns=COLUMNS))
    return objective(summary, penalty), summary


def study_name(t) -> str:
    """Name = output config + digest of everything that defines the objective, so that a changed study
    definition starts a new study instead of mixing incomparable trials."""
    spec = OmegaConf.to_container(t, resolve=True)
    for k in ("trials", "out", "storage"):
        spec.pop(k, None)
    if t.kind == "identify":         # the identify studies keep the names they had before tracking studies
        for k in ("kind", "track_cells", "prior_spread"):
            spec.pop(k, None)
    digest = hashlib.sha256(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:8]
    return f"{t.method}_{'track_' if t.kind == 'track' else ''}{t.variant}-{digest}"


def simulate_track_cells(t) -> list[dict]:

    return [tracking_data.make_cell(cfg, bounds=False) for cfg in track_cell_configs(t)]


def track_cell_label(c, i: int) -> str:
    return f"{c.name or f'cell{i}'}_{c.noise_ug:g}ug_{c.duration_s:g}s"


def evaluate_track(name: str, options: dict, cells: list[dict], labels: list[str], penalty: float):
    """Run the tracker on every record of every cell; the objective's parts and the per-record table."""

    rows = []
    for label, cell in zip(labels, cells, strict=True):
        dt = float(cell["dt_s"])
        truth = cell["truth_freq_rad_s"]
        for r in range(cell["accel_m_s2"].shape[0]):
            tr, message = track_record(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], options)
            if tr is None:
                rows.append({"cell": label, "replicate": r, "error": np.nan, "failed_share": 1.0, "message": message})
                continue
            s = score_track(tr.t_s, tr.frequencies, tr.converged, tr.runtime_s, truth, dt)
            err = s["err_rel_median"] if np.isfinite(s["err_rel_median"]) else s["err_rel_median_late"]
            failed = mode_failed(tr.t_s, tr.frequencies, truth, dt)
            rows.append({"cell": label, "replicate": r, "error": err, "failed_share": float(failed.mean()),
                         "message": ""})
    table = pd.DataFrame(rows)
    return track_objective(table, penalty), table


def storage_url(t) -> str:
    if t.storage:
        return t.storage

    DEFAULT_DB.parent.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{(DEFAULT_DB.parent / 'optuna.db').resolve()}"


def task(cfg) -> None:
    import optuna  # optional extra (.[tuning])

    t = cfg.tuning
    space = OmegaConf.to_container(t.space, resolve=True)
    if t.kind == "track":
        name = t.method
        base_options = track_base_options(t)
        cells = simulate_track_cells(t)
        labels = [track_cell_label(c, i) for i, c in enumerate(t.track_cells)]
        n_modes = cells[0]["prior_rad_s"].shape[1]

        def evaluate_options(options):
            return evaluate_track(name, options, cells, labels, float(t.penalty))[0]
    else:
        base = base_method(t.method)
        name = method_of_config(t.method)
        label = variant_label(name, t.variant)
        prior = np.asarray(list(base.prior_rad_s), dtype=float)
        n_modes = prior.size
        base_options = {**OmegaConf.to_container(base.options, resolve=True),
                        **OmegaConf.to_container(t.fixed, resolve=True)}
        cells = simulate_cells(t)

        def evaluate_options(options):
            return evaluate(name, label, prior, options, cells, float(t.penalty))[0]
    sname = study_name(t)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = optuna.create_study(study_name=sname, storage=storage_url(t), direction="minimize",
                                sampler=optuna.samplers.TPESampler(seed=int(t.sampler_seed)),
                                load_if_exists=True)
    _fail_stale(study)
    if t.enqueue_base and not study.trials:
        study.enqueue_trial(base_params(space, base_options, n_modes), user_attrs={"base": True})
    parent = _log_study(cfg, sname) if cfg.runlog.enabled else None

    def trial_objective(trial):
        options = {**base_options, **suggest_options(trial, space, base_options, n_modes)}
        t0 = time.perf_counter()
        parts = evaluate_options(options)
        for k, v in parts.items():
            trial.set_user_attr(k, v)
        print(f"trial {trial.number}: J = {parts['value']:.4g} ({time.perf_counter() - t0:.1f} s)", flush=True)
        if parent is not None:
            _log_trial(cfg, sname, parent, trial, options, parts)
        return parts["value"]

    done = sum(tr.state.is_finished() for tr in study.trials)
    remaining = max(0, int(t.trials) - done)
    print(f"study {sname}: {done} trials done, running {remaining}", flush=True)
    study.optimize(trial_objective, n_trials=remaining, catch=(ValueError, np.linalg.LinAlgError))
    best = study.best_trial
    tuned = {**OmegaConf.to_container(t.fixed, resolve=True),
             **suggest_options(optuna.trial.FixedTrial(best.params), space, base_options, n_modes)}
    if t.kind == "track":
        out = Path(t.out) if t.out else paths.TRACKER_CONFIGS / f"{t.method}_{t.variant}.yaml"
        text = track_config_text(t, sname, study, best, tuned)
    else:
        out = Path(t.out) if t.out else paths.METHOD_CONFIGS / f"{t.method}_{t.variant}.yaml"
        text = config_text(t, name, sname, study, best, tuned)
    atomic_write_text(out, text)
    print(f"best trial {best.number}: J = {best.value:.4g}\nwrote {out}")
    if parent is not None:
        log_run(cfg.runlog.experiment, f"tuning/{sname}/best{len(study.trials)}", params=_flat(tuned),
                metrics={"best_value": best.value, "best_trial": best.number}, artifacts=[out],
                tags={"mlflow.parentRunId": parent, "kind": "tuning-result"})


def _fail_stale(study) -> None:
    """A trial left RUNNING by a killed process is marked failed (this command runs trials one at a time)."""
    from optuna.trial import TrialState  # optional extra (.[tuning])

    for tr in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        study._storage.set_trial_state_values(tr._trial_id, TrialState.FAIL)


def _round(value):
    if isinstance(value, float):
        return float(f"{value:.4g}")
    if isinstance(value, list):
        return [_round(v) for v in value]
    if isinstance(value, dict):
        return {k: _round(v) for k, v in value.items()}
    return value


def config_text(t, name: str, sname: str, study, best, tuned: dict) -> str:
    finished = [tr for tr in study.trials if tr.value is not None]
    base_trials = [tr for tr in finished if tr.user_attrs.get("base")]
    cells = ", ".join(f"{c.noise_ug:g} µg/{c.n_samples}" for c in t.cells)
    attrs = best.user_attrs
    per_cell = "; ".join(
        f"{k.removesuffix('_value')}: median RMSE/CRLB {attrs[k.replace('_value', '_median_rmse_over_crlb')]:.3g}, "
        f"failure rate {attrs[k.replace('_value', '_failure_rate')]:.2f}"
        for k in attrs if k.endswith("_value") and k != "value")
    lines = [
        f'# Variant "{variant_label(name, t.variant)}": configs/method/{t.method}.yaml with options tuned by '
        "experiments.tuning.tune (Optuna TPE).",
        f"# Objective: mean over cells of log10(median over modes of RMSE/CRLB) + {t.penalty:g} x failure rate"
        " (experiments/report/objective.py).",
        f"# Cells: {cells}; tuning seed {t.seed} (never a scoring seed), {t.replicates} replicates per cell, "
        f"dt {t.dt_s:g} s.",
        f"# Trials: {len(study.trials)} ({len(finished)} complete); best trial #{best.number}, J = {best.value:.4g}"
        + (f"; base config (trial #{base_trials[0].number}) J = {base_trials[0].value:.4g}" if base_trials else "")
        + ".",
        f"# Best trial per cell: {per_cell}.",
        f"# Study: {sname} in {_shown(storage_url(t))}; MLflow experiment 'tuning', run key tuning/{sname}.",
        f"# Date: {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}; git {git_commit()}.",
        "# Command: python -m experiments.tuning.tune " + " ".join(sys.argv[1:]),
        "# Values rounded to 4 significant digits.",
    ]
    body = {"defaults": [t.method, "_self_"], "variant": t.variant, "options": _round(tuned)}
    return "\n".join(lines) + "\n" + OmegaConf.to_yaml(OmegaConf.create(body))


def track_config_text(t, sname: str, study, best, tuned: dict) -> str:
    """The variant file of a tracking study (``experiments.tracker_variants``) with its provenance."""
    finished = [tr for tr in study.trials if tr.value is not None]
    base_trials = [tr for tr in finished if tr.user_attrs.get("base")]
    attrs = best.user_attrs
    cells = [k.removesuffix("_value") for k in attrs if k.endswith("_value")]
    per_cell = "; ".join(f"{c}: median error {100 * attrs[c + '_median_error']:.3g} % of ω, failed modes "
                         f"{attrs[c + '_failure_rate']:.2f}" for c in cells)
    lines = [
        f'# Tracker variant "{t.method}:{t.variant}": the tracking options of {t.method} (its defaults, the grids\' '
        f"plain {t.method} row) with these over them, tuned by experiments.tuning.tune (Optuna TPE).",
        f"# Objective: mean over cells of log10(median over records of the median tracking error / ω after "
        f"convergence) + {t.penalty:g} x share of (record, mode) never converged or diverged "
        "(experiments/report/objective.py, track_objective).",
        f"# Cells: {', '.join(track_cell_label(c, i) for i, c in enumerate(t.track_cells))}; tuning seed "
        f"{t.seed} (never a scoring seed), {t.replicates} records per cell, dt {t.dt_s:g} s, "
        f"prior spread {t.prior_spread:g}.",
        f"# Trials: {len(study.trials)} ({len(finished)} complete); best trial #{best.number}, J = {best.value:.4g}"
        + (f"; base (trial #{base_trials[0].number}) J = {base_trials[0].value:.4g}" if base_trials else "") + ".",
        f"# Best trial per cell: {per_cell}.",
        f"# Study: {sname} in {_shown(storage_url(t))}; MLflow experiment 'tuning', run key tuning/{sname}.",
        f"# Date: {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}; git {git_commit()}.",
        "# Command: python -m experiments.tuning.tune " + " ".join(sys.argv[1:]),
        "# Values rounded to 4 significant digits.",
    ]
    body = {"tracker": t.method, "variant": t.variant, "options": _round(tuned)}
    return "\n".join(lines) + "\n" + OmegaConf.to_yaml(OmegaConf.create(body))


def _shown(url: str) -> str:
    """A storage URL inside the project shown relative to it (the header must not name a checkout)."""
    for root in (paths.PACKAGE, paths.CONFIGS.resolve().parent, Path.cwd()):   # experiments/configs is a link
        prefix = f"sqlite:///{root}/"
        if url.startswith(prefix):
            return "sqlite:///" + url.removeprefix(prefix)
    return url


def _flat(options: dict) -> dict:
    return {f"option.{k}": v for k, v in options.items()}


def _log_study(cfg, sname: str) -> str:
    params = {"study": sname, **{f"tuning.{k}": v for k, v in
                                 OmegaConf.to_container(cfg.tuning, resolve=True).items()}}
    run_id, _ = log_run(cfg.runlog.experiment, f"tuning/{sname}", params=params,
                        tags={"kind": "tuning-study", "git_commit": git_commit()})
    return run_id


def _log_trial(cfg, sname: str, parent: str, trial, options: dict, parts: dict) -> None:
    log_run(cfg.runlog.experiment, f"tuning/{sname}/trial{trial.number}", params=_flat(options),
            metrics={k: v for k, v in parts.items() if np.isfinite(v)},
            tags={"mlflow.parentRunId": parent, "kind": "tuning-trial", "trial": str(trial.number)})


def main() -> None:
    cs = ConfigStore.instance()
    cs.store(name="tune_schema", node=TuneApp)
    cs.store(group="tuning", name="tuning_schema", node=TuningConfig)
    register(with_methods=methods.names())
    run_app("tune", task, check)


if __name__ == "__main__":
    main()
