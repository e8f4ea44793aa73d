"""The cell classes, their winners and the Pareto front (experiments/report/pareto.py) on a hand-made
summary whose answers are known; the figure is written for a summary with several classes."""

import numpy as np
import pandas as pd

from experiments.report import pareto


def summary_row(method, noise, n, ratio, failure, runtime, identifiable=True):
    return dict(method=method, noise_ug=noise, n_samples=n, mode=1, rmse_over_crlb=ratio,
                failure_rate=failure, median_runtime_s=runtime, identifiable=identifiable)


def summary():
    rows = []
    for noise, n in ((1.0, 64), (1000.0, 64), (1.0, 256), (1000.0, 256)):
        rows += [summary_row("slow_exact", noise, n, 1.0, 0.0, 0.1),
                 summary_row("fast_ok", noise, n, 1.5, 0.0, 0.001),
                 summary_row("accurate_but_fails", noise, n, 0.9, 0.3, 0.01),
                 summary_row("dominated", noise, n, 2.0, 0.0, 0.2),
                 summary_row("dominated", noise, n, 99.0, 0.0, 0.2, identifiable=False)]
    return pd.DataFrame(rows)


def test_classes_split_at_128_samples_and_100_ug():
    got = pareto.cell_class([20, 127, 128, 2048], [100.0, 100.1, 0.1, 1e5])
    assert got.tolist() == ["short, low noise", "short, high noise", "long, low noise", "long, high noise"]


def test_the_winner_is_the_most_accurate_method_failing_at_most_ten_percent():
    table = pareto.class_table(summary())
    assert set(table["cell_class"]) == set(pareto.CLASSES)
    winners = table[table["winner"]]
    assert len(winners) == 4 and set(winners["method"]) == {"slow_exact"}
    # a pair that is not identifiable does not enter the median
    assert np.allclose(table.loc[table["method"] == "dominated", "median_rmse_over_crlb"], 2.0)
    assert np.allclose(table.loc[table["method"] == "fast_ok", "median_ms_per_fit"], 1.0)


def test_front_keeps_only_the_undominated():
    table = pareto.class_table(summary())
    one = table[(table["cell_class"] == "long, high noise") & (table["mean_failure_rate"] <= 0.1)]
    assert pareto.pareto_front(one)["method"].tolist() == ["fast_ok", "slow_exact"]
    assert "slow_exact 1.00× the bound" in pareto.winners_text(table)


def test_figure_is_written(tmp_path):
    files = pareto.figure(pareto.class_table(summary()), tmp_path / "pareto")
    assert [f.suffix for f in files] == [".png", ".svg"] and all(f.stat().st_size > 0 for f in files)
