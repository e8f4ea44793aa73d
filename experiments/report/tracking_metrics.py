"""Scores of a frequency tracker on one record, and of a tracker on one cell (its replicates).

A track is the tracker's estimate ω̂ᵢ(t_j) at its own times t_j (each a sample time, causal); the truth is
ωᵢ(t_k) at every sample. Every score compares ω̂ᵢ(t_j) with ωᵢ at the same sample. Definitions (``tol`` = 1 %,
``hold_s`` = 2 s by default):

* **converged at t**: every mode within ``tol`` of the truth, |ω̂ᵢ − ωᵢ| ≤ tol·ωᵢ, from t on for at least
  ``hold_s`` (judged against the truth, not the tracker's own flag). **Time to converge**: the first such
  t, from the record's start. **Re-convergence**: the first such t at or after a step, minus the step's
  instant. NaN when it never happens (reported as such, and counted).
* **tracking error**: eᵢ(t) = |ω̂ᵢ − ωᵢ| after the first convergence, relative to ωᵢ and to the bounds
  (the PCRB std at that sample: ``err_bound_*`` the **genie** bound, every input known; ``err_ufbound_*``
  the **unknown-force** bound, the white disturbance unknown; ``err_rbound_*`` on a drift cell the
  **unknown-rate** bound, the unknown-force one not told the drift's rate); its median and 90th percentile over time and
  modes (empirical quantiles, no interpolation: a missing estimate counts as an infinite error). An
  efficient unbiased tracker's |e|/σ has median 0.67 (the half-normal's), so ``err_ufbound_median`` ≈ 0.67
  is at the bound and 1.35 is twice it.
* **late error**: the same error over the second half of the record whether or not the tracker converged
  (``err_rel_median_late``, ``err_rel_p90_late``; × the unknown-force bound ``err_ufbound_median_late``): it
  ranks trackers that never hold all four modes.
* **share within 1 %**: the fraction of the track's times at which every mode is within ``tol``.
* **lag under a drift**: the delay τ ≥ 0 that best explains the estimate as a late copy of the truth,
  argmin_τ median_t |ω̂ᵢ(t) − ωᵢ(t − τ)| over the drifting span after convergence, per mode; the median
  over modes is reported.
* **diverged**: over the last 10 % of the record the median error of some mode exceeds 10 % (a missing
  estimate counts as an infinite error, so a mode lost most of that time counts; one window without it
  does not). **False lock**: not diverged, but over the last 10 % the tracker flags a mode
  converged (most of the time) while its median error exceeds ``tol``.
* **CPU per sample**: ``runtime_s`` / samples; **on board**: a processor 100× slower keeps up at
  20 ms per sample (``cpu_per_sample_s`` × 100 ≤ 0.020 s).

A **laboratory record** (``experiments.simulate.laboratory``: moves every 0.4–2 s, ``step_times_s``) is
scored per dwell (:func:`score_dwells`), as a lab scores it: a dwell j runs from move j (the record's start
for j = 0) to the next; its **scored span** starts ``SETTLE_PERIODS`` (10) periods of the dwell's slowest
mode after the move. ``err_rel_median``/``p90`` and ``share_within_1pct`` are over the scored spans;
**re-convergence** after move j is the first estimate time from which every mode stays within ``tol`` to the
dwell's end (never: ∞), ``t_reconverge_s`` its median over moves (NaN if that is ∞), ``reconverge_periods``
the same in periods of the slowest mode, ``reconverged_share`` the share of moves re-converged within
``SETTLE_PERIODS`` periods; ``t_converge_s`` is dwell 0's. The late error, divergence and false lock are as
above; the lag and the bound columns are NaN (no drift, no bound computed).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

__all__ = ["DIVERGED_REL", "HOLD_S", "ONBOARD_BUDGET_S", "ONBOARD_SLOWDOWN", "SETTLE_PERIODS", "SUMMARY_MEDIANS",
           "TAIL", "TOL", "converged_from", "lag_s", "reconvergence_median", "sample_index", "score_dwells",
           "score_record", "score_track", "summarize_cell"]

TOL = 0.01
HOLD_S = 2.0
ONBOARD_SLOWDOWN = 100.0
ONBOARD_BUDGET_S = 0.020
TAIL = 0.10
DIVERGED_REL = 0.10
SETTLE_PERIODS = 10.0            # a laboratory dwell is scored from this many periods of its slowest mode on


def sample_index(t_s, dt_s: float, n_samples: int) -> np.ndarray:
    """The sample index k = t/Δt of each estimate time; ``ValueError`` if one is not a sample of the record."""
    t_s = np.asarray(t_s, dtype=float)
    k = np.round(t_s / dt_s).astype(int)
    if t_s.size == 0:
        raise ValueError("the track has no estimates")
    if np.any(np.abs(k * dt_s - t_s) > 1e-6 * dt_s) or k.min() < 0 or k.max() >= n_samples:
        raise ValueError(f"track times must be sample times within the record (0 … {(n_samples - 1) * dt_s:g} s); "
                         f"got {t_s.min():g} … {t_s.max():g} s")
    return k


def converged_from(t_s: np.ndarray, ok: np.ndarray, start_s: float, hold_s: float = HOLD_S) -> float:
    """The first time t ≥ ``start_s`` from which ``ok`` holds for at least ``hold_s`` (or to the record's
    end, if that is at least ``hold_s`` later); NaN if none."""
    t_s = np.asarray(t_s, dtype=float)
    ok = np.asarray(ok, dtype=bool)
    n = t_s.size
    # next_bad[j]: index of the first not-ok at or after j (n if none)
    idx = np.where(~ok, np.arange(n), n)
    next_bad = np.minimum.accumulate(idx[::-1])[::-1]
    end_t = np.append(t_s, np.inf)[next_bad]
    end_t = np.where(next_bad == n, t_s[-1] + (t_s[-1] - t_s[-2] if n > 1 else 0.0), end_t)
    good = ok & (t_s >= start_s) & (end_t - t_s >= hold_s)
    j = np.flatnonzero(good)
    return float(t_s[j[0]]) if j.size else math.nan


def lag_s(t_s: np.ndarray, est: np.ndarray, truth_t_s: np.ndarray, truth: np.ndarray, span_s, *,
          max_lag_s: float = 30.0, step_s: float | None = None) -> float:
    """Median over modes of argmin_τ median_t |ω̂ᵢ(t) − ωᵢ(t − τ)|, t in ``span_s`` (module docstring)."""
    lo, hi = span_s
    sel = (t_s >= lo) & (t_s <= hi) & np.all(np.isfinite(est), axis=1)
    if sel.sum() < 3:
        return math.nan
    step = step_s or float(truth_t_s[1] - truth_t_s[0]) * 5
    taus = np.arange(0.0, max_lag_s + step / 2, step)
    lags = []
    for i in range(est.shape[1]):
        cost = [np.median(np.abs(est[sel, i] - np.interp(t_s[sel] - tau, truth_t_s, truth[:, i]))) for tau in taus]
        lags.append(taus[int(np.argmin(cost))])
    return float(np.median(lags))


def _relative_errors(t_s, frequencies, truth: np.ndarray, dt_s: float):
    """(t_s, est, k, err, rel, ok): the track at the samples ``k`` of its instants, its absolute (rad/s) and
    relative errors against the truth there (a missing estimate: an infinite error)."""
    t_s = np.asarray(t_s, dtype=float)
    est = np.asarray(frequencies, dtype=float)
    n, m = truth.shape
    if est.shape != (t_s.size, m):
        raise ValueError(f"track frequencies of shape {est.shape}; expected ({t_s.size}, {m})")
    k = sample_index(t_s, dt_s, n)
    err = np.abs(est - truth[k])
    rel = np.where(np.isfinite(err), err / truth[k], np.inf)
    return t_s, est, k, err, rel


def _cost(runtime_s: float, n: int) -> dict:
    """The track's CPU time, per sample, and whether that fits the on-board budget."""
    out = {"n_samples": n, "cpu_s": float(runtime_s), "cpu_per_sample_s": float(runtime_s) / n}
    out["onboard_ok"] = bool(out["cpu_per_sample_s"] * ONBOARD_SLOWDOWN <= ONBOARD_BUDGET_S)
    return out


