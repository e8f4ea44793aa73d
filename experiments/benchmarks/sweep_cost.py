"""Cost model of a grid's sweep: one fit per method × cell, timed, and the grid's wall time predicted on C cores.

    python -m experiments.benchmarks.sweep_cost --grid full --cores 2
    python -m experiments.benchmarks.sweep_cost --grid paper --cores 2 --replicates 2 --methods era hdmd
    python -m experiments.benchmarks.sweep_cost --grid configs/grid/my.yaml --label after

For every cell (noise level × record length) of the grid file (``configs/grid/<grid>.yaml``, or a path)
it simulates the cell's records exactly as the workflow's datasets batch does (``make_cell`` with the
grid's seed: the same bytes) and times ``--replicates`` fits of each method entry (its resolved config:
prior and options, variants included) on the first records, in this one process, warm. Methods with a
lock-step batch (``methods.get_batch``: the Kalman filters) are timed as the workflow runs them, all
records of a call together, on ``--batch-records`` records, and charged per record.

The time of a fit is its CPU time (``time.process_time``, one BLAS thread as in the workflow's jobs): on
a machine shared with other work, wall time is inflated by the load, CPU time much less so. The model:

- CPU of a method's identify batch = Σ_cells R × t_fit(cell) + its process start-up (``--startup``:
  imports and the first fit of a fresh interpreter, measured per method; else 0);
- the datasets batch = Σ_cells (time to simulate the cell, measured here);
- wall on C cores = the datasets batch, then the identify batches (one process each, one core each, as
  the workflow runs them with ``--set-threads identify=1``) placed longest first on C cores (the LPT
  makespan; the lower bound max(Σ/C, longest) is printed beside it). The serial steps after them
  (aggregate, track, reports) are not modelled: add their measured time.

Writes the per-cell fit times to ``results/bench/sweep_cost/<grid>[_<label>].csv`` and the printed tables
to ``results/bench/sweep_cost.md``. Compare runs by their ratios: the machine's load is printed beside them.
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml
from threadpoolctl import threadpool_limits

import methods
from experiments import provenance
from experiments.io import atomic_write_text
from experiments.paths import GRIDS, ROOT
from experiments.simulate.datasets import DatasetConfig, make_cell

__all__ = ["load_grid", "method_setup", "time_fits", "makespan", "predict", "main"]

GRID_KEYS = ("noise_ug", "n_samples", "replicates", "seed", "methods")


def load_grid(grid: str) -> dict:
    """The grid file's values (``configs/grid/<grid>.yaml`` or a path); a noise × length grid only."""
    path = Path(grid) if grid.endswith((".yaml", ".yml")) else GRIDS / f"{grid}.yaml"
    if not path.is_file():
        raise ValueError(f"grid '{grid}': no file {path}")
    g = yaml.safe_load(path.read_text()) or {}
    missing = [k for k in GRID_KEYS if k not in g]
    if missing or g.get("cells") or g.get("scenarios"):
        raise ValueError(f"grid '{grid}': the cost model needs a noise x length grid with {', '.join(GRID_KEYS)}"
                         + (f" (missing {', '.join(missing)})" if missing else " (scenario cells are not modelled)"))
    g.setdefault("name", path.stem)
    return g


def method_setup(entry: str, overrides: list[str]) -> tuple[str, np.ndarray, dict]:
    """(method name, prior, options) of a grid's methods entry (``akf:tuned`` -> configs/method/akf_tuned),
    resolved by Hydra as the identify job composes it."""
    node = json.loads(provenance.resolved_method_config(entry.replace(":", "_"), tuple(overrides)))
    return node["name"], np.asarray(node["prior_rad_s"], float), dict(node.get("options") or {})


def _one_fit(name, y, dt, prior, options):
    """CPU seconds of one call (a batch of records: per record)."""
    batch = methods.get_batch(name) if y.ndim == 2 and len(y) > 1 else None
    t0 = time.process_time()
    try:
        if batch is not None:
            batch(y, dt, np.tile(prior, (len(y), 1)), **options)
        else:
            methods.get(name)(y if y.ndim == 1 else y[0], dt, prior, **options)
    except Exception:  # noqa: BLE001 - a failed fit still costs what it cost, as in the workflow
        pass
    return (time.process_time() - t0) / (len(y) if batch is not None else 1)


