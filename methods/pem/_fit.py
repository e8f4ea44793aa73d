"""Prediction-error method with a Gauss–Newton search (paper §3.3, §4.3, eqs. 30–31, Tables 4–5).

The identification model is eq. (8) without the frequency states, with the tip acceleration as output
(eq. 10), in the innovation form of eq. (31) (:mod:`methods.pem.predictor`). The unknowns are the
frequencies, the initial state (as MATLAB's ``pem`` estimates it), optionally the damping ratios and a
sensor offset. The loss V(θ) = (1/N) Σ ε(k)² is minimised by Gauss–Newton, eq. (30),

    θ⁽ⁱ⁺¹⁾ = θ⁽ⁱ⁾ − μ (JᵀJ)⁻¹ Jᵀε,    J = ∂ε/∂θ (exact: closed form, or CasADi for the Kalman predictor),

with μ = 1 halved until the loss decreases (the paper's rule), optionally Levenberg–Marquardt damped and
with the initial state and offset re-solved exactly at every trial point (:mod:`methods.pem.search`).
The covariance σ̂²(JᵀJ)⁻¹ at the optimum, σ̂² = Σε²/(N − p), gives ``Estimate.std``.

Two predictors: ``"kalman"`` — the paper's, steady-state Kalman gain from the discrete Riccati equation with
Qd = 0.001, Rd = 0.4 (§4.3); ``"output_error"`` — gain zero, the maximum-likelihood estimator for the
data's white measurement noise.

Local minima (the paper's first complaint): several starts — a data-driven one (matrix pencil,
:mod:`methods.pem._pencil`, matched to the prior), the prior, seeded perturbations of the prior — the
lowest loss wins, then modes the record does not determine are restarted from the prior's frequency ratios
(:func:`_repaired_start`); ``extra["n_agree"]`` says how many starts reached the answer. "Demanding
calculation" (the second): the output-error predictor and its Jacobian in closed form, O(N), nothing built
per record shape; one BLAS thread inside the fit (small matrices; OpenBLAS threads only slow it down).

The defaults of :class:`Options` are the measured best setting; the paper's is the variant ``pem:paper``
(configs/method/pem_paper.yaml: the options it changes).
See methods/pem/README.md for the choices and the measured numbers.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from threadpoolctl import ThreadpoolController

from methods import labels
from methods.estimate import Estimate, check_inputs, failed, flat_record, make_options
from methods.pem import _drift, _lines, _map, _residual, _saturation, search
from methods.pem import _fast as fast
from methods.pem._pencil import PENCIL_WINDOW, argsort_few, pencil_start
from methods.pem.predictor import modal_basis

PREDICTORS = ("output_error", "kalman")
SEARCHES = ("levenberg_marquardt", "gauss_newton")
BIAS_MODES = ("estimate", "subtract_mean", "none")


@dataclass
class Options:
    """Keyword options of :func:`identify`. Defaults: the best setting (output error = ML); the paper's
    setting is the variant ``pem:paper`` (configs/method/pem_paper.yaml)."""

    predictor: str = "output_error"      # "output_error" (gain 0, ML) or "kalman" (paper, eq. 31)
    kalman_qd: float = 0.001             # Qd of the paper's LQE (§4.3), Γ = I; only for "kalman"
    kalman_rd: float = 0.4               # Rd of the paper's LQE (§4.3); only for "kalman"
    tip_mode_shape: list[float] = field(default_factory=lambda: [2.0, -2.0, -2.0, 2.0])  # Wₙ(L), eq. (10)
    estimate_damping: bool = True        # damping ratios unknown (else held at damping_ratio)
    damping_bounds: list[float] = field(default_factory=lambda: [-0.8, 0.8])  # ζ kept inside (projection)
    frequency_band: float | None = 0.5   # ω kept within prior·(1 + band)^±1 (§4.1: known to ~30 %); None: free
    damping_ratio: float = 0.005         # assumed ζ (paper gives none), and the start of the search
    bias: str = "estimate"               # "estimate" (unknown offset), "subtract_mean" (paper), "none"
    data_driven_start: bool = True       # a matrix-pencil start matched to the prior
    pencil_extra_order: int = 6          # poles beyond 2m + 1 to absorb noise in the pencil
    n_starts: int = 3                    # starts in all: pencil (if on), the prior, then perturbations
    accept_white: bool = True            # stop after the pencil start when its fit explains the record
    start_spread: float = 0.1            # 1σ of the log-normal perturbation of the prior
    seed: int = 0                        # seed of the perturbations (the method stays a pure function)
    search: str = "levenberg_marquardt"  # or "gauss_newton" (paper: pure GN, μ halved)
    separable: bool = True               # re-solve x₀, b exactly at every trial point (variable projection)
    repair_rounds: int = 2               # restarts of undetermined modes from the prior's ratios
    max_iterations: int = 50             # Gauss–Newton iterations per start
    tol_loss: float = 1e-10              # stop when the relative loss improvement falls below this
    tol_step: float = 1e-4               # stop when every step is below this many standard deviations
    # the default (variable-projection) search also stops when its Gauss–Newton step would lower Σε² by less
    # than this times σ̂²: the point is then within √this std of the minimum in the joint metric (0: off)
    tol_decrease: float = 0.01
    # 1σ of the prior frequencies, rad/s (a list, or one number for every mode): a Gaussian prior, and the
    # fit is the MAP one (methods/pem/_map.py); None: no prior information, the ML fit. Typed Any because
    # OmegaConf's structured configs take no union of a list and a number; _check_prior_std checks it.
    prior_std_rad_s: Any = None
    damping_prior_std: float | None = None   # with prior_std_rad_s: ζ ~ N(damping_ratio, this²); None: ζ free
    posterior_summary: str = "mean"      # with prior_std_rad_s: "mean" (posterior mean, MMSE) or "mode" (MAP)
    posterior_draws: int = 0             # with "mean": importance draws per round around the MAP; 0: Laplace mixture
    drift_segments: int = 3              # segments of the drift test when the residual is not white; 0: off
    # what a record whose residual is not white reports: "small_amplitude" (ω₀ of the backbone-chirp fit,
    # the frequency as the amplitude goes to zero, for every mode the record determines; methods/pem/_chirp.py)
    # or "record" (the record's average, a drifting mode's std widened by the spread between segments)
    drift_frequency: str = "small_amplitude"
    # a record whose extreme value is a plateau (a clipped sensor, methods/pem/_saturation.py) is fitted after
    # its last clipped sample (when MIN_TAIL samples remain), and extra["saturation"] says so; False: as it is
    skip_clipped: bool = True
    absorb_lines: bool = True            # refit with a residual line outside every band as an extra mode
    # the residual check judges the residual below this frequency only, rad/s: a decimated record's pass
    # band, above which the anti-alias filter coloured the noise (the measurement job sets it); None: all
    whiteness_band_rad_s: float | None = None





def identify(y, dt, prior, **options) -> Estimate:
    """Frequencies (rad/s) minimising the prediction-error loss, in prior order, with their 1σ.

    Parameters
    ----------
    y : array_like, shape (N,)
        Tip acceleration in m/s², t_k = k·dt.
    dt : float
        Sample interval in s.
    prior : array_like, shape (m,)
        A-priori frequencies in rad/s (paper Table 4: 2.65, 16.73, 17.32, 52.91).
    **options
        Fields of :class:`Options`.

    Returns
    -------
    Estimate
        ``extra``: damping ratios and their std, offset, loss, per-start losses, ``n_agree``, the winning
        start, and the stopping reason of every start.
    """
    y, dt, prior = check_inputs(y, dt, prior)
    opts = make_options(Options, options, "pem")
    _check_options(opts, prior)
    # One BLAS thread inside the fit: its matrices are small (p ≤ 4m + 1 columns), and OpenBLAS's own
    # threads made it 2.6–5× slower on 2 cores (measured: experiments.benchmarks.pem_speed --parts warm blas).
    restore = _one_blas_thread()
    try:
        clip = _saturation.detect(y) if opts.skip_clipped else None
        start = 0 if clip is None or y.size - clip["last_clipped"] - 1 < MIN_TAIL else clip["last_clipped"] + 1
        y = y[start:]
        if opts.prior_std_rad_s is not None:
            est = _identify_map(y, dt, prior, opts)
        else:
            est = _lines.absorb(_identify(y, dt, prior, opts), y, dt, prior, opts,
                                lambda wider: _identify(y, dt, wider, opts))
            est = _drift.attach(est, y, dt, prior, opts, identify)
        return est if clip is None else _saturation.attach(est, clip, start)
    finally:
        for pool, threads in restore:
            pool.set_num_threads(threads)


@functools.cache
def _blas_pools() -> tuple:
    """The process's BLAS thread pools (threadpoolctl's controllers, found once: the search for loaded
    libraries costs more than a fit)."""
    return tuple(ThreadpoolController().select(user_api="blas").lib_controllers)


def _one_blas_thread() -> list:
    """Every BLAS pool set to one thread; returns the (pool, threads) to restore. The pools already at one
    thread are left alone: threadpoolctl's ``limit`` (its info, select and restore: 13 µs, 1 % of a fit)
    for the two get/set calls that matter."""
    restore = []
    for pool in _blas_pools():
        threads = pool.get_num_threads()
        if threads != 1:
            pool.set_num_threads(1)
            restore.append((pool, threads))
    return restore


def _identify(y: np.ndarray, dt: float, prior: np.ndarray, opts: Options) -> Estimate:
    m, n = prior.size, y.size
    free = free_mask(m, opts)
    n_free = int(sum(free))
    if n <= n_free:
        return failed(prior, f"{n} samples cannot determine {n_free} unknowns")
    if opts.bias == "subtract_mean":
        y = y - y.mean()
    shape = np.asarray(opts.tip_mode_shape if len(opts.tip_mode_shape) == m else np.ones(m), float)
    bounds = search.search_bounds(prior, dt, opts)
    fits, join, accepted = [], None, False
    for label, w0, z0 in starts(y, dt, prior, opts):
        fit = _fit(y, dt, w0, z0, shape, free, opts, bounds, join)
        fit["start"] = label
        fits.append(fit)
        if join is None and fit["converged"] and np.isfinite(fit["loss"]):
            std = _free_std(fit)
            if (std[:m] <= search.IDENTIFIED_REL_STD * fit["theta"][:m]).all():   # every mode determined
                if (opts.accept_white and label in (QUICK, "pencil")
                        and _explains_record(fit, std[:m], n, dt, opts.predictor == "output_error")):
                    fits, accepted = [fit], True
                    break
                join = (fit["theta"], std)
    # a start that joined an earlier fit stopped short of the common minimum: it never wins
    ok = [f for f in fits if np.isfinite(f["loss"]) and not f["joined"]]
    if not ok:
        reasons = "; ".join(f"{f['start']}: {f['message']}" for f in fits)
        return failed(prior, f"every start failed: {reasons}")
    best = min(ok, key=lambda f: f["loss"])
    # an accepted fit determines every mode: both repairs below would return None (nothing to repair)
    for _ in range(0 if accepted else opts.repair_rounds):
        start = _repaired_start(best, free, prior, opts)
        if start is None:
            break
        fit = _fit(y, dt, *start, shape, free, opts, bounds)
        fit["start"] = f"repair{len(fits)}"
        fits.append(fit)
        if not fit["loss"] < best["loss"]:
            break
        best = fit
    for _ in range(0 if accepted else opts.repair_rounds):
        start = _line_start(best, free, prior, opts, n, dt)
        if start is None:
            break
        fit = _fit(y, dt, *start, shape, free, opts, bounds)
        fit["start"] = f"line{len(fits)}"
        fits.append(fit)
        if not fit["loss"] < best["loss"]:
            break
        best = fit
    return _estimate(best, fits, prior, free, n, dt, opts, opts.predictor == "output_error")


def prior_std(opts: Options, prior: np.ndarray) -> np.ndarray | None:
    """``prior_std_rad_s`` as m numbers (rad/s), or None when absent."""
    if opts.prior_std_rad_s is None:
        return None
    return np.broadcast_to(np.asarray(opts.prior_std_rad_s, dtype=float), prior.shape).copy()


def _identify_map(y: np.ndarray, dt: float, prior: np.ndarray, opts: Options) -> Estimate:
    """The MAP fit (:mod:`methods.pem._map`) as an Estimate: frequencies in prior order (the prior term
    names each mode), the posterior std (Laplace), a mode flagged not determined where the fit crossed a
    neighbour."""
    if why := flat_record(y):
        return failed(prior, why)
    m = prior.size
    free = free_mask(m, opts)
    if opts.bias == "subtract_mean":
        y = y - y.mean()
    fit = _map.map_fit(y, dt, prior, prior_std(opts, prior), opts, search.search_bounds(prior, dt, opts), free)
    if "failed" in fit:
        return failed(prior, fit["failed"])
    freq, z = fit["theta"][:m], fit["theta"][m:2 * m]
    std, z_std = fit["std_free"][:m], (fit["std_free"][m:2 * m] if opts.estimate_damping else np.full(m, np.nan))
    lo, hi = np.r_[0.0, freq[:-1]], np.r_[freq[1:], np.inf]
    # per mode: the search stopped on a tolerance, the posterior locates the mode (std ≤ 10 % of ω, as
    # for the ML fit), the record determined it (at least as much information from the data as from the
    # prior: posterior variance ≤ half the prior's; else the answer is the prior's, and says so) and it
    # kept its place between its neighbours
    per_mode = (fit["converged"] & np.isfinite(std) & (std > 0) & (std <= search.LOCATED_REL_STD * freq)
                & (std <= prior_std(opts, prior) / np.sqrt(2.0)) & (lo < freq) & (freq < hi))
    extra = {"damping": z, "damping_std": z_std, "offset_m_s2": float(fit["theta"][-1]), "loss": fit["loss"],
             "posterior_cost": fit["cost"], "noise_std_m_s2": float(np.sqrt(fit["sigma2"])),
             "data_dof": fit["edf"], "best_start": fit["start"], "total_iterations": fit["iterations"],
             "posterior_summary": fit["summary"], "posterior_maxima": fit["maxima"], "posterior_ess": fit["ess"]}
    message = (f"MAP: {fit['message']} (start '{fit['start']}', {fit['iterations']} iterations); "
               f"{fit['summary']} of {fit['maxima']} posterior maxima")
    return Estimate(freq, std, converged=bool(per_mode.any()), iterations=int(fit["iterations"]),
                    message=message, extra=extra, converged_per_mode=per_mode)


def _fit(y, dt, w0, z0, shape, free, opts: Options, bounds, join=None) -> dict:
    """One start's search: the variable-projection path (:mod:`methods.pem._fast`) for the default
    options, else the reference (:func:`methods.pem.search.fit_one_start`: any predictor and search)."""
    if fast.applies(opts):
        fit = fast.fit_one_start(y, dt, w0, z0, free, opts, bounds, join)
        if fit is not None:
            return fit
    return search.fit_one_start(y, dt, w0, z0, shape, free, opts, bounds, join)


def _free_std(fit: dict) -> np.ndarray:
    """σ̂√diag((JᵀJ)⁻¹) of a fit's free unknowns (SVD of J: computed once per fit, then kept)."""
    if "std_free" not in fit:
        fit["std_free"] = search.lstsq_step(fit["J"], fit["e"])[1]
    return fit["std_free"]