def _late(t_s: np.ndarray) -> np.ndarray:
    """The instants of the record's second half."""
    return t_s >= t_s[0] + 0.5 * (t_s[-1] - t_s[0])


def _percentile(values: np.ndarray, q: float) -> float:
    return float(np.percentile(values, q, method="inverted_cdf"))


def _mode_medians(rel: np.ndarray, scored: np.ndarray) -> dict:
    """Each mode's median relative error over the scored instants."""
    return {f"err_rel_median_mode{i + 1}": float(np.median(rel[scored, i])) if scored.any() else math.nan
            for i in range(rel.shape[1])}


def _tail_verdicts(t_s: np.ndarray, rel: np.ndarray, converged, tol: float) -> dict:
    """Over the record's last TAIL: ``diverged`` (a mode's median error above DIVERGED_REL) and ``false_lock``
    (not diverged, but a mode the tracker flags as converged is off by more than ``tol``)."""
    m = rel.shape[1]
    tail = t_s >= t_s[0] + (1 - TAIL) * (t_s[-1] - t_s[0])
    med = np.median(rel[tail], axis=0) if tail.any() else np.full(m, np.inf)
    diverged = bool(np.any(med > DIVERGED_REL))
    flagged = np.asarray(converged, dtype=bool)[tail].mean(axis=0) > 0.5 if tail.any() else np.zeros(m, bool)
    return {"diverged": diverged, "false_lock": bool(not diverged and np.any(flagged & (med > tol)))}


