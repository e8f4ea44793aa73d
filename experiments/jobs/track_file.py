"""Hydra app: track the modal frequencies of a user's own measurement file over time.

    python -m experiments.jobs.track_file data.path=rec.csv                       # the recommended tracker
    python -m experiments.jobs.track_file data.path=rec.uff data.channel=tip tracker=era tracker.options.hop_samples=10
    modal-id-track-file data.path=rec.csv prior='[188.5]'                          # the console script

The file is read as the identify job reads it (:mod:`experiments.recordings`: CSV, UFF 58 by pyuff, LabVIEW
.lvm and .tdms, MATLAB .mat; ``data.channel``, ``data.units``, ``data.dt``, rounded time stamps fitted), from
its start (or ``data.start_s``) to its end (or ``data.stop_s``), brought to its band (``data.band_hz``, else
from the spectrum) and decimated by the same anti-alias FIR. The modes to track are the ``prior`` (rad/s) or,
without one, the modes of a stabilisation diagram of the record's first stretch (the first tenth, at least
64 samples, or ``first_stretch_s``), found as identify finds them. Then ``methods.track(tracker, y, dt,
prior, **options)``: ``tracker=`` any of ``methods.track_names()`` (default :data:`DEFAULT_TRACKER`) or a
variant file of ``configs/tracker/`` (``tracker=akf_tuned``), ``tracker.options.<name>=`` any of its options
(checked by Hydra against the tracker's options dataclass, then by ``methods.check_track_options`` against
the record); only the options given are passed, the rest are the tracker's own defaults.

Written in the run folder (``results/runs/<time>_track/``, or ``hydra.run.dir=``): ``track.csv``
(file time, then per mode the frequency in Hz and rad/s, its 1σ and the tracker's converged flag),
``track.json`` (the same arrays, the prior and how it was found, the record, the segment, the tracker's
options and message) and ``track.png``/``.svg`` (:mod:`experiments.report.track_figure`: the spectrogram with
the tracked frequencies and their ±2σ band, the record below). The run is then logged to MLflow
(experiment ``measurement-tracks``) after the answer by a detached ``python -m experiments.runlog.file_tracks``,
which queues it for the identify job's logger (:mod:`experiments.runlog.pending`) and logs it;
``runlog.enabled=false`` skips it, ``runlog.background=false`` waits for it.

Bad input — no such file, a bad format or channel, an unknown tracker or option, a bad prior, a window longer
than the record — gets one line ``error: ...`` and exit status 2 before any work; nothing is written.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import os
import subprocess
import sys
from dataclasses import field
from pathlib import Path
from typing import Any

import numpy as np
from hydra.core.config_store import ConfigStore
from hydra.core.hydra_config import HydraConfig
from omegaconf import MISSING, OmegaConf

import methods
from experiments.config_schema import DataConfig, RunlogConfig
from experiments.hydra_app.command_line import fail, run_app
from experiments.io import atomic_write_text, write_json
from experiments.paths import TRACKER_CONFIGS
from methods.tracking import track_options_class

__all__ = ["DEFAULT_TRACKER", "EXPERIMENT", "FIRST_STRETCH_FRACTION", "FIRST_STRETCH_MIN_SAMPLES", "SOURCE",
           "TrackFileConfig", "changed_options", "check", "first_stretch", "load", "main", "register", "task",
           "track_csv", "tracker_named_on", "tracker_of", "tracker_schema"]

# The tracker to fly as shipped (docs/measured/tracking.md, "As shipped, on records unlike the grid's").
DEFAULT_TRACKER = "gated_pencil"
EXPERIMENT = "measurement-tracks"
SOURCE = "experiments/jobs/track_file.py"
RUNLOG_MODULE = "experiments.runlog.file_tracks"     # logs this job's run (started as a command, not imported)
RUN_FILE = "mlflow_track_run.json"                   # the run, ready to log (experiments/runlog/file_tracks.py)
FIRST_STRETCH_FRACTION = 0.1      # without a prior, the modes come from this share of the record...
FIRST_STRETCH_MIN_SAMPLES = 64    # ...but at least this many (a stabilisation diagram to order 15; a segment's least)


def tracker_schema(tracker: str):
    """The config node of ``tracker=<name>``: its name and its options, the tracker's options dataclass, so a
    typo or a wrong type in ``tracker.options.*`` fails at composition with the key's name."""
    options_cls = track_options_class(tracker)
    return dataclasses.make_dataclass(f"{tracker}_tracker", [
        ("name", str, field(default=tracker)),
        ("options", options_cls, field(default_factory=options_cls))])


