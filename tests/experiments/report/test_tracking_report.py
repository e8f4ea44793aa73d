"""The tracking page's verdict against the naive baseline, on a hand-made summary."""

import math

import numpy as np
import pandas as pd

from experiments.report.tracking_report import verdict


def row(tracker, err, late, reconv, never_re=0.0):
    return {"tracker": tracker, "schedule": "step", "excitation": "thrusters", "noise_ug": 1000.0,
            "err_rel_median": err, "err_rel_median_late": late, "t_reconverge_s": reconv,
            "never_reconverged_rate": never_re}


def test_best_tracker_beats_the_baseline_at_half_its_error_and_20_s():
    lines = verdict(pd.DataFrame([row("pem", 0.002, 0.002, 8.0), row("next_era", 0.005, 0.005, 6.0)]))
    assert "**pem**" in lines[0] and "0.4× the error of the naive next_era (beats it:" in lines[0]


def test_slow_reconvergence_does_not_beat_it():
    lines = verdict(pd.DataFrame([row("pem", 0.002, 0.002, 25.0), row("next_era", 0.005, 0.005, 6.0)]))
    assert "does not beat it" in lines[0]


def test_baseline_that_never_converged_is_compared_by_late_error():
    lines = verdict(pd.DataFrame([row("fft", 0.004, 0.003, 5.0), row("next_era", math.nan, 0.03, math.nan, 1.0)]))
    assert "0.1× the late (it never held every mode) error" in lines[0] and "beats it" in lines[0]


def test_no_tracker_converged_names_the_smallest_late_error():
    lines = verdict(pd.DataFrame([row("fft", math.nan, 0.04, math.nan, 1.0),
                                  row("pll", math.nan, 0.09, math.nan, 1.0)]))
    assert "no tracker held every mode within 1 %; the smallest late error: fft, 4 %" in lines[0]


def test_a_tracker_converged_in_one_replicate_of_three_does_not_lead():
    lucky, steady, base = row("ssi_cov", 0.0005, 0.01, math.nan), row("gated_pencil", 0.001, 0.001, 9.0), \
        row("next_era", 0.005, 0.005, 6.0)
    lucky["never_converged_rate"], steady["never_converged_rate"], base["never_converged_rate"] = 2 / 3, 0.0, 0.0
    lines = verdict(pd.DataFrame([lucky, steady, base]))
    assert "**gated_pencil**" in lines[0] and "ssi_cov" not in lines[0]
    lone = verdict(pd.DataFrame([lucky]))
    assert "no tracker held every mode within 1 % in most replicates; the smallest late error: ssi_cov" in lone[0]


def test_baseline_ratio_and_the_bound_stand_beside_the_error():
    from experiments.report.tracking_report import add_baseline_ratio

    rows = [dict(row("pem", 0.002, 0.002, 8.0), cell="c", err_ufbound_median=1.3),
            dict(row("next_era", 0.005, 0.005, 6.0), cell="c", err_ufbound_median=3.0)]
    summary = add_baseline_ratio(pd.DataFrame(rows))
    assert summary["x_next_era"].tolist() == [0.4, 1.0]
    assert "(1.3× the unknown-force bound)" in verdict(summary)[0]
    summary["err_rbound_median"] = [0.6, 1.5]                       # a drift cell: the bound not told the rate
    assert "(1.3× the unknown-force bound, 0.6× the one not told the drift's rate)" in verdict(summary)[0]


def lab_row(tracker, err, share, periods):
    """A laboratory cell's summary: re-convergence counted in periods of the slowest mode over the moves."""
    return {"tracker": tracker, "schedule": "lab1", "excitation": "laboratory", "noise_ug": 300.0,
            "err_rel_median": err, "err_rel_median_late": err, "t_reconverge_s": 0.2,
            "never_reconverged_rate": 0.0, "reconverged_share": share, "reconverge_periods": periods}


def test_laboratory_cell_beats_only_when_every_move_reconverged_within_10_periods():
    beats = verdict(pd.DataFrame([lab_row("era", 0.001, 1.0, 6.0), lab_row("next_era", 0.01, 0.2, 30.0)]))
    assert "0.1× the error of the naive next_era (beats it:" in beats[0]
    assert "within 10 periods of every move" in beats[0] and "6 periods of the slowest mode" in beats[0]
    slow = verdict(pd.DataFrame([lab_row("era", 0.001, 0.8, 8.0), lab_row("next_era", 0.01, 0.2, 30.0)]))
    assert "(does not beat it:" in slow[0] and "80 % of moves within 10" in slow[0]


def test_nan_percentiles_are_numpys_on_columns_with_and_without_nans():
    import warnings

    from experiments.report.tracking_plots import nan_percentiles

    rng = np.random.default_rng(3)
    a = rng.standard_normal((5, 300, 4))
    a[rng.random(a.shape) < 0.3] = np.nan
    a[:, 7, 2] = np.nan                                  # a column with no value
    a[1:, 8, 1] = np.nan                                 # one value
    for q, got in zip((10, 50, 90, 0, 100), nan_percentiles(a, (10, 50, 90, 0, 100)), strict=True):
        with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
            want = np.nanpercentile(a, q, axis=0)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
        assert np.isnan(got[7, 2]) and got[8, 1] == a[0, 8, 1]
