"""Basin of attraction of a method on random structures other than the paper's (pem's robustness target).

    python -m experiments.benchmarks.basin                         # pem, 100 structures (~15 min on a busy core)
    python -m experiments.benchmarks.basin --structures 20 --method pem --variant paper
    python -m experiments.benchmarks.basin --failures failures.json   # also write every failure case

A *structure*: m ∈ {2, …, 5} modes, frequencies log-uniform in 1.5–80 rad/s and at least 8 % apart,
ζ uniform in 0.002–0.03, modal amplitudes log-uniform in 0.3–1 (arbitrary units), phases uniform, and a
constant sensor offset (uniform ±0.5) in every other structure. The record: N samples at Δt = 0.02 s plus
white noise of σ = ``--noise`` × the largest amplitude. A structure is redrawn until every mode is
identifiable in the record (CRLB with the offset unknown ≤ 1 % of ω and ≤ 10 % of the distance to the
nearest mode, experiments.report.scoring.identifiable): a failure is then a local minimum, not noise.

Each structure is identified from priors with
- a common error: prior = c · ω for every c of ``--scales`` (default 0.7 0.8 0.9 1.1 1.2 1.3);
- independent errors: prior = ω (1 + s u), u ~ U(−1, 1) per mode, s = ``--spread`` (0.25), ``--draws`` draws;
  with ``--spread-min`` a > 0 every error is at least a: prior = ω (1 ± (a + (s − a)|u|)), the sign u's
  (``--spread-min 0.15``: each mode independently 15–25 % off);
priors sorted. ``--scales`` with no value: independent errors only. Success per trial: every mode within
tolerance of the truth (experiments.report.success).

Each mode of a trial is also classed by what the method *said*: a mode it calls determined
(``converged_per_mode`` True and a finite frequency) is either right (within tolerance) or **called
determined but wrong** — a crossed label, a mode in the wrong slot, a local minimum reported as an answer;
a mode it flags as not determined is **honestly not determined**. The first is the dangerous failure (a
user trusts it); the second costs only the mode. The report gives both per trial and per structure (a
structure counts once if any of its trials has such a mode).

Seeds: structure k draws from ``default_rng([seed, 0x4241, k])`` ("BA"), its noise and independent priors from
``default_rng([seed, 0x4241, k, trial])``; ``--seed`` defaults to 4242, never the grids' scoring seed 20261121.
The method's options are those of ``configs/method/<method>[_<variant>].yaml`` (its ``defaults`` chain).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

import methods
from experiments import paths
from experiments.io import write_json
from experiments.report.scoring import identifiable
from experiments.report.success import mode_success, tolerance
from experiments.simulate.crlb import crlb_std

__all__ = ["STREAM", "SCORING_SEED", "DT_S", "ZETA", "METHOD_DIR", "method_options", "draw_structure", "record",
           "trials", "run", "report", "main"]

STREAM = 0x4241
SCORING_SEED = 20261121
DT_S = 0.02
F_MIN, F_MAX, MIN_RATIO = 1.5, 80.0, 1.08
ZETA = (0.002, 0.03)
METHOD_DIR = paths.METHOD_CONFIGS


def method_options(config: str) -> dict:
    """The ``options`` of a method config, following its ``defaults`` chain (parents first)."""
    cfg = yaml.safe_load((METHOD_DIR / f"{config}.yaml").read_text()) or {}
    out = {}
    for parent in cfg.get("defaults") or []:
        if isinstance(parent, str) and parent != "_self_" and not parent.endswith("_schema"):
            out |= method_options(parent)
    return out | (cfg.get("options") or {})


def draw_structure(seed: int, k: int, n_samples: int, noise: float) -> dict:
    """Structure k (see the module docstring), redrawn until every mode is identifiable."""
    rng = np.random.default_rng([seed, STREAM, k])
    while True:
        m = int(rng.integers(2, 6))
        w = np.sort(np.exp(rng.uniform(np.log(F_MIN), np.log(F_MAX), m)))
        if np.any(w[1:] / w[:-1] < MIN_RATIO):
            continue
        zeta = rng.uniform(*ZETA, m)
        amp = np.exp(rng.uniform(np.log(0.3), 0.0, m))
        phase = rng.uniform(0, 2 * np.pi, m)
        offset = float(rng.uniform(-0.5, 0.5)) if k % 2 else 0.0
        sigma = noise * amp.max()
        bound = crlb_std(w, zeta, amp, phase, n_samples, DT_S, sigma, offset=True)
        if np.all(identifiable(w, bound)):
            return {"k": k, "freq": w, "zeta": zeta, "amp": amp, "phase": phase, "offset": offset,
                    "sigma": sigma, "crlb": bound}


def record(s: dict, n_samples: int, rng) -> np.ndarray:
    t = np.arange(n_samples) * DT_S
    w, z = s["freq"], s["zeta"]
    clean = (s["amp"] * np.exp(-z * w * t[:, None]) * np.cos(w * np.sqrt(1 - z**2) * t[:, None] + s["phase"]))
    return clean.sum(axis=1) + s["offset"] + s["sigma"] * rng.standard_normal(n_samples)


def trials(s: dict, scales, spread: float, draws: int, seed: int, spread_min: float = 0.0):
    """(kind, value, prior, trial index) of one structure."""
    out = [("common", c, np.sort(c * s["freq"]), i) for i, c in enumerate(scales)]
    for d in range(draws):
        u = np.random.default_rng([seed, STREAM, s["k"], 1000 + d]).uniform(-1, 1, s["freq"].size)
        error = np.sign(u) * (spread_min + (spread - spread_min) * np.abs(u))      # = spread·u when spread_min = 0
        out.append(("independent", spread, np.sort(s["freq"] * (1 + error)), len(scales) + d))
    return out


def label_outcome(s: dict, freq, per_mode) -> tuple[bool, bool, bool]:
    """(any mode called determined but wrong, any mode honestly not determined, any crossed label) of one
    trial.

    A mode is *called determined* when the method's ``converged_per_mode`` says so and its frequency is
    finite; it is wrong when it is not within the success tolerance of its true mode
    (experiments.report.success.tolerance: 5 CRLB std or 0.5 %, at most half-way to the neighbour). A wrong
    one is a *crossed label* when it is within the tolerance of another true mode (the right frequency in
    the wrong slot), else an inaccurate one.
    """
    freq = np.asarray(freq, float)
    called = np.asarray(per_mode, bool) & np.isfinite(freq)
    right = mode_success(s["freq"], s["crlb"], freq, called)
    wrong = called & ~right
    tol = tolerance(s["freq"], s["crlb"])
    near = np.abs(np.where(np.isfinite(freq), freq, np.inf)[:, None] - s["freq"][None, :]) <= tol[None, :]
    np.fill_diagonal(near, False)
    return bool(wrong.any()), bool((~called).any()), bool((wrong & near.any(axis=1)).any())


def run(args) -> dict:
    name = args.method
    config = f"{name}_{args.variant}" if args.variant else name
    options = method_options(config)
    identify = methods.get(name)
    rows, failures = [], []
    t0 = time.perf_counter()
    for k in range(args.structures):
        s = draw_structure(args.seed, k, args.n_samples, args.noise)
        for kind, value, prior, i in trials(s, args.scales, args.spread, args.draws, args.seed, args.spread_min):
            y = record(s, args.n_samples, np.random.default_rng([args.seed, STREAM, k, i]))
            try:
                est = identify(y, DT_S, prior, **options)
                freq, conv, msg = np.asarray(est.frequencies, float), bool(est.converged), est.message
                per_mode = np.asarray(est.converged_per_mode, bool)
                std = np.asarray(est.std, float)
            except Exception as exc:  # noqa: BLE001 - a crash is a failure of the trial, recorded
                freq, conv, msg = np.full(prior.size, np.nan), False, f"{type(exc).__name__}: {exc}"
                per_mode, std = np.zeros(prior.size, bool), np.full(prior.size, np.nan)
            ok = bool(mode_success(s["freq"], s["crlb"], freq, [conv] * prior.size).all())
            wrong, undetermined, crossed = label_outcome(s, freq, per_mode)
            rows.append({"k": k, "m": s["freq"].size, "offset": s["offset"] != 0, "kind": kind, "value": value,
                         "success": ok, "converged": conv, "wrong_determined": wrong,
                         "not_determined": undetermined, "crossed": crossed})
            if not ok:
                failures.append({"structure": k, "kind": kind, "value": value, "true_rad_s": s["freq"],
                                 "damping": s["zeta"], "offset": s["offset"], "prior_rad_s": prior,
                                 "estimate_rad_s": freq, "converged": conv,
                                 "converged_per_mode": per_mode, "wrong_determined": wrong,
                                 "not_determined": undetermined, "std_rad_s": std,
                                 "message": str(msg)[:200]})
        if args.progress:
            print(f"structure {k + 1}/{args.structures}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return {"rows": rows, "failures": failures, "seconds": time.perf_counter() - t0, "config": config}


def report(result: dict, args) -> str:
    df = pd.DataFrame(result["rows"])
    lines = [f"{result['config']}: {args.structures} random structures (seed {args.seed}), N = {args.n_samples}, "
             f"noise {args.noise:g} × largest amplitude, {result['seconds']:.0f} s", ""]

    def rate(sub):
        failed = 100 * (~sub["converged"]).mean()
        return f"{100 * sub['success'].mean():.1f} % of {len(sub)} (not converged {failed:.1f} %)"

    n_struct = df["k"].nunique()
    by_structure = df.groupby("k")[["wrong_determined", "not_determined", "crossed"]].any()
    lines.append(f"called determined but wrong: {100 * df['wrong_determined'].mean():.1f} % of {len(df)} trials, "
                 f"{int(by_structure['wrong_determined'].sum())} of {n_struct} structures "
                 f"({100 * by_structure['wrong_determined'].mean():.1f} %)")
    lines.append(f"  of which a crossed label (another true mode's frequency): {100 * df['crossed'].mean():.1f} % "
                 f"of trials, {int(by_structure['crossed'].sum())} of {n_struct} structures")
    lines.append(f"identifiable but not determined (some mode; every mode here is identifiable): "
                 f"{100 * df['not_determined'].mean():.1f} % of trials, "
                 f"{int(by_structure['not_determined'].sum())} of {n_struct} structures")
    for kind, g in df.groupby("kind"):
        per = g.groupby("k")[["wrong_determined", "not_determined"]].any()
        lines.append(f"  {kind}: determined but wrong {100 * g['wrong_determined'].mean():.1f} % of {len(g)} trials "
                     f"({int(per['wrong_determined'].sum())} of {len(per)} structures), identifiable but not "
                     f"determined {100 * g['not_determined'].mean():.1f} % ({int(per['not_determined'].sum())} "
                     f"of {len(per)} structures)")
    common, indep = df[df["kind"] == "common"], df[df["kind"] == "independent"]
    if len(common):
        lines.append(f"common factor {min(args.scales):g}…{max(args.scales):g}: success {rate(common)}")
    for c, g in common.groupby("value"):
        lines.append(f"  c = {c:g}: {rate(g)}")
    spread = (f"{100 * args.spread_min:g}–{100 * args.spread:g} %" if args.spread_min else
              f"±{100 * args.spread:g} %")
    if len(indep):
        lines.append(f"independent {spread}: success {rate(indep)}")
    for label, g in df.groupby("offset"):
        lines.append(f"{'with' if label else 'without'} offset: success {rate(g)}")
    for m, g in df.groupby("m"):
        lines.append(f"{m} modes: success {rate(g)}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="pem", choices=methods.names())
    ap.add_argument("--variant", default="", help="configs/method/<method>_<variant>.yaml (default: none)")
    ap.add_argument("--structures", type=int, default=100)
    ap.add_argument("--scales", type=float, nargs="*", default=[0.7, 0.8, 0.9, 1.1, 1.2, 1.3])
    ap.add_argument("--spread", type=float, default=0.25)
    ap.add_argument("--spread-min", type=float, default=0.0, help="least independent error (0: ±spread·U(−1, 1))")
    ap.add_argument("--draws", type=int, default=2, help="independent-error priors per structure")
    ap.add_argument("--n-samples", type=int, default=512)
    ap.add_argument("--noise", type=float, default=0.01, help="noise 1σ relative to the largest amplitude")
    ap.add_argument("--seed", type=int, default=4242)
    ap.add_argument("--failures", type=Path, help="write every failed trial to this JSON file")
    ap.add_argument("--progress", action="store_true")
    args = ap.parse_args(argv)
    if args.seed == SCORING_SEED:
        print(f"error: --seed {args.seed} is the grids' scoring seed; use another", file=sys.stderr)
        return 2
    if not (METHOD_DIR / f"{args.method}{'_' + args.variant if args.variant else ''}.yaml").exists():
        print(f"error: no config configs/method/{args.method}_{args.variant}.yaml", file=sys.stderr)
        return 2
    if (args.structures < 1 or args.n_samples < 8 or not 0 <= args.spread < 1 or min(args.scales, default=1) <= 0
            or not 0 <= args.spread_min <= args.spread or (not args.scales and args.draws < 1)):
        print(f"error: --structures ≥ 1, --n-samples ≥ 8, 0 ≤ --spread-min ≤ --spread < 1, --scales > 0 and a "
              f"trial per structure are required (got --spread {args.spread}, --spread-min {args.spread_min}, "
              f"--scales {args.scales}, --draws {args.draws})", file=sys.stderr)
        return 2
    result = run(args)
    print(report(result, args))
    if args.failures:
        write_json(args.failures, result["failures"])
        print(f"wrote {args.failures} ({len(result['failures'])} failures)")
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import one_blas_thread, run_with_page

    with one_blas_thread():
        raise SystemExit(run_with_page(main, "basin"))   # prints, and writes results/bench/basin.md