WHITENESS_ALPHA = 0.01     # false-alarm rate of the residual's sinusoid test (a false alarm costs time only)


def mode_wald(theta: np.ndarray, n: int, dt: float) -> np.ndarray:
    """Per mode (θ order): cᵢᵀ [(ΦᵀΦ)⁻¹]ᵢᵢ⁻¹ cᵢ, its amplitudes' Wald statistic times σ² — the loss the fit
    would gain if the mode were dropped (its amplitudes cᵢ = (Aᵢ, Bᵢ) set free of the other columns).
    Unlike the mode's energy ‖Φᵢcᵢ‖², it is small for two modes the record does not tell apart (large,
    cancelling amplitudes on nearly collinear columns)."""
    m = (theta.size - 1) // 4
    phi = modal_basis(theta[:m], theta[m:2 * m], dt, n)
    try:
        S = np.linalg.inv(phi.T @ phi)
    except np.linalg.LinAlgError:
        return np.zeros(m)
    out = np.zeros(m)
    for i in range(m):
        c, block = theta[2 * m + 2 * i:2 * m + 2 * i + 2], S[2 * i:2 * i + 2, 2 * i:2 * i + 2]
        try:
            out[i] = float(c @ np.linalg.solve(block, c))
        except np.linalg.LinAlgError:
            out[i] = 0.0
    return out