@dataclasses.dataclass
class TrackFileConfig:
    """The job's config (configs/track_file.yaml)."""

    tracker: Any = MISSING
    data: DataConfig = field(default_factory=DataConfig)
    prior: list[float] | None = None          # rad/s; None: from a stabilisation diagram of the first stretch
    n_modes: int | None = None                # without a prior: at most this many modes
    first_stretch_s: float | None = None      # the stretch the modes are found on, s (None: module docstring)
    runlog: RunlogConfig = field(default_factory=lambda: RunlogConfig(experiment=EXPERIMENT))
    progress: bool = True


def tracker_named_on(argv: list[str]) -> str:
    """The tracker a command line names (the last ``tracker=``), else :data:`DEFAULT_TRACKER`; one line and
    exit 2 for an unknown one."""
    named = [a.split("=", 1)[1].strip("'\"") for a in argv if a.startswith("tracker=")]
    name = named[-1] if named else DEFAULT_TRACKER
    variants = sorted(p.stem for p in TRACKER_CONFIGS.glob("*.yaml"))
    if name not in methods.track_names() and name not in variants:
        fail(f"unknown tracker '{name}'; known trackers: {', '.join(methods.track_names())} "
             f"(variants: {', '.join(variants)})")
    return name


def register(tracker: str) -> None:
    """Store the job's schema, and the named tracker's node in the group ``tracker`` (a variant,
    ``configs/tracker/<name>_<variant>.yaml``, is a file of that group already)."""
    cs = ConfigStore.instance()
    cs.store(name="track_file_schema", node=TrackFileConfig)
    if tracker in methods.track_names():
        cs.store(group="tracker", name=tracker, node=tracker_schema(tracker))


def tracker_of(cfg) -> tuple[str, str]:
    """(tracker name, label): ``era`` or, for a variant file, ``akf`` and ``akf:tuned``."""
    node = cfg.tracker
    if "name" in node:
        return str(node.name), str(node.name)
    return str(node.tracker), f"{node.tracker}:{node.variant}"


def changed_options(cfg) -> dict:
    """The options the command line (or a variant file) set, those that differ from the tracker's defaults:
    only these are passed, so the tracker's own defaults (which may follow Δt and the prior) stay its own."""
    given = OmegaConf.to_container(cfg.tracker.options, resolve=True) or {}
    defaults = dataclasses.asdict(track_options_class(tracker_of(cfg)[0])())
    return {k: v for k, v in given.items() if k not in defaults or _differs(v, defaults[k])}


def _differs(a, b) -> bool:
    try:
        return bool(np.any(np.asarray(a, dtype=object) != np.asarray(b, dtype=object)))
    except ValueError:                     # shapes that do not broadcast: different
        return True


def load(cfg) -> dict:
    """The record to track: the whole file (or ``data.start_s``–``data.stop_s``) in its band, decimated; read
    once per process (the pre-check and the task both ask)."""
    d = cfg.data
    if d.dataset is not None:
        raise ValueError("data.dataset is a generated cell (the identify job's); the track job reads a measurement "
                         "file: give data.path=")
    if d.path is None:
        raise ValueError("give the measurement file: data.path=<file> (.csv, .uff/.unv, .lvm, .tdms, .mat)")
    prior = None if cfg.prior is None else [float(w) for w in cfg.prior]
    cover = 1.25 * max(prior) / (2 * np.pi) if prior and all(np.isfinite(prior)) else 0.0
    from experiments.recordings.load import load_segment  # the readers: only once the file is read

    rec, seg = load_segment(d, cover, whole_record=True)
    return {"y": seg.y, "dt": seg.dt, "t0": seg.t0, "source": str(Path(d.path)), "record": rec, "segment": seg}


