"""The white-force benchmark's summary (experiments.benchmarks.tracking_ambient.summary) on a hand-made table:
the ratios are the table's own numbers, and a replicate that never re-converged counts in a step cell's median."""

import math

import numpy as np
import pandas as pd
import pytest

from experiments.benchmarks.tracking_ambient import summary


def _row(cell, tracker, r, err_30, t_re, has_step):
    return {"cell": cell, "tracker": tracker, "r": r, "err": err_30, "err_30": err_30, "bound_30": 0.002,
            "rbound_30": 0.004 if cell == "drift" else math.nan, "t_reconverge_s": t_re, "has_step": has_step,
            "cover_1sigma": 0.7, "us_per_sample": 100.0}


def test_summary_ratios_and_a_never_reconverged_replicate():
    rows = [_row("step", "next_era", 0, 0.010, 30.0, True), _row("step", "next_era", 1, 0.012, 40.0, True),
            _row("step", "x", 0, 0.004, 12.0, True), _row("step", "x", 1, 0.006, math.nan, True),
            _row("drift", "next_era", 0, 0.008, math.nan, False), _row("drift", "next_era", 1, 0.008, math.nan, False),
            _row("drift", "x", 0, 0.002, math.nan, False), _row("drift", "x", 1, 0.002, math.nan, False)]
    s = summary(pd.DataFrame(rows)).set_index(["cell", "tracker"])
    assert s.loc[("step", "x"), "x_next_era"] == pytest.approx(0.005 / 0.011)
    assert s.loc[("step", "x"), "x_bound"] == pytest.approx(2.5)
    assert s.loc[("step", "next_era"), "t_reconverge_s"] == pytest.approx(35.0)
    assert s.loc[("step", "x"), "t_reconverge_s"] == math.inf       # 12 s and never: never, not 12 s
    assert np.isnan(s.loc[("drift", "x"), "t_reconverge_s"])        # no step: no re-convergence
    assert s.loc[("drift", "x"), "x_rbound"] == pytest.approx(0.5)  # × the unknown-rate bound, drifts only
    assert np.isnan(s.loc[("step", "x"), "x_rbound"])
