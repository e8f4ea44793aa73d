"""Is a reported std honest when the record is not what the model assumes? Coverage per mismatch axis.

    python -m experiments.benchmarks.mismatch [--grid configs/grid/mismatch.yaml] [--replicates R]
                                              [--methods pem akf] [--out results/bench/mismatch]

For each cell of the grid (the mismatch axes of ``experiments.simulate.mismatch``: coloured noise, an
unmodelled mode, a Duffing frequency, saturation, quantisation, and the plain cell; the records made by the
workflow's ``experiments.simulate.datasets.make_cell``), every method of the grid identifies the R records
with its own config's prior and options (``configs/method/<name>.yaml``), and the errors against the
plant's eigenfrequencies are scored by ``experiments.report.coverage.coverage`` on the modes each
replicate determined (``converged_per_mode``). For pem these stds are scored:

- ``reported``: what it answers (the white-noise std; when its residual check fails, ω₀ of the
  backbone-chirp fit and its robust std for every mode the record determines, the robust std elsewhere;
  with ``pem:record``, the robust std with the drift term for a drifting mode);
- ``white``: the white-noise std σ̂√diag((JᵀJ)⁻¹) of the same fit;
- ``robust``: the sandwich std, without the drift term;
- ``before``: pem as it was before the residual check (``absorb_lines`` and ``drift_segments`` off,
  the white-noise std);
- on the Duffing cells, the drift test's claims (:func:`drift_claims`).

The truth of a Duffing cell depends on the claim (:func:`duffing_truth`): an answer at small amplitude is
scored against the linear frequency ω; an answer about the record (a mode whose segments agree, and the
white/robust/spectral rows, which describe the whole-record fit) against the frequency the record holds,
``experiments.simulate.mismatch.record_frequency_rad_s`` (where a constant-frequency fit of the mode's
noise-free record converges to): nothing in a record whose amplitude hardly changes tells the frequency at
another amplitude.

``flagged`` is the share of records whose final residual check failed; ``absorbed`` the share whose
residual line outside every band was refitted as an extra mode (``methods.pem._lines``). Rows with
``mode`` = "all" pool the modes; rows with ``mode`` = 1 … m give the reported std's coverage per mode
(:func:`per_mode`), printed as one table per method (:func:`mode_table`). ``--seed`` draws the records
from another seed than the grid's (a design seed). Writes ``coverage.csv`` / ``coverage.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

import methods
from experiments import paths
from experiments.io import markdown_table, write_table
from experiments.report.coverage import IDEAL_1STD, IDEAL_2STD, coverage
from experiments.simulate import mismatch, scenarios
from experiments.simulate.datasets import DatasetConfig, ScenarioConfig, make_cell

__all__ = ["DEFAULT_GRID", "method_setup", "cell_label", "BEFORE", "run_method", "std_kinds", "drift_claims",
           "duffing_truth", "per_mode", "score", "cell_records", "run", "mode_table", "main"]

DEFAULT_GRID = str(paths.GRIDS / "mismatch.yaml")


def method_setup(name: str) -> tuple[str, list[float], dict]:
    """(registry name, prior, options) of a method config ``name`` or variant ``name:variant``."""
    base, _, variant = name.partition(":")
    cfg = OmegaConf.load(paths.METHOD_CONFIGS / f"{base}.yaml")
    options = OmegaConf.to_container(cfg.get("options") or OmegaConf.create({}))
    if variant:
        options.update(OmegaConf.to_container(OmegaConf.load(paths.METHOD_CONFIGS / f"{base}_{variant}.yaml")
                                              .get("options") or OmegaConf.create({})))
    return base, list(cfg.prior_rad_s), options


def cell_label(axes: dict) -> tuple[str, str]:
    """(axis, value) naming a cell; the plain cell is ("none", "")."""
    if not axes:
        return "none", ""
    (axis, value), = axes.items()
    return axis, f"{value:g}"


# pem as it was before the residual check: no line absorbed, no drift test, and its white-noise std
BEFORE = {"absorb_lines": False, "drift_segments": 0, "skip_clipped": False}


def run_method(name: str, records: np.ndarray, dt: float, extra_options: dict | None = None) -> list:
    base, prior, options = method_setup(name)
    options = {**options, **(extra_options or {})}
    batch = methods.get_batch(base)
    if batch is not None:
        return batch(records, dt, prior, **options)
    identify = methods.get(base)
    return [identify(y, dt, prior, **options) for y in records]


def std_kinds(est) -> dict[str, np.ndarray]:
    """The stds a method's Estimate offers: ``reported`` always; pem's ``white`` and ``robust`` too."""
    out = {"reported": est.std}
    check = est.extra.get("residual_check") if isinstance(est.extra, dict) else None
    if check is not None:
        out["white"] = est.extra.get("white_noise_std", est.std)
        out["robust"] = check.get("robust_std_rad_s", est.std)       # a white residual: its own std
        out["spectral"] = check.get("spectral_std_rad_s", est.std)
    return out


def drift_claims(est, truth: np.ndarray, amplitude: np.ndarray, delta: float) -> dict:
    """What pem's drift test claims on a Duffing record, as (error, std) pairs: ``small_amplitude`` — the
    amplitude line's ω₀ ± its std against the linear frequency; ``at_reference_amplitude`` — the answer ±
    its std against the backbone ω√(1 + 2δ(a_ref/a)²) at the amplitude a_ref the answer says it refers to."""
    drift = est.extra.get("drift") if isinstance(est.extra, dict) else None
    if drift is None:
        return {}
    ref = np.asarray(drift["reference_amplitude_m_s2"], float)
    drifting = np.asarray(drift["drifting"], bool) & est.converged_per_mode
    # the backbone only where a claim is scored: a mode that does not drift may carry a reference amplitude
    # far outside the backbone's range (1 + 2δA² < 0), whose square root would only warn and be masked
    at_ref = mismatch.backbone_rad_s(truth, np.where(drifting, ref / amplitude, 0.0), delta)
    return {"small_amplitude": (np.where(drifting, drift["small_amplitude_rad_s"] - truth, np.nan),
                                drift["small_amplitude_std"]),
            "at_reference_amplitude": (np.where(drifting, np.asarray(drift["whole_record"]) - at_ref, np.nan),
                                       np.hypot(est.extra["residual_check"]["robust_std_rad_s"],
                                                np.nan_to_num(drift["tau_rad_s"])))}


def duffing_truth(truth: np.ndarray, record: np.ndarray):
    """``truths(est)`` for a Duffing cell: (truth of the reported frequencies, truth of the whole-record fit),
    per mode; the linear ω where pem reported the small-amplitude frequency, else the record's (module doc)."""
    def truths(est):
        reported = np.asarray(est.extra.get("drift_reported") or [""] * truth.size) if isinstance(est.extra, dict) \
            else np.full(truth.size, "")
        return np.where(reported == "small_amplitude", truth, record), record
    return truths


