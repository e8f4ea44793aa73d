"""Figs. 4–6 of the paper (§4.4): phase-locked-loop frequency estimates against time, one panel per mode.

- ``figure: fig4`` — each loop alone on a noise-free unit sinusoid at its true frequency, A(s) = 1;
  plus the measured pull-in (acquisition) range of each loop and the Table 6 / design-rule check.
- ``figure: fig5`` — all four loops on the noise-free tip accelerometer of the truth plant, A(s) = 1.
- ``figure: fig6`` — with the Chebyshev input filters and mode 1's K = 5 (the paper's Fig. 6), mode 1
  also with K = 1 for comparison; and the same at the noise levels of §4.4 (1000, 10 000, 100 000 µg).

Each writes a PNG and an SVG, and a metrics table (CSV + Markdown): the estimate (mean over the final
window, the method's output), the spread of the instantaneous estimate over that window, the RMS error of
the instantaneous estimate over the window, the time after which the estimate (averaged over one period of
its 2ω ripple) stays within 2 % of the truth, and the lock indicator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from experiments.io import save_figure, write_table  # noqa: E402
from experiments.simulate.datasets import UG  # noqa: E402
from experiments.simulate.plant import PlantConfig, build_plant  # noqa: E402
from methods import pll  # noqa: E402
from methods.estimate import Estimate  # noqa: E402
from methods.pll.design import (  # noqa: E402
    LoopParameters,
    loop_time_constants,
    omega_l_from_time_constants,
    stability_margins,
)

__all__ = ["SETTLE_TOLERANCE", "NOISE_COLOURS", "Params", "run"]

SETTLE_TOLERANCE = 0.02     # "acquired": the instantaneous estimate stays within 2 % of the truth
NOISE_COLOURS = ("tab:green", "tab:blue", "tab:orange", "tab:red")


@dataclass
class Params:
    """One of the paper's PLL figures. Defaults: Fig. 6; the experiment configs set ``figure``."""

    figure: str = "fig6"                     # fig4 | fig5 | fig6
    n_samples: int = 2048                    # 41 s at 0.02 s: two acquisition times of loop 1 (4π/ω_L)
    dt_s: float = 0.02
    prior_rad_s: list[float] = field(default_factory=lambda: [2.80, 16.00, 18.00, 52.00])   # Table 6
    options: dict[str, Any] = field(default_factory=dict)       # pll options over methods.pll defaults
    reference_gain: list[float] | None = None   # also run with these K (dashed lines), e.g. Table 6's
    noise_ug: list[float] = field(default_factory=lambda: [0.0])  # 1σ noise levels; > 1 → noise figure
    replicates: int = 20                     # noise realisations per level for the metrics table
    seed: int = 1
    pullin_offsets_omega_l: list[float] = field(
        default_factory=lambda: [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.25, 2.5])  # fig4 only
    pullin_phases: int = 4
    pullin_record_acquisition_times: float = 6.0
    plant: PlantConfig = field(default_factory=PlantConfig)


def run(params: Params, out_dir: Path) -> list[Path]:
    """Draw the figure named by ``params.figure`` into ``out_dir``; return the files written."""
    out_dir = Path(out_dir)
    if params.figure not in ("fig4", "fig5", "fig6"):
        raise ValueError(f"figure = '{params.figure}' must be fig4, fig5 or fig6")
    if params.n_samples < 8 or not params.dt_s > 0:
        raise ValueError(f"n_samples = {params.n_samples} (≥ 8) and dt_s = {params.dt_s} (> 0) are needed")
    plant = build_plant(params.plant)
    truth = plant.freq_rad_s
    t = np.arange(params.n_samples) * params.dt_s
    options = dict(params.options)
    if params.figure == "fig4":
        runs = {"": _single_loops(params, truth, t, options)}
    else:
        clean = plant.tip_acceleration(params.n_samples, params.dt_s)
        runs = {"": pll.identify(clean, params.dt_s, params.prior_rad_s, **options)}
    if params.reference_gain is not None:
        ref = {**options, "gain": list(params.reference_gain)}
        runs[_gain_label(params.reference_gain)] = (
            _single_loops(params, truth, t, ref) if params.figure == "fig4" else
            pll.identify(plant.tip_acceleration(params.n_samples, params.dt_s), params.dt_s,
                         params.prior_rad_s, **ref))
    written = _draw(params, runs, truth, t, out_dir / params.figure, options)
    rows = []
    for label, est in runs.items():
        rows += _metrics(est, truth, params, label or _gain_label(options.get("gain")), 0.0)
    written += write_table(pd.DataFrame(rows), out_dir / f"{params.figure}_metrics")
    if params.figure == "fig4":
        written += write_table(_pullin_table(params, truth), out_dir / "fig4_pullin_range")
        written += write_table(_design_table(params), out_dir / "table6_design_rule")
    noisy = [u for u in params.noise_ug if u > 0]
    if noisy and params.figure != "fig4":
        written += _noise_study(params, plant, t, options, out_dir)
    return written


