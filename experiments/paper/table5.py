"""Table 5 of the paper (§4.3): frequencies identified by the prediction-error method at 1000 µg.

The paper prints one run: true 3.23, 20.24, 22.00, 56.67; a priori (Table 4) 2.65, 16.73, 17.32, 52.91;
estimated 3.20, 20.25, 22.00, 56.61 rad/s. The record length is not stated (§4: "20–256 samples"); this
uses the longest, 256 samples at Δt = 0.02 s. Over R noise draws it regenerates the table with

- ``paper``: the paper's setting, the variant ``pem:paper`` (``configs/method/pem_paper.yaml``) — Kalman
  innovation predictor (steady-state gain, Qd = 0.001, Rd = 0.4), damping held at its assumed value, the
  mean subtracted, one Gauss–Newton run from Table 4;
- ``best``: the method's defaults (``methods.pem.Options``) — output error (maximum likelihood), damping and
  offset estimated, multi-start with a data-driven start;

and the Cramér–Rao bound, so that the printed errors can be read in standard deviations of the best
possible unbiased estimator. Writes ``table5.csv``/``.md`` and ``table5_notes.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from experiments.config_schema import stated_options
from experiments.io import atomic_write_text, markdown_table, write_table
from experiments.simulate.crlb import crlb_std
from experiments.simulate.datasets import UG, replicate_rng
from experiments.simulate.plant import PlantConfig, build_plant
from methods import pem

__all__ = ["FAR_CRLB", "Params", "run"]

FAR_CRLB = 5.0           # a replicate is "far" when a mode is more than this many CRLB std off


@dataclass
class Params:
    """Table 5 over R replicates. Defaults: the paper (§4.3, Tables 4–5)."""

    n_samples: int = 256                     # the longest record of the paper's range (§4: 20–256)
    dt_s: float = 0.02                       # §4
    noise_ug: float = 1000.0                 # §4.3
    replicates: int = 100
    seed: int = 1                            # not the grid's scoring seed
    prior_rad_s: list[float] = field(default_factory=lambda: [2.65, 16.73, 17.32, 52.91])          # Table 4
    printed_true_rad_s: list[float] = field(default_factory=lambda: [3.23, 20.24, 22.00, 56.67])   # Table 5
    printed_estimate_rad_s: list[float] = field(default_factory=lambda: [3.20, 20.25, 22.00, 56.61])  # Tab. 5
    paper_config: str = "pem_paper"          # the paper's setting: configs/method/pem_paper.yaml, its one home
    best_config: str = "pem"                 # the method's defaults (configs/method/pem.yaml sets no option)
    plant: PlantConfig = field(default_factory=PlantConfig)


def run(params: Params, out_dir: Path) -> list[Path]:
    """Run both settings on the same R records and write the table and its notes."""
    _check(params)
    plant = build_plant(params.plant)
    n, dt = params.n_samples, params.dt_s
    sigma = params.noise_ug * UG
    clean = plant.tip_acceleration(n, dt)
    bound = crlb_std(plant.freq_rad_s, plant.damping, plant.modal_amplitude, plant.modal_phase, n, dt, sigma)
    settings = {"paper": stated_options(params.paper_config), "best": stated_options(params.best_config)}
    estimates = {name: np.empty((params.replicates, 4)) for name in settings}
    converged = {name: np.empty(params.replicates, bool) for name in settings}
    for r in range(params.replicates):
        y = clean + sigma * replicate_rng(params.seed, params.noise_ug, n, r).standard_normal(n)
        for name, opts in settings.items():
            est = pem.identify(y, dt, params.prior_rad_s, **opts)
            estimates[name][r] = est.frequencies
            converged[name][r] = est.converged
    table = _table(params, plant.freq_rad_s, bound, estimates, converged)
    out_dir = Path(out_dir)
    written = write_table(table, out_dir / "table5")
    written.append(atomic_write_text(out_dir / "table5_notes.md",
                                     _notes(params, settings, plant.freq_rad_s, bound, estimates, converged, table)))
    return written


def _check(params: Params) -> None:
    for name in ("prior_rad_s", "printed_true_rad_s", "printed_estimate_rad_s"):
        if len(getattr(params, name)) != 4:
            raise ValueError(f"{name} must list the 4 modes, got {getattr(params, name)}")
    if params.replicates < 1 or params.n_samples < 20:
        raise ValueError(f"replicates = {params.replicates} must be ≥ 1 and n_samples = {params.n_samples} ≥ 20")
    if params.seed == 20261121:
        raise ValueError("seed 20261121 is the grid's scoring seed; use another")


def _answered(est: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Replicates with an answer: converged and finite."""
    return ok & np.all(np.isfinite(est), axis=1)


def _far(est: np.ndarray, true: np.ndarray, bound: np.ndarray) -> np.ndarray:
    return np.any(~(np.abs(est - true) <= FAR_CRLB * bound), axis=1)


def _table(params, true, bound, estimates, converged) -> pd.DataFrame:
    printed = np.asarray(params.printed_estimate_rad_s)
    rows = {
        "mode": np.arange(1, 5),
        "true (model), rad/s": true,
        "true printed, rad/s": params.printed_true_rad_s,
        "a priori (Table 4), rad/s": params.prior_rad_s,
        "estimate printed (Table 5), rad/s": printed,
        "printed error / CRLB": (printed - true) / bound,
    }
    for name, est in estimates.items():
        good = est[_answered(est, converged[name])]
        rows[f"{name}: mean ± std, rad/s"] = [f"{good[:, i].mean():.4f} ± {good[:, i].std(ddof=1):.4f}"
                                              if len(good) > 1 else "–" for i in range(4)]
        rows[f"{name}: bias / CRLB"] = (good.mean(axis=0) - true) / bound if len(good) else np.nan
        rows[f"{name}: RMSE / CRLB"] = np.sqrt(np.mean((est - true) ** 2, axis=0)) / bound
    rows["CRLB std, rad/s"] = bound
    return pd.DataFrame(rows)


def _notes(params, settings, true, bound, estimates, converged, table) -> str:
    lines = [
        "# Table 5 regenerated (prediction-error method, §4.3)",
        "",
        f"Record: {params.n_samples} samples at Δt = {params.dt_s} s (the longest of the paper's 20–256), "
        f"{params.noise_ug:g} µg white noise, {params.replicates} noise draws (seed {params.seed}), "
        f"Table 4 priors {params.prior_rad_s} rad/s.",
        "",
        f"- paper setting: `{settings['paper']}`",
        f"- best setting: methods.pem defaults + `{settings['best']}`",
        "",
        "Mean ± std and bias are over the replicates with an answer (converged, finite); RMSE/CRLB is over all "
        "of them.",
        "",
    ]
    for name, est in estimates.items():
        answered = _answered(est, converged[name])
        far = _far(est, true, bound)
        lines.append(f"- {name}: {len(est) - answered.sum()} of {len(est)} replicates without an answer; "
                     f"{far.sum()} with a mode more than {FAR_CRLB:g} CRLB std off.")
    printed_err = np.abs(np.asarray(params.printed_estimate_rad_s) - true) / bound
    lines += ["", "The paper's printed estimates are "
              + ", ".join(f"{e:.0f}" for e in printed_err)
              + " CRLB std from the truth (modes 1–4).", "", markdown_table(table), ""]
    return "\n".join(lines)