def time_fits(grid: dict, entries: list[str], replicates: int, batch_records: int, noises=None, progress=print):
    """Per (entry, noise, N): median CPU s per fit; and per cell the seconds to simulate it. ``noises``: time
    only these of the grid's noise levels (default all)."""
    setups = {e: method_setup(e, (grid.get("method_overrides") or {}).get(e, [])) for e in entries}
    fits, data_s = {}, {}
    warm = make_cell(DatasetConfig(noise_ug=100.0, n_samples=64, replicates=2, seed=1))["accel_m_s2"]
    for name, prior, options in setups.values():           # first-call costs (caches, JIT) are start-up
        _one_fit(name, warm if methods.get_batch(name) else warm[0], 0.02, prior, options)
    for noise in noises or grid["noise_ug"]:
        for n in grid["n_samples"]:
            t0 = time.process_time()
            cell = make_cell(DatasetConfig(noise_ug=noise, n_samples=n, replicates=grid["replicates"],
                                           seed=grid["seed"], dt_s=grid.get("dt_s", 0.02),
                                           bias_m_s2=grid.get("bias_m_s2", 0.0)))
            data_s[(noise, n)] = time.process_time() - t0
            y, dt = cell["accel_m_s2"], float(cell["dt_s"])
            for e, (name, prior, options) in setups.items():
                if methods.get_batch(name) is not None:
                    fits[(e, noise, n)] = _one_fit(name, y[:batch_records], dt, prior, options)
                else:
                    fits[(e, noise, n)] = float(np.median([_one_fit(name, y[r], dt, prior, options)
                                                           for r in range(min(replicates, len(y)))]))
            progress(f"{noise:g} µg, N = {n}: timed", flush=True)
    return fits, data_s