# --------------------------------------------------------------------------------------------------------

def _gain_label(gain) -> str:
    gain = pll.Options().gain if gain is None else gain
    return "K = " + ", ".join(f"{g:g}" for g in gain)


def _single_loops(params: Params, truth, t, options) -> Estimate:
    """Fig. 4: loop j alone on sin(ω_j t), A(s) = 1 unless the options say otherwise; results stacked."""
    ests = []
    for j, w in enumerate(truth):
        one = _one_loop_options(options, j)
        ests.append(pll.identify(np.sin(w * t), params.dt_s, [params.prior_rad_s[j]], **one))
    extra = {key: np.concatenate([np.atleast_1d(e.extra[key]) for e in ests])
             for key in ("lock_indicator", "locked", "acquisition_time_s")}
    extra["lock_history"] = np.column_stack([e.extra["lock_history"][:, 0] for e in ests])
    extra["window_s"] = ests[0].extra["window_s"]
    return Estimate(np.concatenate([e.frequencies for e in ests]), np.concatenate([e.std for e in ests]),
                        history=np.column_stack([e.history[:, 0] for e in ests]),
                        converged=all(e.converged for e in ests), iterations=t.size,
                        message="; ".join(e.message for e in ests), extra=extra)


def _one_loop_options(options: dict, j: int) -> dict:
    """The options of loop j alone (A(s) = 1 unless the options say otherwise)."""
    full = pll.Options(**{"input_filter": False, **options})
    one = {k: [getattr(full, k)[j]] for k in pll.PER_LOOP_OPTIONS}
    if full.filter_centre_rad_s is not None:
        one["filter_centre_rad_s"] = [full.filter_centre_rad_s[j]]
    return {**{"input_filter": False, **options}, **one}


def _settle_time(history: np.ndarray, true: float, dt: float) -> float:
    """Time after which |ω̂ − ω| ≤ 2 % ω to the end of the record (NaN if it never gets there).

    ω̂ is first averaged over one period of the detector's 2ω ripple (π/ω, trailing), which is not a
    tracking error; the time reported is the end of the first window that stays inside.
    """
    k = max(1, min(history.size, int(round(math.pi / (true * dt)))))
    smooth = np.convolve(history, np.ones(k) / k, mode="valid")       # smooth[i] ends at sample i+k-1
    bad = np.flatnonzero(np.abs(smooth - true) > SETTLE_TOLERANCE * true)
    if bad.size == 0:
        return float((k - 1) * dt)
    if bad[-1] == smooth.size - 1:
        return math.nan
    return float((bad[-1] + k) * dt)


def _metrics(est, truth, params: Params, label: str, noise_ug: float, replicate: int = 0) -> list[dict]:
    """Per-mode numbers. ``early_rms_error_rad_s``: RMS error of the instantaneous estimate over a window
    as long as the output window starting at 1.5 × 4π/ω_L — after acquisition, before the faster modes
    have decayed into the noise or below the leakage of the others (ζ = 0.005: mode 4 loses 1/e in 3.5 s)."""
    window = int(round(est.extra["window_s"] / params.dt_s))
    tail = est.history[-window:]
    rows = []
    for j, w in enumerate(truth):
        start = min(int(round(1.5 * est.extra["acquisition_time_s"][j] / params.dt_s)),
                    est.history.shape[0] - window)
        early = est.history[start:start + window, j]
        rows.append({
            "figure": params.figure, "run": label, "noise_ug": noise_ug, "replicate": replicate,
            "mode": j + 1, "true_rad_s": float(w), "prior_rad_s": params.prior_rad_s[j],
            "estimate_rad_s": float(est.frequencies[j]), "error_rad_s": float(est.frequencies[j] - w),
            "error_pct": float(100 * (est.frequencies[j] - w) / w), "window_std_rad_s": float(est.std[j]),
            "window_rms_error_rad_s": float(np.sqrt(np.mean((tail[:, j] - w) ** 2))),
            "early_rms_error_rad_s": float(np.sqrt(np.mean((early - w) ** 2))),
            "settle_2pct_s": _settle_time(est.history[:, j], w, params.dt_s),
            "acquisition_time_4pi_over_wl_s": float(est.extra["acquisition_time_s"][j]),
            "lock_indicator": float(est.extra["lock_indicator"][j]),
            "locked": bool(est.extra["locked"][j]),
        })
    return rows


