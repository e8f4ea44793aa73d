"""What limits tracking a slosh modulation under a white force: the bounds, and the lag-against-noise trade-off.

    python -m experiments.benchmarks.slosh_bound [--seed 31] [--replicates 2]

Records: the paper's plant (``experiments.simulate.tracking_data``), a white body force of 5 N per sample
(the tracking grid's), 120 s at 0.02 s, the frequencies ωᵢ(t) = ωᵢ(1 + a sin 2πft) for a slosh of a = 2, 3 and
5 % at f = 0.05 and 0.1 Hz, noise 100 and 1000 µg. Per mode, over the record after 30 s, medians over time and
replicates, in % of ω:

* **unknown-force PCRB** (``pcrb_force.unknown_force_pcrb``: the force unknown, the walk matched to the
  modulation step by step) and the **genie** PCRB (``pcrb.cell_pcrb``: the force known);
* **the best window**: a tracker that fits constant frequencies (``const``) or a straight line in time
  (``trend``, evaluated at the window's end) to the last W s. Its error is at least √(noise_W² + lag_W²):
  noise_W the unknown-force bound of a constant frequency from those W s alone (the same recursion with no
  walk, started from the bound's prior at the window's start), lag_W the error of the fit to the noise-free
  ω(t) at the window's end (a constant fit: ω(t) − its window mean, of order a·ω·(πfW)²/6 … a·ω for
  W ≳ 1/(2f); a line: the curvature's share, smaller by about the window's share of the period). The table
  gives the W (of 2.5, 5, 10, 20, 40 s) with the least of that total, and its two parts. Evaluated at 12
  window ends over the record's second half.

A window of the noise-limited length (the one the frequency resolution of a white-force response needs,
√(ζω/W)) is longer than the slosh period can afford: the page shows which side of the trade-off each mode
sits on. Prints the table and writes it to results/bench/slosh_bound.md.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np

from experiments.simulate.pcrb import prior_covariance
from experiments.simulate.pcrb_force import unknown_force_pcrb
from experiments.simulate.plant import build_plant
from experiments.simulate.timevarying import modal_model
from experiments.simulate.tracking_data import TrackingCellConfig, make_cell

__all__ = ["AMPLITUDES", "FREQS_HZ", "NOISE_UG", "WINDOWS_S", "lag", "main", "slosh_row"]

AMPLITUDES = (0.02, 0.03, 0.05)
FREQS_HZ = (0.05, 0.1)
NOISE_UG = (100.0, 1000.0)
WINDOWS_S = (2.5, 5.0, 10.0, 20.0, 40.0)
FORCE_N = 5.0
SETTLE_S = 30.0
N_ENDS = 12


def lag(w: np.ndarray, end: int, width: int, trend: bool) -> np.ndarray:
    """|ω(t_end) − the least-squares constant (or line, at t_end) fitted to ω over the window|, per mode."""
    seg = w[end - width + 1: end + 1]
    if not trend:
        return np.abs(w[end] - seg.mean(axis=0))
    t = np.arange(width, dtype=float)
    coef = np.polynomial.polynomial.polyfit(t, seg, 1)
    return np.abs(w[end] - (coef[0] + coef[1] * t[-1]))


def slosh_row(amp: float, hz: float, noise_ug: float, seed: int, replicates: int) -> dict:
    cfg = TrackingCellConfig(schedule={"slosh": amp, "slosh_hz": hz}, excitation={"disturbance_force_n": FORCE_N},
                             noise_ug=noise_ug, duration_s=120.0, replicates=replicates, seed=seed)
    cell = make_cell(cfg)
    w, x, u, prior = cell["truth_freq_rad_s"], cell["modal_state"], cell["inputs"], cell["prior_rad_s"]
    dt, sigma = float(cell["dt_s"]), float(cell["noise_std_m_s2"])
    n, m = w.shape
    after = slice(int(SETTLE_S / dt), None)
    out = {"uf": np.median(cell["pcrb_unknown_force_std_rad_s"][:, after] / w[None, after], axis=(0, 1)),
           "genie": np.median(cell["pcrb_std_rad_s"][:, after] / w[None, after], axis=(0, 1))}
    model = modal_model(build_plant(cfg.plant))
    ends = np.linspace(n // 2, n - 1, N_ENDS).astype(int)
    p0 = np.diag(prior_covariance(model, w, x, prior))
    for kind in ("const", "trend"):
        best = {"total": np.full(m, np.inf), "noise": np.zeros(m), "lag": np.zeros(m), "w_s": np.zeros(m)}
        for width_s in WINDOWS_S:
            width = int(round(width_s / dt))
            noise, lags = [], []
            for e in ends:
                s = slice(e - width + 1, e + 1)
                std = unknown_force_pcrb(model, w[s], x[:, s], dt, sigma, prior, force_std_n=FORCE_N, u=u[:, s],
                                         rw_q=np.zeros(m), P0=p0)[:, -1]
                # a line's value at its window's end has 4× the variance of the window's mean: 2× the std
                noise.append(np.median(std, axis=0) * (2.0 if kind == "trend" else 1.0) / w[e])
                lags.append(lag(w, e, width, kind == "trend") / w[e])
            noise, lags = np.median(noise, axis=0), np.sqrt(np.mean(np.square(lags), axis=0))
            total = np.hypot(noise, lags)
            better = total < best["total"]
            for key, value in (("total", total), ("noise", noise), ("lag", lags), ("w_s", np.full(m, width_s))):
                best[key] = np.where(better, value, best[key])
        out[kind] = best
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=31)
    parser.add_argument("--replicates", type=int, default=2)
    args = parser.parse_args(argv)
    if args.replicates < 1:
        parser.exit(2, f"error: --replicates = {args.replicates} must be at least 1\n")

    def pct(v):
        return "/".join(f"{100 * x:.2f}" for x in v)

    lines = ["# What limits tracking a slosh under a white force", "",
             f"`python -m experiments.benchmarks.slosh_bound --seed {args.seed} --replicates {args.replicates}`: "
             "the paper's plant, 5 N white body force, 120 s, ωᵢ(1 + a sin 2πft); per mode 1/2/3/4, % of ω, medians "
             f"after {SETTLE_S:g} s. PCRB: the unknown-force and the genie bound (walk matched step by step). "
             "Best window: the window length (s) with the least √(noise² + lag²) for a constant (const) or a "
             "straight-line (trend) fit, and that total with its noise and lag parts (docstring).", "",
             "| a | f Hz | µg | PCRB unknown force | PCRB genie | const: W s | const: total (noise, lag) | "
             "trend: W s | trend: total (noise, lag) |", "|---|---|---|---|---|---|---|---|---|"]
    print("\n".join(lines), flush=True)
    for amp, hz, noise in itertools.product(AMPLITUDES, FREQS_HZ, NOISE_UG):
        r = slosh_row(amp, hz, noise, args.seed, args.replicates)
        c, t = r["const"], r["trend"]
        lines.append(f"| {100 * amp:g} % | {hz:g} | {noise:g} | {pct(r['uf'])} | {pct(r['genie'])} | "
                     f"{'/'.join(f'{v:g}' for v in c['w_s'])} | {pct(c['total'])} ({pct(c['noise'])}, "
                     f"{pct(c['lag'])}) | {'/'.join(f'{v:g}' for v in t['w_s'])} | {pct(t['total'])} "
                     f"({pct(t['noise'])}, {pct(t['lag'])}) |")
        print(lines[-1], flush=True)
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import one_blas_thread, run_with_page

    with one_blas_thread():
        raise SystemExit(run_with_page(main, "slosh_bound"))   # prints, and writes results/bench/slosh_bound.md