def _detected(fit: dict, w_std: np.ndarray, n: int, dt: float, alpha: float, energy: bool) -> np.ndarray:
    """Per mode (θ order): does the record detect it? Its std is below :func:`detection_std` (the rule
    for a sinusoid that lasts the record), or — for the output-error model, whose θ holds each mode's
    amplitudes — dropping it would raise the loss beyond the noise's 1 − α level: Wald statistic
    (:func:`mode_wald`)/σ̂² > 2 ln(N/2α). The std rule alone misses a damped mode in a long record: its
    information stops growing once it has decayed, while the rule's bound keeps shrinking as 1/N (mode 4
    of the plant at N = 262 144). Computed once per fit and (α, energy): the acceptance test and the
    estimate ask for the same."""
    done = fit.setdefault("detected", {})
    if (alpha, energy) not in done:
        done[alpha, energy] = _detect(fit, w_std, n, dt, alpha, energy)
    return done[alpha, energy]


def _detect(fit: dict, w_std: np.ndarray, n: int, dt: float, alpha: float, energy: bool) -> np.ndarray:
    """:func:`_detected`, computed."""
    found = w_std <= detection_std(n, dt, alpha)
    if found.all():                                    # every mode detected by its std: nothing to add
        return found
    if not energy or fit.get("e") is None or "theta" not in fit or not np.isfinite(fit["theta"]).all():
        return found
    # only for a mode the record determines (std ≤ 1 % of ω): on a short record the Wald statistic at a
    # fitted ω ignores how loosely ω itself is pinned, and the std rule is the right one
    candidates = ~found & (w_std <= search.IDENTIFIED_REL_STD * fit["theta"][:w_std.size])
    if not candidates.any():                           # the usual case: no basis to build
        return found
    e = fit["e"]
    sigma2 = float(e @ e) / max(n - len(fit.get("std_free", ())), 1)
    if not sigma2 > 0:
        return found
    if "wald" not in fit:                              # (for two α: computed once)
        fit["wald"] = mode_wald(fit["theta"], n, dt)
    return found | (candidates & (fit["wald"] / sigma2 > 2.0 * np.log(n / (2.0 * alpha))))


