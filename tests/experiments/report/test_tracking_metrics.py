"""Tracking scores on hand-made tracks whose answers are known by construction."""

import math

import numpy as np
import pandas as pd
import pytest

from experiments.report.tracking_metrics import converged_from, score_track, summarize_cell

DT = 0.02
N = 3000                                    # 60 s
T = np.arange(N) * DT
W0 = np.array([3.23, 20.24, 22.0, 56.67])


def constant_truth():
    return np.tile(W0, (N, 1))


def score(est, truth, **kw):
    kw.setdefault("runtime_s", 0.1)
    return score_track(T, est, np.ones_like(est, bool), kw.pop("runtime_s"), truth, DT, **kw)


def test_perfect_track_scores_zero_error_at_once():
    truth = constant_truth()
    s = score(truth.copy(), truth, bound=0.001 * truth)
    assert s["t_converge_s"] == 0.0 and s["share_within_1pct"] == 1.0
    assert s["err_rel_median"] == 0.0 and s["err_bound_p90"] == 0.0
    assert not s["diverged"] and not s["false_lock"]


def test_time_to_converge_from_a_prior_5_percent_off():
    truth = constant_truth()
    est = truth * 1.05
    est[T >= 10.0] = truth[T >= 10.0] * 1.002
    s = score(est, truth, bound=0.001 * truth)
    assert s["t_converge_s"] == pytest.approx(10.0)
    assert s["share_within_1pct"] == pytest.approx(50 / 60, abs=1e-3)
    assert s["err_rel_median"] == pytest.approx(0.002)
    assert s["err_bound_median"] == pytest.approx(2.0)          # 0.2 % error over a 0.1 % bound


def test_error_is_scored_against_every_bound_each_in_its_own_column():
    truth = constant_truth()
    est = truth * 1.002
    s = score(est, truth, bound=0.001 * truth, bound_unknown_force=0.004 * truth, bound_unknown_rate=0.008 * truth)
    assert s["err_bound_median"] == pytest.approx(2.0)          # × the genie bound
    assert s["err_ufbound_median"] == pytest.approx(0.5)        # × the unknown-force bound
    assert s["err_rbound_median"] == pytest.approx(0.25)        # × the unknown-rate bound
    assert s["err_ufbound_median_late"] == pytest.approx(0.5)   # the second half, converged or not
    alone = score(est, truth, bound=0.001 * truth)
    assert np.isnan(alone["err_ufbound_median"]) and np.isnan(alone["err_rbound_median"])


def test_a_short_visit_within_1_percent_is_not_convergence():
    truth = constant_truth()
    est = truth * 1.05
    est[(T >= 5.0) & (T < 6.0)] = truth[0]                       # 1 s < hold 2 s
    est[T >= 20.0] = truth[0]
    assert score(est, truth)["t_converge_s"] == pytest.approx(20.0)


def test_never_converged_is_nan_and_counted():
    truth = constant_truth()
    s = score(truth * 1.05, truth)
    assert math.isnan(s["t_converge_s"]) and math.isnan(s["err_rel_median"])
    assert s["err_rel_median_late"] == pytest.approx(0.05)       # the late error still ranks it
    rows = pd.DataFrame([s, score(truth.copy(), truth)])
    summary = summarize_cell(rows)
    assert summary["never_converged_rate"] == 0.5 and summary["t_converge_s"] == 0.0


def test_reconvergence_after_a_step():
    truth = constant_truth()
    truth[T >= 30.0, 2] *= 1.06                                   # mode 3 up 6 % at 30 s
    est = truth.copy()
    late = (T >= 30.0) & (T < 34.0)
    est[late, 2] = W0[2]                                          # still the old value for 4 s
    s = score(est, truth, step_time_s=30.0)
    assert s["t_reconverge_s"] == pytest.approx(4.0)
    assert summarize_cell(pd.DataFrame([s]), has_step=True)["never_reconverged_rate"] == 0.0


