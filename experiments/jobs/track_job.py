"""The tracking grid's jobs: simulate its records, run one tracker on all of them, score each track.

    python -m experiments.jobs.track_job data tracking --out results/tracking/data [--workers 2]
    python -m experiments.jobs.track_job run tracking --tracker akf --data results/tracking/data \
        --out results/tracking/track/akf
    python -m experiments.jobs.track_job score tracking --tracker akf --data results/tracking/data \
        --out results/tracking/track/akf      # score the stored tracks again (after a change of the metrics)

``tracking`` is a grid name (``configs/grid/tracking.yaml``) or a path to a grid file. ``data`` writes one
``<cell>.npz`` per cell (``experiments.simulate.tracking_data``). ``run`` calls
``methods.track(tracker, y, dt, prior, **options)`` on every replicate of every cell (the prior is the
cell's, never the truth; the options are the grid's ``tracker_options``) and writes, per cell,
``<cell>.npz`` (the tracks: ``t_s`` (K,), ``frequencies``/``std``/``converged`` (R, K, m), ``runtime_s``
(R,)), ``<cell>.csv`` (the scores of every replicate, ``experiments.report.tracking_metrics``) and
``<cell>.json`` (what the result depends on, for the MLflow step).

Everything is checked before the first record is simulated or tracked: the grid and every cell, the
tracker's name and its options against every cell's prior, sample interval and length. Bad input gets one
line ``error: ...`` on stderr, exit status 2, nothing written. A tracker that raises on one record is
recorded for that record (NaN estimates, the message) and the run goes on.
"""

from __future__ import annotations

import inspect
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

import methods
from experiments.cli import ArgumentParser, cpu_line
from experiments.hydra_app.command_line import fail
from experiments.io import read_npz, write_json, write_npz
from experiments.provenance import digest, git_state
from experiments.report.tracking_metrics import score_record
from experiments.simulate.tracking_grid import load_grid, make_grid_cell, nominal_prior_rad_s
from experiments.tracker_variants import split, variant_options

__all__ = ["WARM_UP_SAMPLES", "check_tracker", "grid_trackers", "hold_on", "main", "rescore_tracker", "run_cell",
           "run_data", "run_tracker", "score_cell", "track_record", "tracker_cells", "tracker_names", "warm_up"]


def tracker_names() -> list[str]:

    face = getattr(methods, "track_names", None)
    if face is None:
        raise ValueError("this installation has no trackers (methods.track_names is missing)")
    return list(face())


def grid_trackers(grid: dict) -> list[str]:
    """The grid's trackers: ``[all]`` is every registered tracker (``all`` may stand beside variants, e.g.
    ``[all, akf:tuned]``); ``name:variant`` is a tracker variant (``experiments.tracker_variants``); an
    unknown name or variant is refused."""
    known = tracker_names()
    listed = list(grid["trackers"])
    wanted = (known if "all" in listed else []) + [t for t in listed if t != "all" and not ("all" in listed
                                                                                          and t in known)]
    for spec in wanted:
        name, _ = split(spec)
        if name not in known:
            raise ValueError(f"grid {grid['name']}: unknown tracker '{name}'; known: {', '.join(known)}")
        try:
            variant_options(spec)
        except ValueError as exc:
            raise ValueError(f"grid {grid['name']}: {exc}") from None
    for name in grid.get("tracker_options") or {}:
        if name not in wanted:
            raise ValueError(f"grid {grid['name']}: tracker_options.{name}: '{name}' is not one of the grid's "
                             f"trackers ({', '.join(wanted)})")
    for name, _, _ in grid.get("tracker_exclude") or []:
        if name not in wanted:
            raise ValueError(f"grid {grid['name']}: exclude: tracker '{name}' is not one of the grid's "
                             f"trackers ({', '.join(wanted)})")
    return wanted


