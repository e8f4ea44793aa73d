"""The Bayesian yardstick of one grid cell, per mode: the van Trees bound and the posterior mean's RMSE.

A grid cell has one fixed truth and R replicate records; a grid that names a prior (``yardstick_prior``:
a method config whose ``prior_rad_s`` and ``options.prior_std_rad_s`` state ω ~ N(μ, diag(s²)); the paper
grid names ``pem_map``: Table 4's prior, s = 30 % of it) gets, per (cell, mode):

- **van Trees bound** (:func:`experiments.simulate.bayes.van_trees_std`), offset unknown, damping known: the
  Bayesian bound averaged over truths drawn from the prior. Cheap; every cell.
- **the posterior mean on the cell's own records**, where the classical bound is loose for some mode (its
  CRLB, offset known as in the tables' RMSE/CRLB, above ``LOOSE`` × s): for each replicate record, E[ω | y]
  under that prior by sequential Monte Carlo (:func:`experiments.simulate.bayes.smc_posterior_mean`; linear
  unknowns projected out, σ and the damping ratios known at the cell's values), and its RMSE about the
  cell's truth. That is the yardstick: the error, at this truth and on these records, of the estimator that
  is best on average over the prior. It never sees the true frequencies; no one can call it prior-pinned: where
  the record says nothing it is the prior mean, where the record dominates it is the data's answer. Knowing
  ζ and σ makes it slightly optimistic (harder to match) for a method that estimates them.

Each record's posterior mean is the average of two independent SMC runs of ``particles`` each; half their
difference, as an RMS over the records, is the Monte-Carlo error of the yardstick
(``posterior_mean_mc_rad_s``), stated beside it. Seeds: ``default_rng([seed, STREAM, noise_ng, N, r, run])``
from the cell's own seed, so a rerun gives the same bytes.
"""

from __future__ import annotations

import numpy as np

from experiments.simulate import bayes

__all__ = ["LOOSE", "PARTICLES", "VAN_TREES_POINTS", "STREAM", "COLUMNS", "loose_modes", "cell_rows"]

LOOSE = 0.1            # the classical bound is loose where CRLB > LOOSE × the prior's 1σ
PARTICLES = 250        # per SMC run; two runs per record (docs/prior.md §6: their Monte-Carlo error)
VAN_TREES_POINTS = 5   # Gauss–Hermite nodes per mode
STREAM = 0x5942        # "YB"

COLUMNS = ["noise_ug", "n_samples", "mode", "true_rad_s", "prior_rad_s", "prior_std_rad_s", "crlb_std_rad_s",
           "van_trees_std_rad_s", "loose", "posterior_mean_rmse_rad_s", "posterior_mean_bias_rad_s",
           "posterior_mean_mc_rad_s", "prior_error_rad_s", "particles"]


def loose_modes(crlb_std, prior_std, loose: float = LOOSE) -> np.ndarray:
    """Per mode: the classical bound exceeds ``loose`` × the prior's 1σ (non-finite counts as loose)."""
    c = np.asarray(crlb_std, float)
    return ~(c <= loose * np.asarray(prior_std, float))


def cell_rows(cell: dict, prior_mean, prior_std, *, particles: int = PARTICLES, loose: float = LOOSE,
              points: int = VAN_TREES_POINTS) -> list[dict]:
    """The yardstick rows of one dataset cell (a dict of its arrays, ``experiments.io.read_npz``)."""
    mu, s = np.asarray(prior_mean, float), np.asarray(prior_std, float)
    truth = np.asarray(cell["truth_freq_rad_s"], float)
    if mu.shape != truth.shape or s.shape != truth.shape:
        raise ValueError(f"the prior has {mu.size} means and {s.size} spreads, the cell {truth.size} modes")
    zeta = np.asarray(cell["truth_damping"], float)
    amp, phase = np.asarray(cell["truth_amplitude_m_s2"], float), np.asarray(cell["truth_phase_rad"], float)
    t = np.asarray(cell["t_s"], float)
    n, dt = t.size, float(cell["dt_s"])
    sigma, noise_ug = float(cell["noise_std_m_s2"]), float(cell["noise_ug"])
    crlb = np.asarray(cell["crlb_std_rad_s"], float)
    vt = bayes.van_trees_std(mu, s, zeta, amp, phase, n, dt, sigma, offset=True, points=points,
                             known_damping=True)
    is_loose = loose_modes(crlb, s, loose)
    rmse = bias = mc = np.full(truth.size, np.nan)
    if is_loose.any():
        y = np.atleast_2d(np.asarray(cell["accel_m_s2"], float))
        est = np.empty((y.shape[0], 2, truth.size))
        for r, rec in enumerate(y):
            for run in range(2):
                rng = np.random.default_rng([int(cell["seed"]), STREAM, int(round(noise_ug * 1000)), n, r, run])
                est[r, run] = bayes.smc_posterior_mean(rec, t, mu, s, zeta, sigma, rng, particles=particles,
                                                       offset=True)[0]
        err = est.mean(axis=1) - truth
        rmse = np.sqrt(np.mean(err**2, axis=0))
        bias = err.mean(axis=0)
        mc = np.sqrt(np.mean(((est[:, 0] - est[:, 1]) / 2) ** 2, axis=0))
    return [{"noise_ug": noise_ug, "n_samples": n, "mode": i + 1, "true_rad_s": float(truth[i]),
             "prior_rad_s": float(mu[i]), "prior_std_rad_s": float(s[i]), "crlb_std_rad_s": float(crlb[i]),
             "van_trees_std_rad_s": float(vt[i]), "loose": bool(is_loose[i]),
             "posterior_mean_rmse_rad_s": float(rmse[i]), "posterior_mean_bias_rad_s": float(bias[i]),
             "posterior_mean_mc_rad_s": float(mc[i]), "prior_error_rad_s": float(abs(mu[i] - truth[i])),
             "particles": int(particles) if is_loose.any() else 0}
            for i in range(truth.size)]