def per_mode(estimates: list, truth: np.ndarray, truths=None) -> list[dict]:
    """Coverage of the reported std per mode (one row per mode, ``mode`` = 1 … m): the pooled figure of
    :func:`score` can hide a std too narrow for one mode and too wide for another."""
    errors, stds = [], []
    for est in estimates:
        ok = est.converged_per_mode & np.isfinite(est.frequencies)
        reported_truth = truth if truths is None else truths(est)[0]
        errors.append(np.where(ok, est.frequencies - reported_truth, np.nan))
        stds.append(np.asarray(est.std, float))
    e, s = np.array(errors), np.array(stds)
    return [{"std": "reported", "mode": i + 1, **coverage(e[:, i], s[:, i])} for i in range(e.shape[1])]


def score(estimates: list, truth: np.ndarray, claims=None, truths=None) -> list[dict]:
    """Coverage rows (one per std kind) of a method's R estimates; ``claims(est)``: more (error, std)
    pairs by name (:func:`drift_claims`); ``truths(est)``: (truth of the reported frequencies, truth of the
    whole-record fit) when they are not ``truth`` (:func:`duffing_truth`)."""
    pooled: dict[str, tuple[list, list]] = {}
    flagged, absorbed = [], []
    for est in estimates:
        ok = est.converged_per_mode & np.isfinite(est.frequencies)
        reported_truth, whole_truth = (truth, truth) if truths is None else truths(est)
        drift = est.extra.get("drift") if isinstance(est.extra, dict) else None
        whole = np.asarray(drift["whole_record"], float) if drift else est.frequencies
        pairs = {kind: (np.where(ok, est.frequencies - reported_truth, np.nan) if kind == "reported" else
                        np.where(ok, whole - whole_truth, np.nan), std)
                 for kind, std in std_kinds(est).items()}
        pairs.update(claims(est) if claims is not None else {})
        for kind, (error, std) in pairs.items():
            e, s = pooled.setdefault(kind, ([], []))
            e.append(np.asarray(error, float))
            s.append(np.asarray(std, float))
        check = est.extra.get("residual_check") if isinstance(est.extra, dict) else None
        if check is not None:
            flagged.append(not check["white"])
            absorbed.append("absorbed_line_rad_s" in est.extra)
    rows = []
    for kind, (e, s) in pooled.items():
        row = {"std": kind, **coverage(np.array(e), np.array(s))}
        row["flagged"] = float(np.mean(flagged)) if flagged else np.nan
        row["absorbed"] = float(np.mean(absorbed)) if absorbed else np.nan
        rows.append(row)
    return rows


def cell_records(grid: dict, cell: dict, replicates: int) -> dict:
    """The cell's dataset as the workflow makes it (``experiments.simulate.datasets.make_cell``)."""

    axes = dict(cell["axes"])
    cfg = DatasetConfig(noise_ug=float(cell["noise_ug"]), n_samples=int(cell["n_samples"]), replicates=replicates,
                        dt_s=float(axes.pop("dt_s", grid.get("dt_s", 0.02))), seed=int(grid["seed"]),
                        bias_m_s2=float(axes.pop("bias_m_s2", grid.get("bias_m_s2", 0.0))),
                        scenario=ScenarioConfig(**axes))
    return make_cell(cfg)