def first_stretch(data: dict, stretch_s: float | None) -> int:
    """Samples of the first stretch the modes are found on (module docstring)."""
    n = data["y"].size
    if stretch_s is not None:
        if not (np.isfinite(stretch_s) and stretch_s > 0):
            raise ValueError(f"first_stretch_s = {stretch_s} must be a positive duration in s")
        return int(min(n, max(FIRST_STRETCH_MIN_SAMPLES, round(stretch_s / data["dt"]))))
    return int(min(n, max(FIRST_STRETCH_MIN_SAMPLES, round(FIRST_STRETCH_FRACTION * n))))


def check(cfg) -> None:
    """Everything that can be known wrong before any work: the file and its channel, units and time; the
    prior; the tracker's options against the record (``methods.check_track_options``); the MLflow store."""
    data = load(cfg)
    y, dt = data["y"], data["dt"]
    if cfg.prior is not None:
        prior = np.asarray(list(cfg.prior), float)
        try:
            methods.check_inputs(y, dt, prior)
        except ValueError as exc:
            raise ValueError(f"{data['source']}: {exc}") from None
    else:
        if cfg.n_modes is not None and cfg.n_modes < 1:
            raise ValueError(f"n_modes = {cfg.n_modes} must be at least 1")
        first_stretch(data, cfg.first_stretch_s)
        lo, hi = data["segment"].band_hz
        prior = np.array([min(np.pi * (lo + hi), 0.9 * np.pi / dt)])     # one mode mid-band, for the options
    name, label = tracker_of(cfg)
    try:
        methods.check_track_options(name, prior, dt, changed_options(cfg), n_samples=y.size)
    except ValueError as exc:
        raise ValueError(f"tracker {label}: {exc}") from None
    if cfg.runlog.enabled:     # an empty or corrupt store: one line now, not after the work
        proc = subprocess.run([sys.executable, "-m", RUNLOG_MODULE, "--check"], capture_output=True, text=True)
        if proc.returncode != 0:
            raise ValueError(proc.stderr.strip().removeprefix("error: ") or "the MLflow store cannot be checked")


def task(cfg) -> None:
    from threadpoolctl import threadpool_limits  # the job only: a test of its parts needs none

    # One BLAS thread, as the tracking grid's jobs (experiments/jobs/track_job.py): the trackers' matrices are
    # small, and threads that wait on them cost more CPU than they save (era 3.5 ms instead of 0.24 ms per
    # sample on a loaded 2-core machine)
    with threadpool_limits(limits=1):
        _task(cfg)


def _task(cfg) -> None:
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    data = load(cfg)
    tracker, label = tracker_of(cfg)
    name = Path(data["source"]).name
    for note in data["record"].notes + data["segment"].notes:
        print(f"{name}: {note}")
    how, short = f"the prior given ({label} from it)", "from the prior given"
    if cfg.prior is None:
        from experiments.recordings.modes_found import find_modes  # pyOMA2 (0.4 s): only without a prior

        n0 = first_stretch(data, cfg.first_stretch_s)
        stretch = {**data, "segment": dataclasses.replace(data["segment"], y=data["y"][:n0])}
        prior, diagram = find_modes(stretch, cfg.n_modes)
        how = f"{diagram.how} on the first {n0 * data['dt']:.4g} s ({n0} samples)"
        short = f"found on the first {n0 * data['dt']:.3g} s by a stabilisation diagram"
        print(f"{how}: {', '.join(f'{w / (2 * np.pi):.5g}' for w in prior)} Hz")
    else:
        prior = np.asarray(list(cfg.prior), float)
    options = changed_options(cfg)
    if cfg.progress:
        print(f"info: {label} on {data['y'].size} samples ({data['y'].size * data['dt']:.6g} s)...",
              file=sys.stderr, flush=True)
    trk = methods.track(tracker, data["y"], data["dt"], prior, **options)
    paths = _report(label, data, prior, (how, short), options, trk, run_dir)
    if cfg.runlog.enabled:
        _log(cfg, label, data, prior, options, trk, paths, run_dir)


