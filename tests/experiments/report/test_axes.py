"""Scenario columns in the summary, the success (basin) criterion, and the axis/basin figures."""

import numpy as np
import pandas as pd
import pytest

from experiments.report import axes
from experiments.report.scoring import COLUMNS
from experiments.report.success import mode_success, success_rates, tolerance
from experiments.report.summary import summarize


def table(errors, converged):
    return pd.DataFrame([dict(method="m", noise_ug=1.0, n_samples=64, replicate=r, mode=1, prior_rad_s=9.0,
                              true_rad_s=10.0, estimate_rad_s=10.0 + e, std_rad_s=np.nan, error_rad_s=e,
                              crlb_std_rad_s=0.5, crlb_offset_std_rad_s=1.0, identifiable=True, converged=c,
                              iterations=1, runtime_s=0.1, message="")
                         for r, (e, c) in enumerate(zip(errors, converged, strict=True))], columns=COLUMNS)


def test_scenario_cells_stay_apart_in_the_summary_and_plain_cells_keep_nan_axes():
    plain = table([1.0, -1.0], [True, True])
    scaled = table([3.0, 3.0], [True, True]).assign(prior_scale=0.8)
    s = summarize(pd.concat([plain, scaled], ignore_index=True))
    assert len(s) == 2
    assert s.loc[s["prior_scale"].isna(), "rmse_rad_s"].item() == pytest.approx(1.0)
    assert s.loc[s["prior_scale"] == 0.8, "rmse_rad_s"].item() == pytest.approx(3.0)
    assert "prior_scale" not in summarize(plain).columns     # a plain grid's table is unchanged


def test_success_tolerance_is_five_sigma_floored_and_capped_by_the_neighbour():
    w = np.array([10.0, 20.0, 20.3])
    tol = tolerance(w, np.array([0.001, 0.5, 0.001]))
    # 5σ = 0.005 < 0.5 % of 10 = 0.05; 5σ = 2.5 capped at half the 0.3 gap; floor 0.1015 capped at 0.15
    np.testing.assert_allclose(tol, [0.05, 0.15, 0.1015])
    ok = mode_success(w, [0.001, 0.5, 0.001], [10.04, 20.3, 20.3], [True, True, True])
    np.testing.assert_array_equal(ok, [True, False, True])   # mode 2 on its neighbour: a local minimum
    assert not mode_success(w, [0.001] * 3, [10.0, 20.0, np.nan], [True] * 3)[2]


def _results(methods_rates):
    rows = []
    for method, scale, hits in methods_rates:
        for r, hit in enumerate(hits):
            for mode, w in ((1, 10.0), (2, 30.0)):
                est = w if hit else w * 1.1
                rows.append(dict(method=method, noise_ug=1.0, n_samples=64, replicate=r, mode=mode,
                                 true_rad_s=w, estimate_rad_s=est, error_rad_s=est - w, crlb_std_rad_s=0.01,
                                 crlb_offset_std_rad_s=0.01, converged=True, identifiable=True,
                                 prior_scale=scale, runtime_s=0.1, std_rad_s=np.nan))
    return pd.DataFrame(rows)


def test_success_rates_and_basin_edges_on_a_known_case(tmp_path):
    res = _results([("a", 0.8, [1, 0, 0, 0]), ("a", 1.0, [1, 1, 1, 1]), ("a", 1.2, [1, 1, 1, 0]),
                    ("b", 0.8, [1, 1, 1, 1]), ("b", 1.0, [1, 1, 1, 1]), ("b", 1.2, [1, 1, 1, 1])])
    rates = success_rates(res, ["method", "prior_scale"])
    assert rates["success_rate"].tolist() == [0.25, 1.0, 0.75, 1.0, 1.0, 1.0]
    edges = axes.basin_edges(rates).set_index("method")["c with success ≥ 90 %"]
    assert edges["a"] == "1 … 1" and edges["b"] == "0.8 … 1.2"
    files = axes.basin_figure(rates, tmp_path / "basin")
    assert files[0].stat().st_size > 10_000