def score_track(t_s, frequencies, converged, runtime_s: float, truth: np.ndarray, dt_s: float, *,
                bound: np.ndarray | None = None, bound_unknown_force: np.ndarray | None = None,
                bound_unknown_rate: np.ndarray | None = None, step_time_s: float | None = None, drift_span_s=None,
                tol: float = TOL, hold_s: float = HOLD_S) -> dict:
    """The scores of one track against the truth of its record (module docstring).

    Parameters
    ----------
    t_s : ndarray, shape (K,)
    frequencies, converged : ndarray, shape (K, m)
        The track's estimates (rad/s) and its own flags.
    truth : ndarray, shape (N, m)
        ωᵢ at every sample of the record.
    bound : ndarray, shape (N, m), optional
        The genie PCRB std at every sample (rad/s): ``err_bound_*``.
    bound_unknown_force : ndarray, shape (N, m), optional
        The unknown-force PCRB std at every sample (rad/s): ``err_ufbound_*``.
    bound_unknown_rate : ndarray, shape (N, m), optional
        The unknown-rate PCRB std (a line's rate not told; drift cells only): ``err_rbound_*``.

    Returns
    -------
    dict of float
    """
    t_s, est, k, err, rel = _relative_errors(t_s, frequencies, truth, dt_s)
    n = truth.shape[0]
    ok = np.all(rel <= tol, axis=1)
    t_conv = converged_from(t_s, ok, float(t_s[0]), hold_s)
    out = {"t_converge_s": t_conv, "share_within_1pct": float(ok.mean()), **_cost(runtime_s, n)}
    after = t_s >= t_conv if math.isfinite(t_conv) else np.zeros(t_s.size, bool)
    for name, q in (("median", 50), ("p90", 90)):
        out[f"err_rel_{name}"] = _percentile(rel[after], q) if after.any() else math.nan
        for key, b in (("err_bound", bound), ("err_ufbound", bound_unknown_force),
                       ("err_rbound", bound_unknown_rate)):
            if b is not None and after.any():
                ratio = err[after] / np.asarray(b)[k][after]
                ratio = np.where(np.isfinite(ratio), ratio, np.inf)     # a missing estimate is no small error
                out[f"{key}_{name}"] = _percentile(ratio, q)
            else:
                out[f"{key}_{name}"] = math.nan
    late = _late(t_s)
    out["err_rel_median_late"] = _percentile(rel[late], 50)
    out["err_ufbound_median_late"] = math.nan
    if bound_unknown_force is not None:
        ratio = err[late] / np.asarray(bound_unknown_force)[k][late]
        out["err_ufbound_median_late"] = _percentile(np.where(np.isfinite(ratio), ratio, np.inf), 50)
    out["err_rel_p90_late"] = _percentile(rel[late], 90)
    out.update(_mode_medians(rel, after))
    out["t_reconverge_s"] = math.nan
    if step_time_s is not None and math.isfinite(step_time_s):
        t_re = converged_from(t_s, ok, float(step_time_s), hold_s)
        out["t_reconverge_s"] = t_re - float(step_time_s)
    out["lag_s"] = math.nan
    if drift_span_s is not None and np.all(np.isfinite(drift_span_s)) and math.isfinite(t_conv):
        lo, hi = drift_span_s
        out["lag_s"] = lag_s(t_s, est, np.arange(n) * dt_s, truth, (max(lo, t_conv), hi))
    out.update(_tail_verdicts(t_s, rel, converged, tol))
    return out