def _explains_record(fit: dict, w_std: np.ndarray, n: int, dt: float, energy: bool = True) -> bool:
    """Whether a fit leaves nothing for another start to find: every mode detected (:func:`_detected`)
    and no sinusoid left in the residual, or the residual at rounding level.

    The other starts and the repair rounds exist for local minima: a mode parked where it explains nothing,
    two close modes merged, a missed mode. Each leaves a sinusoid of the record unexplained, and the
    residual's periodogram shows it: white noise σ² gives 2|E(f)|²/(Nσ²) ~ χ²₂ in each of the N/2 bins,
    which all stay below 2 ln(N/2α) with probability 1 − α (the detection rule of :func:`detection_std`
    and :mod:`methods.peers._mode_picker`); the spectrum is zero-padded ×2 so a sinusoid between bins still
    shows. A lower minimum elsewhere could only fit the noise differently. On the 1000 µg, N = 256 record
    this ends the search after one start (the other two and the repairs cost 20× the first; measured:
    ``python -m experiments.benchmarks.pem_speed``); where the test fails every start runs as before.
    """
    if not np.all(_detected(fit, w_std, n, dt, WHITENESS_ALPHA, energy)):
        return False
    e = fit["e"]
    power = float(e @ e)
    if power <= fit.get("floor", 0.0) * n:
        return True                       # fitted to the rounding of the data: nothing left to find
    spectrum = np.fft.rfft(e, 2 * n)
    if n <= fast.KEEP_BASIS_SAMPLES:      # for the residual check (its periodogram: the even bins)
        fit["spectrum_2n"] = spectrum
    peak = float(np.abs(spectrum).max()) ** 2                      # the largest |E(f)|², squared once
    return 2.0 * peak / power < 2.0 * math.log(n / (2.0 * WHITENESS_ALPHA))


