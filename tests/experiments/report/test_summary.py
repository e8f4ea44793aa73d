import numpy as np
import pandas as pd
import pytest

from experiments.report.scoring import COLUMNS, identifiable
from experiments.report.summary import job_metrics, summarize


def table(errors, converged, crlb=0.5, true=10.0, runtimes=None, stds=None):
    stds = [np.nan] * len(errors) if stds is None else stds
    rows = []
    for r, (e, c) in enumerate(zip(errors, converged, strict=True)):
        rows.append(dict(method="m", noise_ug=1.0, n_samples=64, replicate=r, mode=1, prior_rad_s=9.0,
                         true_rad_s=true, estimate_rad_s=true + e if c else np.nan, std_rad_s=stds[r],
                         error_rad_s=e if c else np.nan, crlb_std_rad_s=crlb, crlb_offset_std_rad_s=2 * crlb,
                         identifiable=True, converged=c,
                         iterations=1, runtime_s=(runtimes or [0.1] * len(errors))[r], message=""))
    return pd.DataFrame(rows, columns=COLUMNS)


def test_summary_statistics_on_known_errors():
    s = summarize(table([1.0, -1.0, 3.0, 0.0], [True, True, True, False], runtimes=[1, 2, 3, 10])).iloc[0]
    assert s["replicates"] == 4 and s["failures"] == 1
    assert s["failure_rate"] == pytest.approx(0.25)
    assert s["bias_rad_s"] == pytest.approx(1.0)
    assert s["std_rad_s"] == pytest.approx(2.0)                   # std of (1, -1, 3) with ddof=1
    assert s["rmse_rad_s"] == pytest.approx(np.sqrt(11 / 3))
    assert s["rmse_over_crlb"] == pytest.approx(np.sqrt(11 / 3) / 0.5)
    assert s["rmse_over_crlb_offset"] == pytest.approx(np.sqrt(11 / 3) / 1.0)
    assert s["median_runtime_s"] == pytest.approx(2.5)


def test_all_failed_cell_has_nan_accuracy_and_full_failure_rate():
    s = summarize(table([0.0, 0.0], [False, False])).iloc[0]
    assert s["failure_rate"] == 1.0
    assert np.isnan(s["rmse_rad_s"]) and np.isnan(s["rmse_over_crlb"])


def test_job_metrics_are_flat_per_mode():
    m = job_metrics(summarize(table([1.0, -1.0], [True, True])))
    assert m["mode1_rmse_rad_s"] == pytest.approx(1.0)
    assert m["mode1_bias_rad_s"] == pytest.approx(0.0)
    assert m["failure_rate"] == 0.0


def test_identifiability_rule_uses_one_percent_and_tenth_of_spacing():
    true = np.array([3.23, 20.24, 22.00, 56.67])
    ok = identifiable(true, np.array([0.03, 0.17, 0.18, 0.5]))
    assert ok.tolist() == [True, True, False, True]                # 0.18 > 0.176 = 10 % of 1.76
    assert not identifiable(true, np.array([0.033, 0.1, 0.1, 0.1]))[0]   # 0.033 > 1 % of 3.23


def test_summary_rows_carry_coverage_of_the_reported_std():
    # z = |e|/σ over converged replicates with a usable σ: 0.5, 1.0 (on the edge: inside), 3.0; the failed
    # replicate and the one without a std are not counted.
    s = summarize(table([0.5, -2.0, 3.0, 0.0, 1.0], [True, True, True, False, True],
                        stds=[1.0, 2.0, 1.0, 1.0, np.nan])).iloc[0]
    assert s["n_with_std"] == 3
    assert s["coverage_1std"] == pytest.approx(2 / 3)
    assert s["coverage_2std"] == pytest.approx(2 / 3)
    assert s["median_abs_err_over_std"] == pytest.approx(1.0)


def test_a_method_without_std_has_nan_coverage():
    s = summarize(table([1.0, -1.0], [True, True])).iloc[0]
    assert s["n_with_std"] == 0 and np.isnan(s["coverage_1std"]) and np.isnan(s["median_abs_err_over_std"])