def score_dwells(t_s, frequencies, converged, runtime_s: float, truth: np.ndarray, dt_s: float,
                 step_times_s, *, tol: float = TOL, settle_periods: float = SETTLE_PERIODS) -> dict:
    """The scores of one track of a laboratory record, dwell by dwell (module docstring).

    Parameters
    ----------
    t_s, frequencies, converged, runtime_s, truth, dt_s
        As :func:`score_track`.
    step_times_s : array_like, shape (S,)
        The moves' instants, s (increasing).

    Returns
    -------
    dict of float
        The keys of :func:`score_track`, plus ``reconverge_periods`` and ``reconverged_share``.
    """
    t_s, _, _, _, rel = _relative_errors(t_s, frequencies, truth, dt_s)
    n = truth.shape[0]
    ok = np.all(rel <= tol, axis=1)
    edges = np.concatenate([[0.0], np.asarray(step_times_s, float).reshape(-1), [n * dt_s]])
    scored = np.zeros(t_s.size, bool)
    reconv_s, reconv_periods = [], []
    for j in range(edges.size - 1):
        lo, hi = edges[j], edges[j + 1]
        inside = (t_s >= lo) & (t_s < hi)
        mid = min(int(round(0.5 * (lo + hi) / dt_s)), n - 1)
        period = 2 * np.pi / float(truth[mid].min())
        scored |= inside & (t_s >= lo + settle_periods * period)
        idx = np.flatnonzero(inside)
        # first estimate of the dwell from which every later one in the dwell is within tol
        bad = idx[~ok[idx]]
        first = idx[0] if idx.size and bad.size == 0 else (bad[-1] + 1 if bad.size and bad[-1] + 1 <= idx[-1]
                                                            else None)
        r = (t_s[first] - lo) if first is not None else math.inf
        reconv_s.append(r)
        reconv_periods.append(r / period)
    out = _cost(runtime_s, n)
    out["share_within_1pct"] = float(ok[scored].mean()) if scored.any() else math.nan
    for name, q in (("median", 50), ("p90", 90)):
        out[f"err_rel_{name}"] = _percentile(rel[scored], q) if scored.any() else math.nan
        out[f"err_bound_{name}"] = math.nan
        out[f"err_ufbound_{name}"] = math.nan                # no bound is computed for a laboratory record
        out[f"err_rbound_{name}"] = math.nan
    late = _late(t_s)
    out["err_rel_median_late"] = _percentile(rel[late], 50)
    out["err_rel_p90_late"] = _percentile(rel[late], 90)
    out["err_ufbound_median_late"] = math.nan
    out.update(_mode_medians(rel, scored))
    moves = np.asarray(reconv_s[1:] or [math.nan])
    med = float(np.median(moves))
    out["t_converge_s"] = reconv_s[0] if math.isfinite(reconv_s[0]) else math.nan
    out["t_reconverge_s"] = med if math.isfinite(med) else math.nan
    med_p = float(np.median(reconv_periods[1:])) if len(reconv_periods) > 1 else math.nan
    out["reconverge_periods"] = med_p if math.isfinite(med_p) else math.nan
    out["reconverged_share"] = (float(np.mean(np.asarray(reconv_periods[1:]) <= settle_periods))
                                if len(reconv_periods) > 1 else math.nan)
    out["lag_s"] = math.nan
    out.update(_tail_verdicts(t_s, rel, converged, tol))
    return out