def startup_s(entry: str) -> float:
    """CPU seconds of a fresh interpreter that imports the identify job and makes one fit of ``entry`` on a
    64-sample record, less that fit's warm cost: what each identify batch pays once."""
    code = ("import os, time; os.environ.setdefault('OPENBLAS_NUM_THREADS', '1'); "
            "import experiments.jobs.identify; "
            "from experiments.benchmarks.sweep_cost import method_setup, _one_fit; "
            "from experiments.simulate.datasets import DatasetConfig, make_cell; "
            f"name, prior, options = method_setup({entry!r}, []); "
            "y = make_cell(DatasetConfig(noise_ug=100.0, n_samples=64, replicates=1, seed=1))['accel_m_s2'][0]; "
            "first = _one_fit(name, y, 0.02, prior, options); warm = _one_fit(name, y, 0.02, prior, options); "
            "print(time.process_time() - warm)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env=os.environ | {"OPENBLAS_NUM_THREADS": "1"})
    return float(out.stdout.strip().splitlines()[-1]) if out.returncode == 0 else float("nan")


def makespan(jobs: dict[str, float], cores: int) -> float:
    """Wall time of independent single-core jobs placed longest first on ``cores`` (LPT, Graham 1969:
    within 4/3 of the optimum)."""
    loads = [0.0] * cores
    for s in sorted(jobs.values(), reverse=True):
        heapq.heapreplace(loads, loads[0] + s)
    return max(loads)


def nearest_noise(noise: float, timed) -> float:
    """The timed noise level nearest to ``noise`` in log scale (a cell not timed is charged as it)."""
    return min(timed, key=lambda x: abs(np.log(x / noise)))


def predict(grid: dict, fits: dict, data_s: dict, starts: dict, cores: int) -> dict:
    """CPU s per entry's batch, the datasets batch, and the predicted wall on ``cores``; every cell of the
    grid counted, each untimed noise level charged as the nearest timed one (:func:`nearest_noise`)."""
    r = grid["replicates"]
    timed = sorted({k[0] for k in data_s})
    cells = [(nearest_noise(x, timed), n) for x in grid.get("noise_ug", timed) for n in grid.get("n_samples", [])]
    cells = cells or list(data_s)
    entries = list(dict.fromkeys(k[0] for k in fits))
    batch = {e: starts.get(e, 0.0) + sum(r * fits[(e, x, n)] for x, n in cells) for e in entries}
    data = sum(data_s[c] for c in cells)
    total = sum(batch.values())
    return {"batch_cpu_s": batch, "data_s": data, "identify_cpu_s": total,
            "wall_s": data + makespan(batch, cores), "bound_s": data + max(total / cores, max(batch.values()))}


def _fmt_s(s: float) -> str:
    return f"{s:.0f} s ({s / 60:.1f} min)" if s < 5400 else f"{s / 3600:.2f} h"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="paper", help="configs/grid/<name>.yaml, or a path to a grid file")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--replicates", type=int, default=1, help="fits timed per cell and method (median)")
    ap.add_argument("--batch-records", type=int, default=10, help="records per lock-step batch call timed")
    ap.add_argument("--methods", nargs="*", help="entries of the grid's methods list (default: all)")
    ap.add_argument("--no-startup", action="store_true", help="do not measure each batch's process start-up")
    ap.add_argument("--noise-ug", type=float, nargs="+",
                    help="time only these of the grid's noise levels; the others are charged as the nearest")
    ap.add_argument("--label", default="", help="suffix of the CSV written (e.g. before, after)")
    args = ap.parse_args(argv)
    try:
        grid = load_grid(args.grid)
        if args.cores < 1 or args.replicates < 1 or args.batch_records < 1:
            raise ValueError(f"--cores {args.cores}, --replicates {args.replicates}, --batch-records "
                             f"{args.batch_records}: each must be at least 1")
        entries = args.methods or list(grid["methods"])
        unknown = [e for e in entries if e not in grid["methods"]]
        if unknown:
            raise ValueError(f"--methods {' '.join(unknown)}: not in grid {grid['name']}'s methods")
        if args.noise_ug and not set(args.noise_ug) <= set(grid["noise_ug"]):
            raise ValueError(f"--noise-ug {args.noise_ug}: not all among the grid's noise levels {grid['noise_ug']}")
        for e in entries:
            method_setup(e, [])
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    load0 = os.getloadavg()[0]
    t_wall = time.perf_counter()
    # one BLAS thread, as the workflow's jobs (experiments/workflow/rules/common.smk sets OPENBLAS_NUM_THREADS=1 before
    # they start); numpy is loaded by now (this package's __init__), so the limit is set through threadpoolctl:
    # OpenBLAS's idle threads spin on a busy machine and their CPU time counted 5-25x a peer's fit
    with threadpool_limits(limits=1):
        fits, data_s = time_fits(grid, entries, args.replicates, min(args.batch_records, grid["replicates"]),
                                 args.noise_ug)
    starts = {} if args.no_startup else {e: startup_s(e) for e in entries}
    pred = predict(grid, fits, data_s, starts, args.cores)
    ns, noises = list(grid["n_samples"]), list(args.noise_ug or grid["noise_ug"])
    print(f"\n## Cost model of grid `{grid['name']}`: {len(noises)} noise levels x {len(ns)} lengths x R = "
          f"{grid['replicates']} on {args.cores} cores (CPU time per fit, one BLAS thread; load average "
          f"{load0:.1f} -> {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs while timing)"
          + (f"; timed at {', '.join(f'{x:g}' for x in noises)} µg only, each other level charged as the nearest"
             if args.noise_ug else "") + "\n")
    show = [n for n in (256, 2048) if n in ns] or ns[-1:]
    print("| method | " + " | ".join(f"ms per fit, N = {n} (median over noise)" for n in show)
          + " | batch start-up s | batch CPU | share |")
    print("|---|" + "---|" * (len(show) + 3))
    for e in sorted(pred["batch_cpu_s"], key=pred["batch_cpu_s"].get, reverse=True):
        per_n = [1e3 * float(np.median([fits[(e, x, n)] for x in noises])) for n in show]
        cpu = pred["batch_cpu_s"][e]
        print(f"| `{e}` | " + " | ".join(f"{v:.3g}" for v in per_n)
              + f" | {f'{starts[e]:.2g}' if e in starts else 'not measured'} | {_fmt_s(cpu)} | "
              f"{cpu / pred['identify_cpu_s']:.1%} |")
    print(f"\n- datasets batch: {_fmt_s(pred['data_s'])}; identify batches: {_fmt_s(pred['identify_cpu_s'])} of CPU")
    print(f"- predicted wall on {args.cores} cores (datasets, then the batches longest first): "
          f"**{_fmt_s(pred['wall_s'])}** (lower bound {_fmt_s(pred['bound_s'])}); serial aggregate/track "
          "steps not included")
    print(f"- this measurement took {_fmt_s(time.perf_counter() - t_wall)} of wall time")
    rows = ["entry,noise_ug,n_samples,cpu_s_per_fit,replicates"]
    rows += [f"{e},{x:g},{n},{t:.6g},{grid['replicates']}" for (e, x, n), t in fits.items()]
    out = ROOT / "results" / "bench" / "sweep_cost" / f"{grid['name']}{'_' + args.label if args.label else ''}.csv"
    atomic_write_text(out, "\n".join(rows) + "\n")
    print(f"- per-cell fit times: {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import run_with_page

    raise SystemExit(run_with_page(main, "sweep_cost"))   # prints, and writes results/bench/sweep_cost.md
