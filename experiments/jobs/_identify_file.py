"""The identify job on a user's own measurement file (docs/measurements.md); private to
:mod:`experiments.jobs.identify`.

    python -m experiments.jobs.identify method=pem data.path=beam.uff data.channel=tip

Read (:func:`experiments.recordings.read_record`: the format by extension, channel, units, time step),
segment and decimate (:func:`experiments.recordings.choose_segment`), and, with ``prior`` omitted, find
the modes on a stabilisation diagram (:mod:`methods.peers.stabilisation`) and give them to the method as
its prior. The answer: per mode the frequency in Hz and rad/s with 1σ, the damping ratio with 1σ, the
amplitude and whether the record determines it, on the terminal and in ``estimate.json``; one figure
(``measurement.png``/``.svg``) of the fit, the spectrum and the diagram.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.io import write_json
from experiments.recordings.load import load_segment
from experiments.recordings.modal_fit import fit_modes
from experiments.recordings.modes_found import find_modes
from experiments.recordings.spectral import flat_band
from experiments.report import model_check
from experiments.report.measurement_figure import measurement_figure
from experiments.units import G_M_S2

__all__ = ["MEASUREMENTS_EXPERIMENT", "load", "find_modes", "method_options", "print_notes", "report", "log"]

MEASUREMENTS_EXPERIMENT = "measurements"


def load(d, prior=None) -> dict:
    """The segment of the file ``d.path`` to identify (``d``: the job's ``data`` config), as the job's
    data dict; read once per process (the job's check and its task both ask)."""
    cover = 1.25 * max(prior) / (2 * np.pi) if prior is not None and len(prior) else 0.0
    rec, seg = load_segment(d, cover)
    return {"y": seg.y[None, :], "dt": seg.dt, "truth": None, "source": str(Path(d.path)), "record": rec,
            "segment": seg}


def method_options(options: dict, data: dict) -> dict:
    """The method's options for the segment: a method with a residual check (``whiteness_band_rad_s``, pem)
    judges a decimated segment's residual in the anti-alias filter's flat pass band only
    (:func:`experiments.recordings.spectral.flat_band`), unless the option was set."""

    q = data["segment"].decimation
    if q > 1 and "whiteness_band_rad_s" in options and options["whiteness_band_rad_s"] is None:
        return {**options, "whiteness_band_rad_s": flat_band(q) * np.pi / data["dt"]}
    return options


def print_notes(data: dict) -> None:
    for note in data["record"].notes + data["segment"].notes:
        print(f"{Path(data['source']).name}: {note}")


def report(name: str, prior, est, data: dict, run_dir: Path, diagram=None) -> list[Path]:
    """Print the modes, write ``estimate.json`` and the figure; return the paths written."""

    seg = data["segment"]
    m = est.frequencies.size
    damping = np.asarray(est.extra.get("damping", np.full(m, np.nan)), float).reshape(-1)
    damping_std = np.asarray(est.extra.get("damping_std", np.full(m, np.nan)), float).reshape(-1)
    damping_from = "the method"
    if np.isnan(damping).all() and diagram is not None:
        damping, damping_from = diagram.modes_damping.copy(), "the stabilisation diagram (no 1σ)"
    # a mode that drifts with amplitude reports its small-amplitude frequency (pem's drift_frequency); the
    # model drawn against the record is the one fitted at the record's own (whole-record) frequencies
    drift = est.extra.get("drift") or {}
    start = int((est.extra.get("saturation") or {}).get("fit_start", 0))       # a clipped record: after the clip
    fit = fit_modes(seg.y, seg.dt, np.asarray(drift.get("whole_record", est.frequencies), float), damping, start)
    how = (diagram.how + f"; refined by {name}" if diagram is not None else f"{name} from the prior given")
    modes = []
    for i in range(m):
        w, s, ok = float(est.frequencies[i]), float(est.std[i]), bool(est.converged_per_mode[i])
        modes.append({"mode": i + 1, "freq_hz": w / (2 * np.pi), "freq_std_hz": s / (2 * np.pi),
                      "freq_rad_s": w, "freq_std_rad_s": s, "damping_ratio": float(damping[i]),
                      "damping_std": float(damping_std[i]), "amplitude_m_s2": float(fit.amplitude[i]),
                      "amplitude_g": float(fit.amplitude[i] / G_M_S2), "determined": ok,
                      "prior_rad_s": float(prior[i])})
        print(f"mode {i + 1}: {_digits(w, s)} rad/s ± {s:.2g} ({_digits(w / (2 * np.pi), s / (2 * np.pi))} Hz ± "
              f"{s / (2 * np.pi):.2g}), damping ratio {_digits(damping[i], damping_std[i])} ± {damping_std[i]:.2g}, "
              f"amplitude {fit.amplitude[i] / G_M_S2:.3g} g"
              + ("" if ok else " — not determined by the record"))
    print(f"how: {how}")
    print(f"converged: {est.converged} ({est.message})")
    for line in model_check.check_lines(est.extra):       # does the model explain the record? (pem)
        print(line)
    stem = run_dir / "measurement"
    figures = measurement_figure(
        stem, y=seg.y, dt=seg.dt, t0=seg.t0, model=fit.model, residual=fit.residual, freq_rad_s=est.frequencies,
        std_rad_s=est.std, determined=est.converged_per_mode, diagram=diagram,
        title=(f"{Path(data['source']).name}, channel {data['record'].channel}: {m} mode{'s' if m != 1 else ''}"
               + (f" from the stabilisation diagram, refined by {name}" if diagram is not None
                  else f" by {name} from the prior given")))
    rec = data["record"]
    path = write_json(run_dir / "estimate.json", {
        "method": name, "how_found": how, "damping_from": damping_from, "modes": modes,
        "frequencies_rad_s": est.frequencies, "std_rad_s": est.std,
        "converged": bool(est.converged), "converged_per_mode": [bool(c) for c in est.converged_per_mode],
        "message": est.message, "prior_rad_s": prior,
        "record": {"path": rec.path, "channel": rec.channel, "unit": rec.unit, "dt_s": rec.dt_s,
                   "n_samples": int(rec.accel_m_s2.size), "notes": rec.notes},
        "segment": {"start_s": seg.t0, "stop_s": seg.stop_s, "n_samples": int(seg.y.size), "dt_s": seg.dt,
                    "decimation": seg.decimation, "band_hz": list(seg.band_hz), "impulse_s": seg.impulse_s,
                    "notes": seg.notes},
        "figure": [p.name for p in figures], **model_check.check_json(est.extra)})
    print(f"wrote {path}, {', '.join(str(p) for p in figures)}")
    return [path, *figures]


def _digits(value: float, std: float) -> str:
    """``value`` with the decimals its 1σ ``std`` warrants (down to the std's second digit), else 6 digits."""
    if not (np.isfinite(std) and std > 0 and np.isfinite(value)):
        return f"{value:.6g}"
    return f"{value:.{max(0, 1 - int(np.floor(np.log10(std))))}f}"


def log(record: dict, est, paths: list[Path], run_dir: Path, background: bool = True) -> None:
    """Log a run on a user's measurement in the MLflow experiment ``measurements`` (keyed like a cell's job).

    The run is written into the run folder first (``mlflow_pending.json``, :mod:`experiments.runlog.pending`)
    and queued; with ``background`` a detached process logs it (and any run left over) while the job ends,
    otherwise the job logs it here. Neither imports MLflow into the job until it logs."""
    # run logging's modules, loaded when the run is logged (runlog.enabled=false never loads them)
    from experiments.runlog import pending
    from experiments.runlog.records import IDENTIFY_SOURCE, config_yaml, job_params, run_key
    from experiments.runlog.store import source_tags

    record = {**record, "grid": "measurement"}
    key = run_key(record)
    metrics = {}
    m = est.frequencies.size
    damping = np.asarray(est.extra.get("damping", np.full(m, np.nan)), float).reshape(-1)
    damping_std = np.asarray(est.extra.get("damping_std", np.full(m, np.nan)), float).reshape(-1)
    for i, (w, s) in enumerate(zip(est.frequencies, est.std, strict=True)):
        metrics[f"freq_rad_s.mode{i + 1}"] = float(w)
        metrics[f"std_rad_s.mode{i + 1}"] = float(s)
        metrics[f"damping.mode{i + 1}"] = float(damping[i])
        metrics[f"damping_std.mode{i + 1}"] = float(damping_std[i])
    metrics["converged"] = float(bool(est.converged))
    ds = record["dataset"]
    pending.enqueue(
        run_dir, MEASUREMENTS_EXPERIMENT, key, params=job_params(record), metrics=metrics, artifacts=paths,
        texts={"config.yaml": config_yaml(record)},
        dataset={"name": ds["name"], "digest_": ds["digest"], "source": ds["path"], "kind": "measurement"},
        tags={**source_tags(IDENTIFY_SOURCE, record["code"]), "kind": "measurement", "method": record["method"]})
    if background:
        pending.start_logger(run_dir)
        print(f"MLflow experiment {MEASUREMENTS_EXPERIMENT}: run {key} is being logged by a background process "
              f"(its output: {Path(run_dir) / pending.LOG}; `python -m experiments.runlog.pending` logs any run "
              f"left waiting)")
        return
    out = pending.log_folder(run_dir)            # None: a logger of another job logged it meanwhile
    created = out is not None and out[2]
    print(f"MLflow experiment {MEASUREMENTS_EXPERIMENT}: run {key} ({'logged' if created else 'already there'})")