def _draw(params: Params, runs: dict, truth, t, stem: Path, options) -> list[Path]:
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    gains = {"": options.get("gain") or pll.Options().gain}
    if params.reference_gain is not None:
        gains[_gain_label(params.reference_gain)] = params.reference_gain
    for j, ax in enumerate(axes.flat):
        for k, (label, est) in enumerate(runs.items()):
            if k > 0 and gains[label][j] == gains[""][j]:
                continue                     # the reference run differs from the main one in other loops
            ax.plot(t, est.history[:, j], lw=0.8, color="tab:green" if k == 0 else "tab:purple",
                    ls="-" if k == 0 else "--", label=f"PLL estimate, K = {gains[label][j]:g}")
        _truth_and_limits(ax, truth[j], params.prior_rad_s[j], [e.history[:, j] for e in runs.values()])
        ax.set_title(f"({'abcd'[j]}) mode {j + 1}")
        ax.set_ylabel("frequency (rad/s)")
        ax.legend(fontsize=7, loc="lower right")
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(_title(params, options))
    fig.tight_layout()
    paths = [save_figure(fig, stem.with_suffix(".png")), save_figure(fig, stem.with_suffix(".svg"))]
    plt.close(fig)
    return paths


def _truth_and_limits(ax, true, prior, histories):
    ax.axhline(true, color="black", lw=1.2, label=f"true {true:.2f} rad/s")
    ax.axhline(prior, color="gray", lw=0.8, ls=":", label=f"a-priori {prior:.2f} rad/s")
    lo, hi = 0.7 * true, 1.3 * true
    ax.set_ylim(lo, hi)
    out = [h for h in histories if np.any((h < lo) | (h > hi))]
    if out:
        ax.text(0.02, 0.95, f"estimate leaves the plot (range {min(h.min() for h in out):.3g}–"
                f"{max(h.max() for h in out):.3g} rad/s)", transform=ax.transAxes, fontsize=7, va="top")


def _title(params: Params, options) -> str:
    filt = options.get("input_filter", pll.Options().input_filter)
    what = {"fig4": "each loop alone on a noise-free unit sinusoid at its true frequency, A(s) = 1",
            "fig5": "all loops on the noise-free tip accelerometer, A(s) = 1",
            "fig6": "all loops on the noise-free tip accelerometer, Chebyshev input filters"}[params.figure]
    if params.figure != "fig4" and not filt:
        what = what.replace("Chebyshev input filters", "A(s) = 1")
    return f"Paper {params.figure.replace('fig', 'Fig. ')} reproduced: {what}; Δt = {params.dt_s} s"


# --------------------------------------------------------------------------------------------------------

def _noise_study(params: Params, plant, t, options, out_dir: Path) -> list[Path]:
    """The same bank at each noise level: a table over all replicates (both gain sets) and a figure of
    replicate 0 — drawn with the reference gains when given, since the main run's K = 5 loop is unstable
    with or without noise."""
    clean = plant.tip_acceleration(params.n_samples, params.dt_s)
    gains = {"": options}
    if params.reference_gain is not None:
        gains[_gain_label(params.reference_gain)] = {**options, "gain": list(params.reference_gain)}
    drawn = list(gains)[-1]
    rows, first = [], {}
    for label, opts in gains.items():
        for level in params.noise_ug:
            reps = params.replicates if level > 0 else 1
            for r in range(reps):
                rng = np.random.default_rng([params.seed, int(round(level * 1000)), r])
                y = clean + level * UG * rng.standard_normal(clean.size) if level > 0 else clean
                est = pll.identify(y, params.dt_s, params.prior_rad_s, **opts)
                rows += _metrics(est, plant.freq_rad_s, params, label or _gain_label(opts.get("gain")),
                                 level, r)
                if r == 0 and label == drawn:
                    first[level] = est
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    for j, ax in enumerate(axes.flat):
        for k, (level, est) in enumerate(first.items()):
            ax.plot(t, est.history[:, j], lw=0.7, color=NOISE_COLOURS[k % len(NOISE_COLOURS)],
                    label=f"{level:g} µg" if level > 0 else "noise-free", zorder=5 - k)
        _truth_and_limits(ax, plant.freq_rad_s[j], params.prior_rad_s[j],
                          [e.history[:, j] for e in first.values()])
        ax.set_title(f"({'abcd'[j]}) mode {j + 1}")
        ax.set_ylabel("frequency (rad/s)")
        ax.legend(fontsize=7, loc="lower right")
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(f"Paper Fig. 6 at the §4.4 noise levels (1σ), {_gain_label(gains[drawn].get('gain'))}, "
                 f"input filters; one realisation (seed {params.seed})")
    fig.tight_layout()
    stem = out_dir / f"{params.figure}_noise"
    paths = [save_figure(fig, stem.with_suffix(".png")), save_figure(fig, stem.with_suffix(".svg"))]
    plt.close(fig)
    df = pd.DataFrame(rows)
    summary = (df.groupby(["run", "noise_ug", "mode"], sort=True)
               .agg(true_rad_s=("true_rad_s", "first"),
                    median_abs_error_rad_s=("error_rad_s", lambda e: float(np.median(np.abs(e)))),
                    median_window_rms_error_rad_s=("window_rms_error_rad_s", "median"),
                    median_early_rms_error_rad_s=("early_rms_error_rad_s", "median"),
                    locked_fraction=("locked", "mean"), replicates=("replicate", "count"))
               .reset_index())
    return paths + write_table(summary, out_dir / f"{params.figure}_noise_metrics")