def score_record(t_s, frequencies, converged, runtime_s: float, cell: dict, r: int) -> dict:
    """The scores of replicate ``r``'s track against its cell (a grid cell's arrays): per dwell for a
    laboratory cell (``step_times_s``), else :func:`score_track` with the cell's bound, step and drift."""
    dt = float(cell["dt_s"])
    if "step_times_s" in cell:
        return score_dwells(t_s, frequencies, converged, runtime_s, cell["truth_freq_rad_s"], dt,
                            cell["step_times_s"])
    step = float(cell["step_time_s"])
    span = cell["drift_span_s"]
    return score_track(t_s, frequencies, converged, runtime_s, cell["truth_freq_rad_s"], dt,
                       bound=cell["pcrb_std_rad_s"][r] if "pcrb_std_rad_s" in cell else None,
                       bound_unknown_force=(cell["pcrb_unknown_force_std_rad_s"][r]
                                            if "pcrb_unknown_force_std_rad_s" in cell else None),
                       bound_unknown_rate=(cell["pcrb_unknown_rate_std_rad_s"][r]
                                           if "pcrb_unknown_rate_std_rad_s" in cell else None),
                       step_time_s=step if np.isfinite(step) else None,
                       drift_span_s=span if np.all(np.isfinite(span)) else None)


SUMMARY_MEDIANS = ("t_converge_s", "t_reconverge_s", "err_rel_median", "err_rel_p90", "err_bound_median",
                   "err_bound_p90", "err_ufbound_median", "err_ufbound_p90", "err_rbound_median", "err_rel_median_late",
                   "err_rel_p90_late",
                   "err_ufbound_median_late", "share_within_1pct", "lag_s", "cpu_per_sample_s", "reconverge_periods",
                   "reconverged_share")


def reconvergence_median(values) -> float:
    """The median over replicates of a re-convergence (s or periods) in which a replicate that never
    re-converged (NaN) counts as ∞, not as absent: two replicates of 5 s and never give ∞ ("never"), three
    of 5 s, 7 s and never give 7 s. NaN only when there is no replicate."""
    v = np.asarray(values, dtype=float)
    return float(np.median(np.where(np.isnan(v), np.inf, v))) if v.size else math.nan


def summarize_cell(rows: pd.DataFrame, *, has_step: bool = False) -> dict:
    """One (tracker, cell): medians over replicates of the per-record scores, and the rates (the share of
    replicates that never converged, never re-converged after the step, diverged, locked falsely). On a
    step cell (``has_step``) the re-convergence's median counts a replicate that never re-converged as ∞
    (:func:`reconvergence_median`), so the median of a cell is never read off its fast replicates alone."""
    out = {"replicates": int(len(rows))}
    for col in SUMMARY_MEDIANS:
        if col not in rows:                     # scores written before the column existed
            out[col] = math.nan
            continue
        values = rows[col].to_numpy(dtype=float)
        out[col] = float(np.nanmedian(values)) if np.isfinite(values).any() else math.nan
    if has_step:
        for col in ("t_reconverge_s", "reconverge_periods"):
            if col in rows:
                out[col] = reconvergence_median(rows[col].to_numpy(dtype=float))
    out["never_converged_rate"] = float(rows["t_converge_s"].isna().mean())
    out["never_reconverged_rate"] = float(rows["t_reconverge_s"].isna().mean()) if has_step else math.nan
    out["diverged_rate"] = float(rows["diverged"].astype(bool).mean())
    out["false_lock_rate"] = float(rows["false_lock"].astype(bool).mean())
    out["onboard_ok"] = bool(out["cpu_per_sample_s"] * ONBOARD_SLOWDOWN <= ONBOARD_BUDGET_S)
    return out