def test_a_replicate_that_never_reconverges_counts_in_the_cells_median():
    truth = constant_truth()
    truth[T >= 30.0, 2] *= 1.06
    fast, slow, never = truth.copy(), truth.copy(), truth.copy()
    fast[(T >= 30.0) & (T < 34.0), 2] = W0[2]                     # back 4 s after the step
    slow[(T >= 30.0) & (T < 40.0), 2] = W0[2]                     # back 10 s after it
    never[T >= 30.0, 2] = W0[2]                                   # never back
    rows = [score(e, truth, step_time_s=30.0) for e in (fast, never)]
    two = summarize_cell(pd.DataFrame(rows), has_step=True)
    # the median of 4 s and never is never, not the 4 s of the one that came back
    assert two["t_reconverge_s"] == math.inf and two["never_reconverged_rate"] == 0.5
    three = summarize_cell(pd.DataFrame(rows + [score(slow, truth, step_time_s=30.0)]), has_step=True)
    assert three["t_reconverge_s"] == pytest.approx(10.0)


def test_lag_of_a_late_copy_of_a_drift():
    truth = W0 * (1 + 0.2 * T / T[-1])[:, None]
    lag = 3.0
    est = W0 * (1 + 0.2 * np.clip(T - lag, 0, None) / T[-1])[:, None]
    s = score(est, truth, drift_span_s=[0.0, T[-1]])
    assert s["lag_s"] == pytest.approx(lag, abs=0.1)


def test_divergence_and_false_lock_are_told_apart():
    truth = constant_truth()
    est = truth.copy()
    est[T >= 50.0] *= 2.0
    assert score(est, truth)["diverged"]
    est = truth.copy()
    est[T >= 50.0, 1] *= 1.03                                     # settled 3 % off, flagged converged
    s = score(est, truth)
    assert s["false_lock"] and not s["diverged"]
    lost = truth.copy()
    lost[T >= 50.0, 0] = np.nan                                   # mode 1 lost for good
    assert score(lost, truth)["diverged"]
    blip = truth.copy()
    blip[-10:, 0] = np.nan                                        # 10 missing estimates of 300 in the tail
    assert not score(blip, truth)["diverged"]


def test_a_missing_estimate_counts_as_a_large_error_not_a_nan():
    truth = constant_truth()
    est = truth * 1.001
    est[::5] = np.nan                                             # a fifth of the windows found nothing
    s = score(est, truth, bound=0.001 * truth, hold_s=0.0)
    assert s["err_bound_median"] == pytest.approx(1.0) and s["err_bound_p90"] == np.inf


def test_onboard_verdict_at_20_ms_on_a_processor_100_times_slower():
    truth = constant_truth()
    fast = score(truth, truth, runtime_s=1.9e-4 * N)             # 0.19 ms/sample -> 19 ms on board
    slow = score(truth, truth, runtime_s=2.1e-4 * N)
    assert fast["onboard_ok"] and not slow["onboard_ok"]
    assert fast["cpu_per_sample_s"] == pytest.approx(1.9e-4)


def test_track_on_a_coarser_grid_is_compared_at_its_own_samples():
    truth = W0 * (1 + 0.1 * T / T[-1])[:, None]
    k = np.arange(99, N, 50)
    s = score_track(T[k], truth[k], np.ones((k.size, 4), bool), 0.0, truth, DT)
    assert s["err_rel_median"] == 0.0 and s["t_converge_s"] == pytest.approx(T[99])


def test_track_times_off_the_record_are_refused():
    truth = constant_truth()
    with pytest.raises(ValueError, match="sample times"):
        score_track(T + 0.007, truth, np.ones((N, 4), bool), 0.0, truth, DT)


def test_converged_from_holds_to_the_end_of_the_record():
    t = np.arange(10.0)
    ok = np.array([0, 0, 0, 0, 0, 0, 0, 1, 1, 1], bool)
    assert converged_from(t, ok, 0.0, hold_s=2.0) == 7.0
    assert math.isnan(converged_from(t, ok, 0.0, hold_s=5.0))