def tracker_cells(grid: dict, tracker: str) -> dict:
    """The grid's cells the tracker runs on: all but those a ``tracker`` item of ``exclude`` leaves out."""
    skip = [(s, e) for name, s, e in grid.get("tracker_exclude") or [] if name == tracker]
    return {name: cell for name, cell in grid["cells"].items()
            if not any((s is None or cell["schedule"] == s) and (e is None or cell["excitation"] == e)
                       for s, e in skip)}


def check_tracker(grid: dict, tracker: str) -> dict:
    """The tracker's options (a variant's over the defaults, then the grid's ``tracker_options``), checked
    against every cell (prior, Δt and record length)."""

    options = {**variant_options(tracker), **dict((grid.get("tracker_options") or {}).get(tracker, {}))}
    check = methods.check_track_options
    takes_length = "n_samples" in inspect.signature(check).parameters
    for name, cell in tracker_cells(grid, tracker).items():
        cfg = cell["config"]
        nominal = np.asarray(nominal_prior_rad_s(cfg), dtype=float)
        try:
            if takes_length:
                check(split(tracker)[0], nominal, cfg.dt_s, options, n_samples=cfg.n_samples)
            else:
                check(split(tracker)[0], nominal, cfg.dt_s, options)
        except ValueError as exc:
            raise ValueError(f"tracker {tracker}, cell {name}: {exc}") from None
    return options


def _write_cell(config, path: Path) -> float:
    """Simulate one cell (records, truth and bounds) into ``path``; its CPU seconds."""
    t0 = time.process_time()
    write_npz(path, make_grid_cell(config))
    return time.process_time() - t0


def run_data(grid: dict, out: Path, workers: int = 1) -> None:
    """Every cell's records into ``out/<cell>.npz``, on ``workers`` processes (the workflow gives the data job
    the cores, as nothing else can run before it: on 2 cores the 24 cells of the tracking grid take half the
    wall time). A cell's records depend only on its config (its seed), not on which process draws them."""
    cells = list(grid["cells"].items())
    if workers <= 1:
        for i, (name, cell) in enumerate(cells):
            cpu = _write_cell(cell["config"], out / f"{name}.npz")
            print(f"cell {i + 1} of {len(cells)} ({name}) in {cpu:.3g} s CPU", flush=True)
        print(f"{len(cells)} cells on 1 process", flush=True)
        return
    # a process pool of the standard library: each worker writes its cell's file itself (atomically), so no
    # record crosses a pipe; the longest cells first would not help, the cells cost about the same
    from concurrent.futures import ProcessPoolExecutor, as_completed  # only the parallel data step needs it

    with ProcessPoolExecutor(max_workers=min(workers, len(cells))) as pool:
        futures = {pool.submit(_write_cell, cell["config"], out / f"{name}.npz"): (i, name)
                   for i, (name, cell) in enumerate(cells)}
        for future in as_completed(futures):
            i, name = futures[future]
            print(f"cell {i + 1} of {len(cells)} ({name}) in {future.result():.3g} s CPU", flush=True)
    print(f"{len(cells)} cells on {min(workers, len(cells))} processes", flush=True)


def track_record(tracker: str, y: np.ndarray, dt_s: float, prior: np.ndarray, options: dict):
    """One record through ``methods.track`` (``tracker`` a name or a ``name:variant`` label whose options are
    already in ``options``); a tracker's exception becomes a failed track (None, message)."""

    try:
        return methods.track(split(tracker)[0], y, dt_s, prior, **options), ""
    except Exception as exc:  # noqa: BLE001 - one failed record is a result, not the end of the grid
        return None, f"{type(exc).__name__}: {' '.join(str(exc).split())}"