def track_csv(t_s: np.ndarray, freq: np.ndarray, std: np.ndarray, converged: np.ndarray) -> str:
    """The track as CSV text: ``t_s`` (file time), then per mode i ``mode{i}_freq_hz``, ``mode{i}_std_hz``,
    ``mode{i}_freq_rad_s``, ``mode{i}_std_rad_s`` (1σ), ``mode{i}_converged`` (0/1); NaN where none."""
    m = freq.shape[1]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["t_s"] + [f"mode{i + 1}_{c}" for i in range(m)
                               for c in ("freq_hz", "std_hz", "freq_rad_s", "std_rad_s", "converged")])
    for k in range(t_s.size):
        row = [f"{t_s[k]:.10g}"]
        for i in range(m):
            w, s = freq[k, i], std[k, i]
            row += [f"{w / (2 * np.pi):.10g}", f"{s / (2 * np.pi):.4g}", f"{w:.10g}", f"{s:.4g}",
                    str(int(bool(converged[k, i])))]
        writer.writerow(row)
    return buf.getvalue()


def _report(label: str, data, prior, how, options, trk, run_dir: Path) -> list[Path]:
    """Print the track's summary; write track.csv, track.json and the figure; return the paths."""
    from experiments.report.track_figure import track_figure  # matplotlib and scipy.signal: after the answer

    how, short = how
    t_file = data["t0"] + trk.t_s
    m = prior.size
    modes = []
    for i in range(m):
        ok = trk.converged[:, i]
        last = np.flatnonzero(np.isfinite(trk.frequencies[:, i]))
        final = float(trk.frequencies[last[-1], i]) if last.size else float("nan")
        final_std = float(trk.std[last[-1], i]) if last.size else float("nan")
        modes.append({"mode": i + 1, "prior_rad_s": float(prior[i]), "final_freq_rad_s": final,
                      "final_std_rad_s": final_std, "final_freq_hz": final / (2 * np.pi),
                      "share_converged": float(ok.mean()) if ok.size else 0.0,
                      "range_hz": ([float(np.nanmin(trk.frequencies[ok, i]) / (2 * np.pi)),
                                    float(np.nanmax(trk.frequencies[ok, i]) / (2 * np.pi))] if ok.any() else None)})
        span = (f", {modes[-1]['range_hz'][0]:.5g}–{modes[-1]['range_hz'][1]:.5g} Hz while converged"
                if ok.any() else ", never converged")
        print(f"mode {i + 1}: last estimate {final / (2 * np.pi):.6g} Hz ± {final_std / (2 * np.pi):.2g} "
              f"({final:.6g} rad/s), converged {100 * modes[-1]['share_converged']:.0f} % of the time{span}")
    print(f"{label}: {trk.message}")
    seg, rec = data["segment"], data["record"]
    files = [atomic_write_text(run_dir / "track.csv", track_csv(t_file, trk.frequencies, trk.std, trk.converged))]
    files += track_figure(run_dir / "track", y=data["y"], dt=data["dt"], t0=data["t0"], t_s=t_file,
                          freq_rad_s=trk.frequencies, std_rad_s=trk.std, converged=trk.converged,
                          title=(f"{Path(data['source']).name}, channel {rec.channel}: {label}, {m} mode"
                                 f"{'s' if m != 1 else ''} {short}"))
    files.insert(1, write_json(run_dir / "track.json", {
        "tracker": label, "options": options, "how_found": how, "prior_rad_s": prior, "modes": modes,
        "t_s": t_file, "frequencies_rad_s": trk.frequencies, "std_rad_s": trk.std,
        "converged": trk.converged.astype(int), "message": trk.message, "runtime_s": trk.runtime_s,
        "record": {"path": rec.path, "channel": rec.channel, "unit": rec.unit, "dt_s": rec.dt_s,
                   "n_samples": int(rec.accel_m_s2.size), "notes": rec.notes},
        "segment": {"start_s": seg.t0, "stop_s": seg.stop_s, "n_samples": int(seg.y.size), "dt_s": seg.dt,
                    "decimation": seg.decimation, "band_hz": list(seg.band_hz), "notes": seg.notes},
        "figure": [p.name for p in files[1:]]}))
    print(f"wrote {', '.join(str(p) for p in files)}")
    return files


