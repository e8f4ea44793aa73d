"""The prior as information: pem's MAP fit against the Bayesian yardstick on truths drawn from the prior.

    python -m experiments.benchmarks.prior                          # writes results/bench/prior.md
    python -m experiments.benchmarks.prior --records 40 --n-samples 20 32 --noise-ug 1000
    python -m experiments.benchmarks.prior --records 60 --n-samples 20 32 64 --noise-ug 1000 --posterior-draws 256
    python -m experiments.benchmarks.prior --part filters --n-samples 256 1500 --records 40
    python -m experiments.benchmarks.prior --part yardstick --records 30 --n-samples 32 64 --noise-ug 1000

Setting: the paper's four modes (Table 3, ζ = 0.005, tip amplitudes 1.04, 4.10, 4.84, 6.42 m/s² with signs
+, −, −, +: PHYSICS.md §4), Δt = 0.02 s. The prior is ω ~ N(μ, diag(s²)) with μ = Table 3 and s =
``--rel-std`` × μ, truncated to increasing frequencies; each record's truth is drawn from it, then white
noise of ``--noise-ug`` µg. Every estimator sees the same records:

- **prior mean**: μ itself;
- **pem (ML)**: ``methods.get("pem")`` with prior μ, no prior_std_rad_s (today's default);
- **pem:map**: the options of ``configs/method/pem_map.yaml`` (its damping prior) with
  ``prior_std_rad_s = s`` (methods/pem/_map.py);
- **pem:map sampled** (with ``--posterior-draws K``): the same with ``posterior_draws = K``, its posterior
  mean by importance sampling around the MAP (methods/pem/_map.py);
- **MMSE**: the posterior mean by sequential Monte Carlo (experiments.simulate.bayes; ``--draws``
  particles, linear unknowns projected out, σ known) under pem:map's own prior, the damping prior
  included: the attainable limit for that knowledge; and the same with ζ known, beside pem:map with ζ held;
- **van Trees**: the bound (E_prior[J] + J_prior)⁻¹ (experiments.simulate.bayes), offset unknown.

Reported per (noise, N, mode): the RMSE of each, MAP/MMSE, and the median time of one MAP and one ML fit.
Seeds: ``default_rng([seed, 0x5052, 0x4d41, noise_ng, N])`` ("PR", "MA"); ``--seed`` defaults to 7 and the
grids' scoring seed 20261121 is refused. Timing figures depend on the machine's load: the header says it.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

import methods
from experiments.benchmarks import one_blas_thread
from experiments.benchmarks.basin import method_options
from experiments.io import atomic_write_text
from experiments.simulate import bayes
from experiments.simulate.crlb import crlb_std

__all__ = ["TRUE_RAD_S", "AMPLITUDE_M_S2", "PHASE_RAD", "ZETA", "DT_S", "UG", "SCORING_SEED", "STREAM", "cell",
           "report", "filters", "yardstick", "main"]

TRUE_RAD_S = np.array([3.23, 20.24, 22.00, 56.67])        # Table 3
AMPLITUDE_M_S2 = np.array([1.04, 4.10, 4.84, 6.42])       # PHYSICS.md §3
PHASE_RAD = np.array([0.0, np.pi, np.pi, 0.0])            # tip signs +, −, −, +
ZETA = np.full(4, 0.005)
DT_S = 0.02
UG = 9.80665e-6
SCORING_SEED = 20261121
STREAM = (0x5052, 0x4D41)
SAMPLED = "pem:map sampled"


def cell(noise_ug: float, n: int, args) -> dict:
    """One (noise, N) cell: the records, every estimator's errors, the yardstick and the fit times."""
    mu, s = TRUE_RAD_S, args.rel_std * TRUE_RAD_S
    sigma = noise_ug * UG
    rng = np.random.default_rng([args.seed, *STREAM, int(round(noise_ug * 1000)), n])
    t = np.arange(n) * DT_S
    truths = bayes.draw_prior(rng, mu, s, args.records, ordered=True)
    pem = methods.get("pem")
    map_options = method_options("pem_map") | {"prior_std_rad_s": s.tolist()}
    fits = {"pem (ML)": {}, "pem:map": map_options,
            "pem:map ζ known": map_options | {"estimate_damping": False, "damping_ratio": float(ZETA[0])}}
    if args.posterior_draws:
        fits[SAMPLED] = map_options | {"posterior_draws": args.posterior_draws}
    err = {k: np.zeros((args.records, 4)) for k in ("prior mean", *fits, "MMSE", "MMSE ζ known")}
    det = {k: np.zeros((args.records, 4), bool) for k in fits}
    cover = {k: np.zeros((args.records, 4), bool) for k in fits}
    times = {k: [] for k in fits}
    ess, stages = np.zeros(args.records), np.zeros(args.records)
    for r, w in enumerate(truths):
        y = bayes.signal(w, ZETA, AMPLITUDE_M_S2, PHASE_RAD, t) + sigma * rng.standard_normal(n)
        err["prior mean"][r] = mu - w
        if n <= args.mmse_max_n:
            post, ess[r], stages[r] = bayes.smc_posterior_mean(y, t, mu, s, ZETA, sigma, rng, particles=args.draws,
                                                               damping_std=map_options["damping_prior_std"])
            known = bayes.smc_posterior_mean(y, t, mu, s, ZETA, sigma, rng, particles=args.draws)[0]
        else:
            post, known, ess[r], stages[r] = np.full(4, np.nan), np.full(4, np.nan), np.nan, np.nan
        err["MMSE"][r] = post - w
        err["MMSE ζ known"][r] = known - w
        for name, opts in fits.items():
            t0 = time.perf_counter()
            est = pem(y, DT_S, mu, **opts)
            times[name].append(time.perf_counter() - t0)
            err[name][r] = est.frequencies - w
            det[name][r] = est.converged_per_mode
            cover[name][r] = np.abs(est.frequencies - w) <= 2 * est.std
    rmse = {k: np.sqrt(np.nanmean(v**2, axis=0)) for k, v in err.items()}
    return {"noise_ug": noise_ug, "n": n, "rmse": rmse, "determined": {k: v.mean(axis=0) for k, v in det.items()},
            "cover2": {k: v.mean(axis=0) for k, v in cover.items()},
            "van_trees": bayes.van_trees_std(mu, s, ZETA, AMPLITUDE_M_S2, PHASE_RAD, n, DT_S, sigma, offset=True,
                                             known_damping=True),
            "crlb": crlb_std(mu, ZETA, AMPLITUDE_M_S2, PHASE_RAD, n, DT_S, sigma, offset=True),
            "ess_median": float(np.median(ess)), "stages": float(np.median(stages)),
            "ms": {k: 1e3 * float(np.median(v)) for k, v in times.items()},
            "ms95": {k: 1e3 * float(np.percentile(v, 95)) for k, v in times.items()},
            "scatter": {k: rmse[k] / np.sqrt(2 * args.records) for k in rmse}}