def run(grid: dict, replicates: int | None = None, method_names: list[str] | None = None,
        seed: int | None = None) -> pd.DataFrame:
    reps = int(replicates or grid["replicates"])
    grid = grid if seed is None else {**grid, "seed": int(seed)}
    rows = []
    for cell in scenarios.grid_cells(grid).values():
        axes = {k: v for k, v in cell["axes"].items() if k in mismatch.AXES}
        data = cell_records(grid, cell, reps)
        truth, dt = data["truth_freq_rad_s"], float(data["dt_s"])
        axis, value = cell_label(axes)
        claims = truths = None
        if axes.get("duffing"):
            delta = float(axes["duffing"])

            def claims(est, delta=delta, amp=data["truth_amplitude_m_s2"], truth=truth):
                return drift_claims(est, truth, amp, delta)

            truths = duffing_truth(truth, mismatch.record_frequency_rad_s(
                truth, data["truth_damping"], delta, data["accel_m_s2"].shape[1], dt))
        for name in method_names or grid["methods"]:
            t0 = time.perf_counter()
            estimates = run_method(name, data["accel_m_s2"], dt)
            seconds = time.perf_counter() - t0
            for row in score(estimates, truth, claims, truths):
                rows.append({"axis": axis, "value": value, "method": name, "mode": "all", **row,
                             "seconds": seconds})
            for row in per_mode(estimates, truth, truths):
                rows.append({"axis": axis, "value": value, "method": name, **row, "seconds": np.nan})
            if name.partition(":")[0] == "pem":
                before = [dataclasses.replace(e, std=e.extra.get("white_noise_std", e.std), extra={})
                          for e in run_method(name, data["accel_m_s2"], dt, BEFORE)]
                row = next(r for r in score(before, truth, truths=truths) if r["std"] == "reported")
                rows.append({"axis": axis, "value": value, "method": name, "mode": "all", **row,
                             "std": "before", "seconds": np.nan})
            print(f"{axis:>16} {value:>6} {name:>10}: {seconds:6.1f} s", flush=True)
    return pd.DataFrame(rows)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default=DEFAULT_GRID)
    parser.add_argument("--replicates", type=int, default=None)
    parser.add_argument("--methods", nargs="+", default=None)
    parser.add_argument("--seed", type=int, default=None, help="the records' seed (default: the grid's)")
    parser.add_argument("--out", default="results/bench/mismatch")
    args = parser.parse_args(argv)
    if args.replicates is not None and args.replicates < 1:
        parser.exit(2, f"error: --replicates = {args.replicates} must be at least 1\n")
    if args.seed is not None and args.seed < 0:
        parser.exit(2, f"error: --seed = {args.seed} must be a non-negative integer\n")
    try:
        grid = OmegaConf.to_container(OmegaConf.load(args.grid))
        for cell in scenarios.grid_cells(grid).values():
            mismatch.check_axes(mismatch.present(cell["axes"]))
        for name in args.methods or grid["methods"]:
            method_setup(name)
    except (ValueError, OSError, KeyError) as exc:
        parser.exit(2, f"error: {exc}\n")
    table = run(grid, args.replicates, args.methods, args.seed)
    write_table(table, Path(args.out) / "coverage")
    print(f"ideal: {IDEAL_1STD:.3f} within 1 std, {IDEAL_2STD:.3f} within 2 std")
    pooled = table["mode"] == "all"
    print(markdown_table(table[pooled].drop(columns=["seconds", "mode"]), ".3g"))
    print(mode_table(table[~pooled]))


def mode_table(rows: pd.DataFrame) -> str:
    """Coverage of the reported std per mode and scenario (rows), as "1σ / 2σ" in %, per method; a cell
    outside 60–80 % at 1σ or below 90 % at 2σ is marked ✗ (R = 50 per mode: ±6.6 points of binomial
    scatter at 68 %)."""
    lines = []
    for name, g in rows.groupby("method", sort=False):
        modes = sorted(g["mode"].unique())
        lines += ["", f"`{name}`: coverage of the reported std per mode, 1σ / 2σ (%)", "",
                  "| axis | value | " + " | ".join(f"mode {m}" for m in modes) + " |",
                  "|---|---|" + "---|" * len(modes)]
        for (axis, value), cell in g.groupby(["axis", "value"], sort=False):
            texts = []
            for m in modes:
                r = cell[cell["mode"] == m].iloc[0]
                if not r["n_with_std"]:
                    texts.append("–")
                    continue
                c1, c2 = 100 * r["coverage_1std"], 100 * r["coverage_2std"]
                mark = "" if 60 <= c1 <= 80 and c2 >= 90 else " ✗"
                texts.append(f"{c1:.0f} / {c2:.0f} ({int(r['n_with_std'])}){mark}")
            lines.append(f"| {axis} | {value} | " + " | ".join(texts) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