def _log(cfg, label: str, data, prior, options, trk, paths: list[Path], run_dir: Path) -> None:
    """Write the run, ready to log, and hand it to :mod:`experiments.runlog.file_tracks` (queued for MLflow
    like the identify job's run, and logged by that process, detached: the job does not wait for MLflow).
    A frequency-tracking module imports no MLflow logging (tests/test_names.py): it starts the command."""
    from experiments import provenance  # the code and file digests: only a logged run needs them

    code = provenance.git_state()
    ds = {"name": Path(data["source"]).name, "digest": provenance.file_digest(data["source"])}
    config = OmegaConf.to_container(cfg, resolve=True)
    keyed = {"tracker": label, "options": options, "prior": [float(w) for w in prior],
             "data": config["data"], "dataset": ds["digest"], "code": code}
    key = f"measurement/track:{label}/{ds['name']}/{provenance.digest(provenance.canonical_json(keyed))}"
    params = {"tracker": label, "prior_rad_s": [float(w) for w in prior], "dataset": ds["name"],
              "dataset_digest": ds["digest"], "git_commit": code["commit"], "git_dirty": code["dirty"],
              "dt_s": data["dt"], "decimation": data["segment"].decimation,
              **{f"option.{k}": v for k, v in options.items()}}
    metrics = {"runtime_s": trk.runtime_s, "n_estimates": float(trk.t_s.size)}
    for i in range(prior.size):
        metrics[f"share_converged.mode{i + 1}"] = float(trk.converged[:, i].mean())
        last = np.flatnonzero(np.isfinite(trk.frequencies[:, i]))
        if last.size:
            metrics[f"final_freq_rad_s.mode{i + 1}"] = float(trk.frequencies[last[-1], i])
    tags = {"mlflow.source.name": SOURCE, "mlflow.source.type": "LOCAL", "git_dirty": str(bool(code["dirty"])).lower(),
            "kind": "measurement-track", "tracker": label}
    if code.get("commit", "unknown") != "unknown":
        tags["mlflow.source.git.commit"] = code["commit"]
    write_json(run_dir / RUN_FILE, {
        "experiment": cfg.runlog.experiment, "run_key": key, "params": {k: str(v) for k, v in params.items()},
        "metrics": metrics, "tags": tags, "texts": {"config.yaml": OmegaConf.to_yaml(OmegaConf.create(config))},
        "dataset": {"name": ds["name"], "digest_": ds["digest"], "source": data["source"], "kind": "measurement"},
        "artifacts": [p.name for p in paths]})
    command = [sys.executable, "-m", RUNLOG_MODULE, str(run_dir)]
    if cfg.runlog.background:
        with open(run_dir / "mlflow_log.txt", "ab") as out:
            subprocess.Popen(command, cwd=os.getcwd(), stdin=subprocess.DEVNULL, stdout=out,
                             stderr=subprocess.STDOUT, start_new_session=True, close_fds=True)
        print(f"MLflow experiment {cfg.runlog.experiment}: run {key} is being logged by a background process "
              f"(its output: {run_dir / 'mlflow_log.txt'})")
        return
    proc = subprocess.run([*command, "--now"], capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"logging the run to MLflow failed: {proc.stderr.strip()[-500:]}")
    print(f"MLflow experiment {cfg.runlog.experiment}: {proc.stdout.strip()}")


def main() -> None:
    """The console script ``modal-id-track-file`` (pyproject.toml), as ``python -m experiments.jobs.track_file``."""
    register(tracker_named_on(sys.argv[1:]))
    run_app("track_file", task, check)


if __name__ == "__main__":
    main()