def hold_on(t_ref: np.ndarray, t_s: np.ndarray, dt: float, *arrays: np.ndarray) -> list[np.ndarray]:
    """Each array of a track (its first axis on the times ``t_s``) held onto the times ``t_ref``: at each t the
    latest estimate made at or before t (a causal zero-order hold), NaN (False for a boolean) before the first.
    Times are compared as sample indices (t / dt rounded), so float noise in them cannot move an estimate.

    A tracker's window and hop follow from the record's prior, so two replicates of one cell (priors drawn
    apart) report on different times; the hold puts them on one time axis without using any estimate
    before it was made."""
    k = np.searchsorted(np.rint(t_s / dt), np.rint(t_ref / dt), side="right") - 1
    before = k < 0
    out = []
    for a in arrays:
        held = a[np.maximum(k, 0)]
        held[before] = False if a.dtype == bool else np.nan
        out.append(held)
    return out


def run_cell(tracker: str, options: dict, data: dict, cell_meta: dict) -> tuple[dict, pd.DataFrame]:
    """Every replicate of a cell through the tracker; the tracks (arrays) and their scores (a table).
    The replicates share the time axis of the one with the most estimates; the others are held onto it
    (:func:`hold_on`)."""
    y_all, prior_all = data["accel_m_s2"], data["prior_rad_s"]
    dt = float(data["dt_s"])
    n, m = data["truth_freq_rad_s"].shape
    tracks = [track_record(tracker, y_all[r], dt, prior_all[r], options) for r in range(y_all.shape[0])]
    done = [tr for tr, _ in tracks if tr is not None]
    t_ref = max((tr.t_s for tr in done), key=len) if done else np.arange(n) * dt
    freq = np.full((len(tracks), t_ref.size, m), np.nan)
    std = np.full_like(freq, np.nan)
    conv = np.zeros(freq.shape, bool)
    runtime = np.zeros(len(tracks))
    messages = []
    for r, (tr, message) in enumerate(tracks):
        if tr is not None:
            if tr.t_s.shape == t_ref.shape and np.allclose(tr.t_s, t_ref):
                freq[r], std[r], conv[r] = tr.frequencies, tr.std, tr.converged
            else:
                freq[r], std[r], conv[r] = hold_on(t_ref, tr.t_s, dt, tr.frequencies, tr.std, tr.converged)
            runtime[r] = tr.runtime_s
            message = tr.message
        messages.append(message)
    arrays = {"t_s": t_ref, "frequencies": freq, "std": std, "converged": conv, "runtime_s": runtime}
    return arrays, score_cell(tracker, arrays, data, cell_meta, messages)


def score_cell(tracker: str, tracks: dict, data: dict, cell_meta: dict, messages: list[str]) -> pd.DataFrame:
    """The scores of every replicate's track (``experiments.report.tracking_metrics.score_record``)."""
    rows = []
    for r in range(tracks["frequencies"].shape[0]):
        s = score_record(tracks["t_s"], tracks["frequencies"][r], tracks["converged"][r], tracks["runtime_s"][r],
                         data, r)
        rows.append({"tracker": tracker, **cell_meta, "replicate": r, **s, "message": str(messages[r])[:300]})
    return pd.DataFrame(rows)


WARM_UP_SAMPLES = 1000


def warm_up(tracker: str, options: dict, data: dict) -> None:
    """One untimed run on the start of the first record, so that the first cell's CPU time does not carry
    the tracker's one-off costs (lazy imports, caches): on the smoke grid the first cell of a tracker took up
    to 2.6x the CPU per sample of the second.
    A tracker that refuses so short a record (its window is longer) is simply not warmed up."""
    y = data["accel_m_s2"][0]
    track_record(tracker, y[: min(y.size, WARM_UP_SAMPLES)], float(data["dt_s"]), data["prior_rad_s"][0], options)


def rescore_tracker(grid: dict, tracker: str, data_dir: Path, out: Path) -> None:
    """Score the tracks a run step wrote again (after a change of the metrics), without running the tracker."""
    cells = tracker_cells(grid, tracker)
    for name, cell in cells.items():
        data, tracks = read_npz(data_dir / f"{name}.npz"), read_npz(out / f"{name}.npz")
        old = pd.read_csv(out / f"{name}.csv")
        table = score_cell(tracker, tracks, data, _meta(name, cell), list(old["message"].fillna("")))
        table.to_csv(out / f"{name}.csv", index=False)
    print(f"{tracker}: {len(cells)} cells scored again", flush=True)