def _pullin_table(params: Params, truth) -> pd.DataFrame:
    """Measured acquisition range: the largest |ω − ω₀| (in units of ω_L) that every phase locks onto.

    Loop j alone on sin(ω t + φ), ω = ω₀ ± r ω_L, φ on a uniform grid, record = 6 × 4π/ω_L; success:
    locked and the estimate within 0.5 % of ω. The paper states ≈ 1.5 ω_L (§3.4) and ≈ 2 ω_L (§4.4).
    Also the time to settle within 2 % (median and worst over the phases that lock) in units of the
    §3.4 acquisition time 4π/ω_L.
    """
    opts = pll.Options(**{"input_filter": False, **params.options})
    rows = []
    for j in range(len(truth)):
        one = _one_loop_options(params.options, j)
        wl = opts.loop_bandwidth_rad_s[j]
        w0 = params.prior_rad_s[j]
        n = int(round(params.pullin_record_acquisition_times * 4 * math.pi / wl / params.dt_s))
        t = np.arange(n) * params.dt_s
        for r in params.pullin_offsets_omega_l:
            for sign in (-1, 1):
                w = w0 + sign * r * wl
                if not 0 < w < math.pi / params.dt_s:
                    continue
                ok, settle = 0, []
                for phase in np.arange(params.pullin_phases) * 2 * math.pi / params.pullin_phases:
                    est = pll.identify(np.sin(w * t + phase), params.dt_s, [w0], **one)
                    if est.converged and abs(est.frequencies[0] - w) <= 0.005 * w:
                        ok += 1
                        settle.append(_settle_time(est.history[:, 0], w, params.dt_s))
                acq = 4 * math.pi / wl
                rows.append({"mode": j + 1, "prior_rad_s": w0, "omega_l_rad_s": wl,
                             "offset_omega_l": sign * r, "input_rad_s": w,
                             "locked_fraction": ok / params.pullin_phases,
                             "settle_2pct_median_over_4pi_wl": np.median(settle) / acq if settle else np.nan,
                             "settle_2pct_max_over_4pi_wl": np.max(settle) / acq if settle else np.nan})
    return pd.DataFrame(rows)


def _design_table(params: Params) -> pd.DataFrame:
    """Table 6 against the rule under eq. (37) (45°), and the loop's stability margins as tabulated."""
    opts = pll.Options(**{k: v for k, v in params.options.items() if k in pll.Options.__dataclass_fields__})
    rows = []
    for j in range(len(opts.loop_bandwidth_rad_s)):
        wl = opts.loop_bandwidth_rad_s[j]
        t1, t2, t3 = loop_time_constants(wl, opts.phase_margin_deg)
        implied = omega_l_from_time_constants(opts.t1_s[j], opts.t2_s[j], opts.t3_s[j],
                                              opts.phase_margin_deg)
        row = {"mode": j + 1, "omega_l_rad_s": wl,
               "T1_table_s": opts.t1_s[j], "T1_rule_s": t1, "T2_table_s": opts.t2_s[j], "T2_rule_s": t2,
               "T3_table_s": opts.t3_s[j], "T3_rule_s": t3,
               "omega_l_implied_by_T1": implied["from_T1"], "omega_l_implied_by_T2T3": implied["from_T2T3"],
               "omega_l_implied_by_T3": implied["from_T3"], "T_VCO_table_s": opts.t_vco_s[j],
               "omega_l_times_T_VCO": wl * opts.t_vco_s[j]}
        for gain in sorted({opts.gain[j], 1.0, 5.0}):
            p = LoopParameters(wl, opts.t_vco_s[j], opts.t1_s[j], opts.t2_s[j], opts.t3_s[j], gain)
            m = stability_margins(p, params.dt_s)
            row[f"phase_margin_K{gain:g}_deg"] = m["phase_margin_deg"]
            row[f"gain_margin_K{gain:g}_db"] = m["gain_margin_db"]
        rows.append(row)
    return pd.DataFrame(rows)