def _repaired_start(best: dict, free, prior: np.ndarray, opts: Options):
    """A start that puts every mode the data do not determine where the prior says it is *relative to*
    the nearest determined mode (ω_i = ω_j · prior_i / prior_j), or None if there is nothing to repair.

    A fit can park a mode where it does nothing useful — two close modes merged into one, the spare one
    above the band — a local minimum whose loss stays well above the noise. The prior's frequency
    *ratios* are far better known than its absolute values (a 20 % error of stiffness or mass moves all
    modes alike), so they are the natural place to restart the spare modes from.
    """
    m = prior.size
    w, w_std, z, _, slot, _ = _labelled(best, free, prior, opts)
    w, w_std, z = w[slot], w_std[slot], z[slot]
    determined = w_std <= search.IDENTIFIED_REL_STD * w
    if determined.all() or not determined.any():
        return None
    good = np.flatnonzero(determined)
    w0, z0 = w.copy(), z.copy()
    for i in np.flatnonzero(~determined):
        j = good[np.argmin(np.abs(np.log(prior[good] / prior[i])))]
        w0[i] = w[j] * prior[i] / prior[j]
        z0[i] = opts.damping_ratio
    return w0, z0 if opts.estimate_damping else np.full(m, opts.damping_ratio)


def _check_options(opts: Options, prior: np.ndarray) -> None:
    if opts.predictor not in PREDICTORS:
        raise ValueError(f"predictor = '{opts.predictor}'; choose one of {PREDICTORS}")
    if opts.search not in SEARCHES:
        raise ValueError(f"search = '{opts.search}'; choose one of {SEARCHES}")
    if opts.bias not in BIAS_MODES:
        raise ValueError(f"bias = '{opts.bias}'; choose one of {BIAS_MODES}")
    if opts.predictor == "kalman":
        if len(opts.tip_mode_shape) != prior.size:
            raise ValueError(f"tip_mode_shape has {len(opts.tip_mode_shape)} entries, the prior {prior.size}")
        if not (opts.kalman_qd > 0 and opts.kalman_rd > 0):
            raise ValueError(f"kalman_qd = {opts.kalman_qd}, kalman_rd = {opts.kalman_rd} must be positive")
    if not 0 <= opts.damping_ratio < 0.9:
        raise ValueError(f"damping_ratio = {opts.damping_ratio} must be in [0, 0.9)")
    if opts.frequency_band is not None and not opts.frequency_band > 0:
        raise ValueError(f"frequency_band = {opts.frequency_band} must be positive (or None for no band)")
    lo, hi = opts.damping_bounds if len(opts.damping_bounds) == 2 else (1.0, -1.0)
    if not -0.9 < lo < hi < 0.9:
        raise ValueError(f"damping_bounds = {opts.damping_bounds} must be [low, high] inside (−0.9, 0.9)")
    if not 1 <= opts.n_starts <= MAX_STARTS:
        raise ValueError(f"n_starts = {opts.n_starts} must be between 1 and {MAX_STARTS} (each start is a "
                         f"whole search)")
    if not 1 <= opts.max_iterations <= MAX_ITERATIONS:
        raise ValueError(f"max_iterations = {opts.max_iterations} must be between 1 and {MAX_ITERATIONS}")
    if not (opts.start_spread >= 0 and opts.tol_loss >= 0 and opts.tol_step >= 0 and opts.tol_decrease >= 0):
        raise ValueError("start_spread, tol_loss, tol_step and tol_decrease must be non-negative")
    if opts.drift_segments != 0 and opts.drift_segments < 2:
        raise ValueError(f"drift_segments = {opts.drift_segments} must be 0 (off) or at least 2")
    if not isinstance(opts.skip_clipped, bool):
        raise ValueError(f"skip_clipped = {opts.skip_clipped!r} must be true or false")
    if opts.drift_frequency not in _drift.REPORTS:
        raise ValueError(f"drift_frequency = {opts.drift_frequency!r} must be one of "
                         + ", ".join(repr(r) for r in _drift.REPORTS))
    if opts.whiteness_band_rad_s is not None and not opts.whiteness_band_rad_s > 0:
        raise ValueError(f"whiteness_band_rad_s = {opts.whiteness_band_rad_s} must be positive (or None: all)")
    if opts.pencil_extra_order < 0:
        raise ValueError(f"pencil_extra_order = {opts.pencil_extra_order} must be non-negative")
    if opts.prior_std_rad_s is not None:
        _check_prior_std(opts, prior)
    if opts.posterior_summary not in ("mean", "mode"):
        raise ValueError(f"posterior_summary = {opts.posterior_summary!r} must be 'mean' or 'mode'")
    if not (isinstance(opts.posterior_draws, int) and 0 <= opts.posterior_draws <= 100_000):
        raise ValueError(f"posterior_draws = {opts.posterior_draws!r} must be an integer in 0…100000")
    if opts.damping_prior_std is not None and not (np.isfinite(opts.damping_prior_std)
                                                   and opts.damping_prior_std > 0):
        raise ValueError(f"damping_prior_std = {opts.damping_prior_std} must be positive (None: no prior on ζ)")


