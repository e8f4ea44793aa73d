"""Coverage of a reported std: hand-made errors, and Gaussian errors with a right and a wrong σ."""

import numpy as np
import pandas as pd
import pytest

from experiments.report.coverage import IDEAL_1STD, IDEAL_2STD, IDEAL_MEDIAN_Z, coverage, method_coverage


def test_coverage_on_hand_made_errors():
    # |e|/σ = 0.5, 0.9, 1.5, 2.5, 0.5, 4.0 -> 3 of 6 within 1σ, 4 of 6 within 2σ, median (0.9 + 1.5)/2
    c = coverage([0.5, -0.9, 1.5, -2.5, 0.1, 4.0, 1.0, 1.0], [1, 1, 1, 1, 0.2, 1, np.nan, 0.0])
    assert c["n_with_std"] == 6                           # NaN and zero std skipped
    assert c["coverage_1std"] == pytest.approx(3 / 6)
    assert c["coverage_2std"] == pytest.approx(4 / 6)
    assert c["median_abs_err_over_std"] == pytest.approx(1.2)


def test_no_std_gives_nan():
    c = coverage([0.1, 0.2], [np.nan, np.nan])
    assert c["n_with_std"] == 0 and np.isnan(c["coverage_1std"]) and np.isnan(c["coverage_2std"])


def test_ideal_values_are_the_normal_ones():
    assert IDEAL_1STD == pytest.approx(0.6827, abs=1e-4)
    assert IDEAL_2STD == pytest.approx(0.9545, abs=1e-4)
    assert IDEAL_MEDIAN_Z == pytest.approx(0.6745, abs=1e-4)


def results(method, errors, stds, converged=True, mode=1, n_samples=64):
    return pd.DataFrame({"method": method, "noise_ug": 1.0, "n_samples": n_samples, "mode": mode,
                         "error_rad_s": errors, "std_rad_s": stds, "converged": converged})


def test_gaussian_errors_with_the_right_std_are_honest_and_a_halved_std_is_not():
    rng = np.random.default_rng(7)                     # not the scoring seed
    sigma = rng.uniform(0.01, 2.0, 2000)
    err = sigma * rng.standard_normal(sigma.size)
    table = pd.concat([results("right", err, sigma), results("half", err, sigma / 2),
                       results("double", err, 2 * sigma), results("none", err, np.nan)])
    cov = method_coverage(table).set_index("method")
    assert cov.loc["right", "coverage_1std"] == pytest.approx(IDEAL_1STD, abs=0.04)
    assert cov.loc["right", "coverage_2std"] == pytest.approx(IDEAL_2STD, abs=0.02)
    assert cov.loc["right", "median_abs_err_over_std"] == pytest.approx(IDEAL_MEDIAN_Z, abs=0.05)
    assert cov.loc["right", "verdict"] == "consistent with its errors"
    assert cov.loc["half", "coverage_1std"] == pytest.approx(0.383, abs=0.04)     # P(|z| ≤ 1/2)
    assert cov.loc["half", "verdict"].startswith("std understated")
    assert cov.loc["double", "verdict"].startswith("std overstated")
    assert cov.loc["none", "verdict"] == "reports no std" and cov.loc["none", "n_with_std"] == 0


def test_pool_is_restricted_to_the_given_cells_and_converged_replicates():
    table = pd.concat([results("m", [0.1, 0.1], [1.0, 1.0]),
                       results("m", [5.0, 5.0], [1.0, 1.0], mode=2),                # not in the pool
                       results("m", [5.0], [1.0], converged=False)])               # failed: not counted
    cells = pd.DataFrame({"method": ["m"], "noise_ug": [1.0], "n_samples": [64], "mode": [1]})
    cov = method_coverage(table, cells).iloc[0]
    assert cov["n_with_std"] == 2 and cov["coverage_1std"] == 1.0


def test_few_pairs_all_inside_one_sigma_are_not_called_overstated():
    # 6 of 6 within 1σ happens with probability 0.683^6 = 0.10 for an honest std: no verdict against it
    cov = method_coverage(results("m", [0.1] * 6, [1.0] * 6)).iloc[0]
    assert cov["verdict"].startswith("consistent") and "weak evidence" in cov["verdict"]