def report(cells: list[dict], args, seconds: float) -> str:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    cmd = " ".join(["python -m experiments.benchmarks.prior", *sys.argv[1:]])
    lines = ["# pem's MAP fit against the Bayesian yardstick (experiments.benchmarks.prior)", "",
             f"`{cmd}` — {seconds:.0f} s, load average {load:.1f} on {os.cpu_count()} cores "
             "(timings are noisy under load).", "",
             f"Truths drawn from the prior N(μ, s²), μ = Table 3, s = {args.rel_std:g} μ = "
             f"{np.round(args.rel_std * TRUE_RAD_S, 3).tolist()} rad/s (ordered), ζ = 0.005; {args.records} "
             f"records per cell, {args.draws} SMC particles. RMSE in rad/s; ± is the Monte-Carlo scatter of the "
             "RMSE (RMSE/√(2R)). MMSE: the attainable limit, the posterior mean (σ known) under pem:map's own "
             "prior, ζ ~ N(0.005, 0.01²) included (configs/method/pem_map.yaml); 'ζ known': both the MMSE and "
             "pem:map with ζ held at its true 0.005. van Trees: the bound with ζ known; CRLB: the classical "
             "bound at μ (no prior, ζ unknown). det.: share of records with "
             "converged_per_mode True. ESS (stages): median effective sample size of the SMC's last "
             "weighting and its tempering stages.", "",
             "| noise µg | N | mode | prior mean | pem (ML) | ML det. | pem:map | map det. | MMSE | map / MMSE | "
             "pem:map ζ known | MMSE ζ known | ratio ζ known | van Trees ζ known | CRLB |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in cells:
        r, d = c["rmse"], c["determined"]
        for i in range(4):
            lines.append(
                f"| {c['noise_ug']:g} | {c['n']} | {i + 1} | {r['prior mean'][i]:.3g} | {r['pem (ML)'][i]:.3g} | "
                f"{d['pem (ML)'][i]:.2f} | {r['pem:map'][i]:.3g} ± {c['scatter']['pem:map'][i]:.1g} | "
                f"{d['pem:map'][i]:.2f} | {r['MMSE'][i]:.3g} | {r['pem:map'][i] / r['MMSE'][i]:.2f} | "
                f"{r['pem:map ζ known'][i]:.3g} | {r['MMSE ζ known'][i]:.3g} | "
                f"{r['pem:map ζ known'][i] / r['MMSE ζ known'][i]:.2f} | {c['van_trees'][i]:.3g} | "
                f"{c['crlb'][i]:.3g} |")
    lines += ["", "Time per fit, ms (median, 95th percentile), and the SMC's effective sample size:", "",
              "| noise µg | N | pem (ML) | pem:map | pem:map ζ known | SMC ESS (stages) |", "|---|---|---|---|---|---|"]
    for c in cells:
        ms = " | ".join(f"{c['ms'][k]:.1f}, {c['ms95'][k]:.1f}" for k in ("pem (ML)", "pem:map", "pem:map ζ known"))
        lines.append(f"| {c['noise_ug']:g} | {c['n']} | {ms} | {c['ess_median']:.0f} ({c['stages']:.0f}) |")
    lines += ["", "Is pem:map's posterior std honest? Share of records with the truth within ±2 std (95 % for "
              "an honest Gaussian posterior), modes 1–4:", "",
              "| noise µg | N | pem:map | pem:map ζ known | pem (ML) |", "|---|---|---|---|---|"]
    for c in cells:
        cov = " | ".join(", ".join(f"{v:.2f}" for v in c["cover2"][k]) for k in ("pem:map", "pem:map ζ known",
                                                                              "pem (ML)"))
        lines.append(f"| {c['noise_ug']:g} | {c['n']} | {cov} |")
    if any(SAMPLED in c["rmse"] for c in cells):
        lines += ["", f"pem:map with its posterior mean refined by importance sampling (posterior_draws = "
                  f"{args.posterior_draws} per round, two rounds around the MAP; methods/pem/_map.py), beside the "
                  "default (the Laplace-mixture mean) on the same records: RMSE, ratio to the MMSE, and the time "
                  "per fit (median, 95th percentile):", "",
                  "| noise µg | N | pem:map RMSE, modes 1–4 | its / MMSE | sampled RMSE | sampled / MMSE | ms pem:map "
                  "| ms sampled |", "|---|---|---|---|---|---|---|---|"]
        for c in cells:
            r, mm = c["rmse"], c["rmse"]["MMSE"]
            lines.append(f"| {c['noise_ug']:g} | {c['n']} | {', '.join(f'{v:.3g}' for v in r['pem:map'])} | "
                         f"{', '.join(f'{v:.2f}' for v in r['pem:map'] / mm)} | "
                         f"{', '.join(f'{v:.3g}' for v in r[SAMPLED])} | "
                         f"{', '.join(f'{v:.2f}' for v in r[SAMPLED] / mm)} | "
                         f"{c['ms']['pem:map']:.1f}, {c['ms95']['pem:map']:.1f} | "
                         f"{c['ms'][SAMPLED]:.1f}, {c['ms95'][SAMPLED]:.1f} |")
    lines += ["", "Targets: at N = 20–64 pem:map within 1.2× the MMSE and never worse than the prior mean or "
              "pem (ML); ≤ 3 ms per MAP fit at N = 20–32; at long records pem:map equal to pem (ML) within "
              "scatter (there the van Trees bound, close to the CRLB, is the yardstick)."]
    return "\n".join(lines) + "\n"


def filters(args) -> str:
    """The Kalman filters scored as the Bayesian estimators they are: truths drawn from the prior their P0
    states (``prior_std_rad_s`` = s, so P0 = s²), is their posterior std honest? Coverage of ±1σ and ±2σ
    (68 % and 95 % for an honest Gaussian posterior), RMSE against the mean reported std, per mode."""
    mu, s = TRUE_RAD_S, args.rel_std * TRUE_RAD_S
    lines = ["# The filters as Bayesian estimators: coverage of their std under the prior (experiments."
             "benchmarks.prior --part filters)", "",
             f"`{' '.join(['python -m experiments.benchmarks.prior', *sys.argv[1:]])}`", "",
             f"Truths drawn from N(μ, s²) (ordered), μ = Table 3, s = {args.rel_std:g} μ; each filter gets "
             "prior μ and prior_std_rad_s = s (its P0 of the frequencies = s²), measurement = acceleration, "
             f"other options its defaults; {args.records} records per cell, noise as given. An honest Gaussian "
             "posterior covers the truth within ±1σ in 68 % and ±2σ in 95 % of records, and its RMSE equals "
             "its reported std.", "",
             "| method | noise µg | N | mode | RMSE | mean std | RMSE / std | within 1σ | within 2σ | det. |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name in ("akf", "wkf"):
        identify = methods.get(name)
        for noise in args.noise_ug:
            for n in args.n_samples:
                rng = np.random.default_rng([args.seed, *STREAM, 0x4B46, int(round(noise * 1000)), n])
                t = np.arange(n) * DT_S
                truths = bayes.draw_prior(rng, mu, s, args.records, ordered=True)
                err, std, det = (np.full((args.records, 4), np.nan) for _ in range(3))
                for r, w in enumerate(truths):
                    y = bayes.signal(w, ZETA, AMPLITUDE_M_S2, PHASE_RAD, t) + noise * UG * rng.standard_normal(n)
                    est = identify(y, DT_S, mu, measurement="acceleration", prior_std_rad_s=s.tolist())
                    err[r], std[r], det[r] = est.frequencies - w, est.std, est.converged_per_mode
                for i in range(4):
                    e, sd = np.abs(err[:, i]), std[:, i]
                    rmse = float(np.sqrt(np.nanmean(e**2)))
                    lines.append(f"| {name} | {noise:g} | {n} | {i + 1} | {rmse:.3g} | {np.nanmean(sd):.3g} | "
                                 f"{rmse / np.nanmean(sd):.2f} | {np.nanmean(e <= sd):.2f} | "
                                 f"{np.nanmean(e <= 2 * sd):.2f} | {np.nanmean(det[:, i]):.2f} |")
                print(f"{name} noise {noise:g} µg, N = {n}", file=sys.stderr)
    return "\n".join(lines) + "\n"


def yardstick(args) -> str:
    """Is the attainable limit converged? Per record, the posterior mean by SMC with ``--draws`` particles
    (two seeds), with 4 × as many, and by plain importance sampling (experiments.simulate.bayes.
    importance_posterior_mean, 20 000 draws, its kernel proposal on the particles of the second SMC run plus
    the prior): the RMSE each gives, and the RMS difference of each from the 4× run, as a share of that
    run's RMSE (the Monte-Carlo error of the yardstick itself)."""
    mu, s = TRUE_RAD_S, args.rel_std * TRUE_RAD_S
    z_std = method_options("pem_map")["damping_prior_std"]
    names = ("SMC", "SMC seed 2", "SMC 4×", "IS")
    t0 = time.perf_counter()
    lines = ["# Is the attainable limit converged? (experiments.benchmarks.prior --part yardstick)", "",
             f"`{' '.join(['python -m experiments.benchmarks.prior', *sys.argv[1:]])}`", "",
             f"Truths drawn from N(μ, s²) (ordered), μ = Table 3, s = {args.rel_std:g} μ, ζ ~ N(0.005, "
             f"{z_std:g}²) as pem:map's prior; {args.records} records per cell; SMC with {args.draws} particles "
             f"(two seeds) and {4 * args.draws}; IS: 20 000 importance draws. RMSE of each posterior-mean "
             "estimate in rad/s; 'diff.': RMS difference from the SMC 4× estimate over the records, as a share "
             "of its RMSE.", "",
             "| noise µg | N | mode | SMC | SMC seed 2 | SMC 4× | IS | diff. SMC | diff. seed 2 | diff. IS | "
             "IS ESS (median) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for noise in args.noise_ug:
        for n in args.n_samples:
            rng = np.random.default_rng([args.seed, *STREAM, 0x5953, int(round(noise * 1000)), n])
            t = np.arange(n) * DT_S
            sigma = noise * UG
            truths = bayes.draw_prior(rng, mu, s, args.records, ordered=True)
            est = {k: np.zeros((args.records, 4)) for k in names}
            ess = np.zeros(args.records)
            for r, w in enumerate(truths):
                y = bayes.signal(w, ZETA, AMPLITUDE_M_S2, PHASE_RAD, t) + sigma * rng.standard_normal(n)
                kw = {"damping_std": z_std}
                est["SMC"][r] = bayes.smc_posterior_mean(y, t, mu, s, ZETA, sigma, rng, particles=args.draws, **kw)[0]
                two = bayes.smc_posterior_mean(y, t, mu, s, ZETA, sigma, rng, particles=args.draws,
                                               particles_out=True, **kw)
                est["SMC seed 2"][r] = two[0]
                est["SMC 4×"][r] = bayes.smc_posterior_mean(y, t, mu, s, ZETA, sigma, rng, particles=4 * args.draws,
                                                            **kw)[0]
                est["IS"][r], ess[r] = bayes.importance_posterior_mean(y, t, mu, s, ZETA, sigma, rng, two[3],
                                                                       centre_weights=two[4], **kw)
                for k in names:
                    est[k][r] -= w
            rmse = {k: np.sqrt(np.mean(v**2, axis=0)) for k, v in est.items()}
            ref = est["SMC 4×"]
            diff = {k: np.sqrt(np.mean((est[k] - ref) ** 2, axis=0)) / rmse["SMC 4×"] for k in names}
            for i in range(4):
                lines.append(f"| {noise:g} | {n} | {i + 1} | " + " | ".join(f"{rmse[k][i]:.3g}" for k in names)
                             + " | " + " | ".join(f"{diff[k][i]:.2f}" for k in ("SMC", "SMC seed 2", "IS"))
                             + f" | {np.median(ess):.0f} |")
            print(f"yardstick noise {noise:g} µg, N = {n}", file=sys.stderr)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines.insert(3, f"{time.perf_counter() - t0:.0f} s, load average {load:.1f} on {os.cpu_count()} cores.")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=100)
    ap.add_argument("--draws", type=int, default=1000, help="particles of the SMC posterior mean")
    ap.add_argument("--n-samples", type=int, nargs="+", default=[20, 32, 64, 256])
    ap.add_argument("--noise-ug", type=float, nargs="+", default=[10.0, 1000.0])
    ap.add_argument("--mmse-max-n", type=int, default=64,
                    help="the SMC limit only up to this N (above, van Trees ≈ CRLB is the yardstick)")
    ap.add_argument("--rel-std", type=float, default=0.03, help="prior 1σ relative to Table 3")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--posterior-draws", type=int, default=0,
                    help="also pem:map with posterior_draws = K (its importance-sampled posterior mean)")
    ap.add_argument("--out", type=Path, default=None,
                    help="default results/bench/prior.md (prior_filters.md with --part filters)")
    ap.add_argument("--part", choices=("map", "filters", "yardstick"), default="map",
                    help="map: pem's MAP fit and the yardstick; filters: akf/wkf coverage under their P0; "
                         "yardstick: is the SMC limit converged (seeds, particles, importance sampling)")
    args = ap.parse_args(argv)
    if args.out is None:
        args.out = Path({"map": "results/bench/prior.md", "filters": "results/bench/prior_filters.md",
                         "yardstick": "results/bench/prior_yardstick.md"}[args.part])
    if args.seed == SCORING_SEED:
        print(f"error: --seed {args.seed} is the grids' scoring seed; use another", file=sys.stderr)
        return 2
    if not 0 <= args.posterior_draws <= 100_000:
        print(f"error: --posterior-draws {args.posterior_draws} must be in 0…100000", file=sys.stderr)
        return 2
    if args.records < 2 or args.draws < 10 or not 0 < args.rel_std < 0.5 or min(args.n_samples) < 20:
        print("error: --records ≥ 2, --draws ≥ 10, 0 < --rel-std < 0.5 and --n-samples ≥ 20 are required",
              file=sys.stderr)
        return 2
    if args.part in ("filters", "yardstick"):
        text = filters(args) if args.part == "filters" else yardstick(args)
        args.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(args.out, text)
        print(text)
        return 0
    t0 = time.perf_counter()
    cells = []
    for noise in args.noise_ug:
        for n in args.n_samples:
            cells.append(cell(noise, n, args))
            print(f"noise {noise:g} µg, N = {n}: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    text = report(cells, args, time.perf_counter() - t0)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out, text)
    print(text)
    return 0


if __name__ == "__main__":
    with one_blas_thread():
        sys.exit(main())