def _check_prior_std(opts: Options, prior: np.ndarray) -> None:
    """``prior_std_rad_s``: one positive finite number, or one per mode; only with the output-error model."""
    value = opts.prior_std_rad_s
    if hasattr(value, "_content"):                       # an OmegaConf ListConfig from a Hydra job
        value = list(value)
    if isinstance(value, (bool, str, dict)):
        raise ValueError(f"prior_std_rad_s = {value!r} must be a number or a list of numbers in rad/s")
    try:
        std = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"prior_std_rad_s = {value!r} must be a number or a list of numbers in rad/s") from None
    if std.ndim > 1 or (std.ndim == 1 and std.size != prior.size):
        raise ValueError(f"prior_std_rad_s = {value!r} must be one number or {prior.size} (one per mode)")
    if not (np.all(np.isfinite(std)) and np.all(std > 0)):
        raise ValueError(f"prior_std_rad_s = {value!r} must be positive and finite (absent: no prior)")
    if not (opts.predictor == "output_error" and opts.separable):
        raise ValueError(f"prior_std_rad_s needs predictor = 'output_error' and separable = true "
                         f"(got predictor = '{opts.predictor}', separable = {opts.separable})")


# Bounds on the work one fit may be asked for: beyond them an option is a typo, not a setting (a thousand
# starts of a ~1 ms search is a second per record; the default is 3, and 3-30 iterations converge).
MAX_STARTS = 1000
MIN_TAIL = 64            # samples after the last clipped one that the fit needs to leave the clipped part out
MAX_ITERATIONS = 10_000


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (validated without a record, before any work):
    keep this function (or its equivalent) when rewriting the module; ``identify`` runs the same checks."""
    opts = make_options(Options, options, "pem")
    _check_options(opts, np.atleast_1d(np.asarray(prior, dtype=float)))
    return opts


def free_mask(m: int, opts: Options) -> tuple[bool, ...]:
    """Which entries of θ = [ω, ζ, x₀, b] the search estimates."""
    return tuple([True] * m + [opts.estimate_damping] * m + [True] * (2 * m) + [opts.bias == "estimate"])


QUICK = "quick pencil"
QUICK_EXTRA_ORDER = 4         # the quick start's poles beyond 2m + 1 (the full start's: pencil_extra_order)


def quick_pencil_columns(m: int, extra_order: int) -> int:
    """The quick start's pencil parameter L from the model order M = 2m + 1 + extra: L = 2M + 2, so that V₁
    (L rows, M columns) has more than twice as many rows as columns, where
    :func:`methods.pem._pencil.matrix_pencil` solves V₁⁺V₂ in two products (with L < 2M it takes the
    pseudo-inverse). The full start's L is N/3 (up to 120), the noise-optimal side of Hua & Sarkar's
    N/3–N/2; the quick one is a cheap first guess that is kept only when its fit explains the record.
    (4 modes: M = 13, L = 28; the fixed L = 32 with M = 15 it replaces cost 1.07× its fit at N = 256. With
    2 extra poles, M = 11 and L = 24, a fit was 4 % faster still but accepted a local minimum on a record
    where this one does not: docs/notes/pem-speed.md, eighth pass.)"""
    return 2 * (2 * m + 1 + extra_order) + 2


def _line_start(best: dict, free, prior: np.ndarray, opts: Options, n: int, dt: float):
    """A start with the residual's strongest line in place of one mode the data do not determine, or None
    when every mode is determined, none is, or the residual holds no line.

    The ratio repair (:func:`_repaired_start`) trusts the prior's ratios; with each prior frequency
    independently 15–25 % off they can point at the wrong slot, and the fit keeps a spare mode parked
    beside a determined one while a true mode stands unexplained in the residual (basin design seed 7,
    N = 128: the mode at 64.9 rad/s left as a line 156× the floor, its slot taken by the mode at 34.4,
    called determined, the spare at 39.3). The residual shows where the missing mode is: its zero-padded
    periodogram's largest bin, when it stands above 2 ln(N/2α) times the mean power (the white-noise test
    of :func:`_explains_record`), and away from every determined mode (3 std). The undetermined mode nearest
    to it in log is replaced by it, and the m frequencies go to the slots in frequency order (the labels
    of :func:`_labelled` are then redone on the fit)."""
    w, w_std, z, _, slot, _ = _labelled(best, free, prior, opts)
    w, w_std, z = w[slot], w_std[slot], z[slot]
    determined = w_std <= search.IDENTIFIED_REL_STD * w
    e = best.get("e")
    if determined.all() or not determined.any() or e is None or not np.isfinite(w).all():
        return None
    power = float(e @ e)
    spectrum = np.abs(np.fft.rfft(e - e.mean(), 2 * n)) ** 2
    k = int(np.argmax(spectrum[1:])) + 1
    if not power > 0 or 2.0 * spectrum[k] / power < 2.0 * np.log(n / (2.0 * WHITENESS_ALPHA)):
        return None
    line = np.pi * k / (n * dt)                       # bin k of a 2n-point rfft, rad/s
    if np.any(np.abs(w[determined] - line) <= 3 * w_std[determined]):
        return None                                   # a determined mode's own line: nothing to move
    spare = np.flatnonzero(~determined)
    i = spare[np.argmin(np.abs(np.log(w[spare] / line)))]
    w0, z0 = w.copy(), z.copy()
    w0[i], z0[i] = line, opts.damping_ratio
    order = np.argsort(w0, kind="stable")
    return w0[order], (z0[order] if opts.estimate_damping else np.full(prior.size, opts.damping_ratio))


def starts(y, dt, prior, opts: Options):
    """(label, ω, ζ) of every start, made when asked for: with ``accept_white`` first a quick pencil start
    (order 2m + 5, L from it, :func:`quick_pencil_columns`: 28 for 4 modes, a small fraction of the full
    pencil's time at N = 256; kept only if its fit explains the record, see :func:`_explains_record`), then
    the ``n_starts``: the pencil start (L = N/3 up to 120: a quick start alone lost 4 % of the random
    structures of ``experiments.benchmarks.basin`` to local minima), the prior, then seeded perturbations."""
    z_prior = np.full(prior.size, opts.damping_ratio)

    def pencil(label, max_columns, extra_order=opts.pencil_extra_order):
        try:
            w, z = pencil_start(y, dt, prior, extra_order=extra_order,
                                default_zeta=opts.damping_ratio, max_columns=max_columns)
        except np.linalg.LinAlgError:
            return None
        return label, w, z if opts.estimate_damping else z_prior

    quick_extra = min(opts.pencil_extra_order, QUICK_EXTRA_ORDER)
    quick_columns = quick_pencil_columns(prior.size, quick_extra)
    if opts.data_driven_start and opts.accept_white and min(y.size, PENCIL_WINDOW) // 3 > quick_columns:
        start = pencil(QUICK, quick_columns, quick_extra)
        if start is not None:
            yield start
    made = 0
    if opts.data_driven_start:
        start = pencil("pencil", 120)
        if start is not None:
            yield start
            made += 1
    if made < opts.n_starts:
        yield "prior", prior.copy(), z_prior
        made += 1
    rng = np.random.default_rng(opts.seed)
    nyquist = np.pi / dt
    while made < opts.n_starts:
        w = prior * np.exp(opts.start_spread * rng.standard_normal(prior.size))
        yield f"perturbed{made}", np.minimum(w, 0.95 * nyquist), z_prior
        made += 1


def detection_std(n: int, dt: float, alpha: float = 0.01) -> float:
    """The largest std(ω) of a mode the record detects, at false-alarm rate ``alpha``.

    A sinusoid of energy E in white noise σ over N samples has std(ω) ≈ √(6σ²/E)/(N·Δt) (its Fisher
    information; damping only raises it). Pure noise exceeds E/σ² = 2 ln(N/2α) with probability α (the
    largest of N/2 χ²₂ projections, the rule of the fft's peak test and methods.peers._mode_picker), so a mode whose
    std is above √(3/ln(N/2α))/(N·Δt) — about a tenth of the Fourier resolution 2π/(NΔt) — is not told
    apart from noise.
    """
    return math.sqrt(3.0 / math.log(n / (2.0 * alpha))) / (n * dt)


def _estimate(best: dict, fits: list[dict], prior: np.ndarray, free, n: int, dt: float, opts: Options,
              energy: bool = True) -> Estimate:
    """The winning fit as an Estimate, its modes labelled with the prior entries (:func:`_label_modes`);
    a mode whose entry is uncertain is not determined."""
    w, w_std, z, z_std, slot, placed = _labelled(best, free, prior, opts)
    detected = _detected(best, w_std, n, dt, 0.01, energy)[slot]
    freq, std, damp, damp_std = w[slot], w_std[slot], z[slot], z_std[slot]
    identified = std <= search.IDENTIFIED_REL_STD * freq
    agree, agree_converged = 0, False
    finite = bool(np.isfinite(freq).all())
    for f in fits:
        if f is best and finite:    # its own frequencies: within 3 std of themselves in every determined mode
            agree += 1
            agree_converged |= f["converged"]
        elif np.isfinite(f["loss"]):
            fw, _, _, _, fw_slot, _ = _labelled(f, free, prior, opts)
            fw = fw[fw_slot]
            if (np.abs(fw - freq)[identified] <= 3 * std[identified]).all():
                agree += 1
                agree_converged |= f["converged"]
    # The answer stands when a search that reached it (within 3 std in every determined mode) stopped on
    # a tolerance, even if the lowest-loss one ran into the iteration limit.
    converged = bool(best["converged"] or agree_converged)
    # per mode: the search stopped on a tolerance and the record locates the mode (a finite, non-zero std
    # within 10 % of ω) and detects it (below); no such mode — an all-zero, constant or pure-noise record
    # — is no answer at all
    per_mode = (converged & np.isfinite(std) & (std > 0) & (std <= search.LOCATED_REL_STD * freq)
                & detected & placed)
    converged = converged and bool(per_mode.any())
    std = np.where(np.isfinite(std), std, np.nan)   # a column the record does not move: no std, not inf
    extra = {
        "damping": damp, "damping_std": damp_std, "identified": identified,
        "offset_m_s2": float(best["theta"][-1]), "loss": float(best["loss"]),
        "n_starts": len(fits), "n_agree": agree, "best_start": best["start"],
        "start_losses": np.array([f["loss"] for f in fits]),
        "start_messages": [f"{f['start']}: {f['message']}" for f in fits],
        "total_iterations": int(sum(f["iterations"] for f in fits)),
    }
    message = f"{best['message']} (start '{best['start']}', {agree}/{len(fits)} starts agree)"
    std, message = _residual_hook(best, slot, free, dt, std, extra, message, opts.whiteness_band_rad_s)
    return Estimate(freq, std, converged=converged, iterations=int(best["iterations"]),
                    message=message, extra=extra, converged_per_mode=per_mode)


def _residual_hook(best, slot, free, dt, std, extra, message, band_rad_s=None):
    """extra["residual_check"] (:func:`methods.pem._residual.assess_fit`); when the residual is not white,
    the reported std is the Newey–West robust one (the white-noise one kept in extra["white_noise_std"])."""
    check = _residual.assess_fit(best, slot, int(sum(free)), dt, band_rad_s=band_rad_s)
    extra["residual_check"] = check
    if check is None or check["white"]:
        return std, message
    robust = check["robust_std_rad_s"]
    extra["white_noise_std"] = std
    std = np.where(np.isfinite(robust) & np.isfinite(std), robust, std)
    return std, (f"{message}; residual not white (Ljung-Box p = {check['ljung_box_p']:.2g}, peak "
                 f"{check['peak_over_floor']:.3g}x floor at {check['peak_rad_s']:.4g} rad/s): std is the robust "
                 "(sandwich) one")


def _mode_table(fit: dict, free, m: int):
    """ω, std(ω), ζ, std(ζ) of a fit in θ order; std = σ̂√diag((JᵀJ)⁻¹), NaN for a fixed entry."""
    std = np.full(fit["theta"].size, np.nan)
    std[_free_index(free)] = _free_std(fit)
    th = fit["theta"]
    return th[:m].copy(), std[:m], th[m:2 * m].copy(), std[m:2 * m]


@functools.lru_cache(maxsize=64)
def _free_index(free: tuple[bool, ...]) -> np.ndarray:
    """np.flatnonzero of a free mask (a tuple: made once per mask, not per fit)."""
    index = np.flatnonzero(free)
    index.flags.writeable = False
    return index


def _labelled(fit: dict, free, prior: np.ndarray, opts: Options):
    """:func:`_mode_table` of a fit, its :func:`_label_modes` slots and which slots are placed, computed
    once per fit (the repair rule, the agreement count and the estimate all ask for the winning fit's)."""
    if "labelled" not in fit:
        w, w_std, z, z_std = _mode_table(fit, free, prior.size)
        band = np.inf if opts.frequency_band is None else opts.frequency_band
        fit["labelled"] = (w, w_std, z, z_std, *_label_modes(w, w_std, prior, band))
    return fit["labelled"]


def _label_modes(w: np.ndarray, w_std: np.ndarray, prior: np.ndarray, band: float = 0.5):
    """Which fitted mode answers for each prior entry, and whether its slot is certain.

    Returns ``slot`` (``slot[i]`` is the mode reported for ``prior[i]``) and ``placed`` (per prior entry).
    Modes the data determine (std ≤ 1 % of ω) take prior entries by :func:`methods.labels.assign`: in
    frequency order (with every mode determined this is plain sorting), the entries of the others told by
    the common scale factor of the determined ones; one whose entry is uncertain is not placed. The
    undetermined modes — a model with more modes than the record supports parks them anywhere, e.g. above
    the highest mode — fill the remaining entries in frequency order, placed only where that keeps the
    reported frequencies increasing and within the band of their entry.
    """
    m = prior.size
    # the determined modes in frequency order, over m Python floats (numpy's comparisons and argsort order)
    wl, sl = w.tolist(), w_std.tolist()
    good_l = [i for i in range(m) if sl[i] <= search.IDENTIFIED_REL_STD * wl[i]]
    good = np.array([good_l[j] for j in argsort_few([wl[i] for i in good_l])], dtype=int)
    lab = labels.assign(w[good], prior, band=band)
    slot, placed = np.empty(m, int), np.zeros(m, bool)
    slot[lab.slot], placed[lab.slot] = good, lab.placed
    if good.size == m:                            # every mode determined (the usual case): nothing left over
        return slot, placed
    taken = np.zeros(m, bool)                     # np.setdiff1d's values from two masks (a tenth of its time)
    taken[good] = True
    rest = np.flatnonzero(~taken)
    rest = rest[np.argsort(w[rest])]
    taken[:] = False
    taken[lab.slot] = True
    free_slots = np.flatnonzero(~taken)                               # in prior order
    slot[free_slots] = rest
    if good.size < m:
        f = w[slot]
        lo, hi = np.r_[0.0, f[:-1]], np.r_[f[1:], np.inf]
        in_band = np.abs(np.log(f / prior)) <= np.log1p(band)
        placed[free_slots] = ((lo < f) & (f < hi) & in_band)[free_slots]
    return slot, placed


def segment_drift(y, dt: float, prior, n_segments: int = 4, alpha: float = _drift.DRIFT_ALPHA, whole=None,
                  **options) -> _drift.DriftReport:
    """The drift test of :func:`methods.pem._drift.segment_drift` (its parameters but ``fit``) with pem's own
    fit, :func:`identify`."""
    return _drift.segment_drift(y, dt, prior, n_segments, alpha, whole, fit=identify, **options)