def _meta(name: str, cell: dict) -> dict:
    return {"cell": name, "schedule": cell["schedule"], "excitation": cell["excitation"],
            "noise_ug": cell["noise_ug"], "duration_s": cell["duration_s"]}


def run_tracker(grid: dict, tracker: str, options: dict, data_dir: Path, out: Path) -> None:
    code = git_state()
    cells = tracker_cells(grid, tracker)
    warm_up(tracker, options, read_npz(data_dir / f"{next(iter(cells))}.npz"))
    for i, (name, cell) in enumerate(cells.items()):
        data = read_npz(data_dir / f"{name}.npz")
        meta = _meta(name, cell)
        t0 = time.process_time()
        arrays, table = run_cell(tracker, options, data, meta)
        write_npz(out / f"{name}.npz", arrays)
        table.to_csv(out / f"{name}.csv", index=False)
        write_json(out / f"{name}.json", {
            "grid": grid["name"], "tracker": tracker, "options": options, "cell": meta,
            "dataset": {"name": name, "digest": str(data["checksum_sha256"])},
            "code": code, "run_key_digest": digest(json.dumps(
                {"tracker": tracker, "options": options, "data": str(data["checksum_sha256"]), "code": code},
                sort_keys=True, default=str))})
        print(f"{tracker}: cell {i + 1} of {len(cells)} ({name}) in {time.process_time() - t0:.3g} s CPU",
              flush=True)


def main(argv: list[str] | None = None) -> None:
    parser = ArgumentParser(prog="python -m experiments.jobs.track_job", description=__doc__.split("\n")[0])
    parser.add_argument("step", choices=("data", "run", "score"))
    parser.add_argument("grid", help="a grid name (configs/grid/<name>.yaml) or a grid file")
    parser.add_argument("--out", required=True)
    parser.add_argument("--tracker")
    parser.add_argument("--data")
    parser.add_argument("--workers", type=int, default=1,
                        help="data step: cells simulated side by side in this many processes (default 1)")
    args = parser.parse_args(argv)
    try:
        if args.workers < 1:
            raise ValueError(f"--workers = {args.workers} must be a positive number of processes")
        grid = load_grid(args.grid)
        if args.step == "score":
            if not args.tracker or not args.data:
                raise ValueError("score needs --tracker NAME and --data DIR")
            missing = [c for c in tracker_cells(grid, args.tracker) if not (Path(args.out) / f"{c}.npz").is_file()]
            if missing:
                raise ValueError(f"{args.out}: no tracks of cell {missing[0]} (run the run step first)")
        if args.step == "run":
            if not args.tracker or not args.data:
                raise ValueError("run needs --tracker NAME and --data DIR")
            if args.tracker not in grid_trackers(grid):
                raise ValueError(f"tracker '{args.tracker}' is not one of grid {grid['name']}'s trackers")
            options = check_tracker(grid, args.tracker)
            missing = [c for c in grid["cells"] if not (Path(args.data) / f"{c}.npz").is_file()]
            if missing:
                raise ValueError(f"{args.data}: no record of cell {missing[0]} (run the data step first)")
    except ValueError as exc:
        fail(" ".join(str(exc).split()))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    # One BLAS thread, as under Snakemake (experiments/workflow/rules/common.smk) and as on board: with several, the
    # CPU time per sample counts threads that wait on tiny matrices (measured: era 3.5 ms instead of 0.24 ms
    # per sample on a loaded 2-core machine).
    with threadpool_limits(limits=1):
        if args.step == "data":
            run_data(grid, out, args.workers)
        elif args.step == "score":
            rescore_tracker(grid, args.tracker, Path(args.data), out)
        else:
            run_tracker(grid, args.tracker, options, Path(args.data), out)
    print(cpu_line(), flush=True)


if __name__ == "__main__":
    sys.exit(main())
