"""The sweep's cost model (experiments/benchmarks/sweep_cost.py): scheduling, prediction, refusals."""

import numpy as np
import pytest

from experiments.benchmarks import sweep_cost


def test_longest_first_on_two_cores_matches_a_hand_schedule():
    # by hand, each job to the least loaded core: 7 -> A (7); 5 -> B (5); 4 -> B (9); 3 -> A (10); 3 -> B (12)
    jobs = {"a": 7.0, "b": 5.0, "c": 4.0, "d": 3.0, "e": 3.0}
    assert sweep_cost.makespan(jobs, 2) == pytest.approx(12.0)
    assert sweep_cost.makespan(jobs, 1) == pytest.approx(22.0)
    assert sweep_cost.makespan(jobs, 8) == pytest.approx(7.0)        # one job per core: the longest


def test_prediction_sums_replicates_cells_and_start_up():
    grid = {"replicates": 10}
    fits = {("x", 1, 64): 0.01, ("x", 10, 64): 0.03, ("y", 1, 64): 0.5, ("y", 10, 64): 0.5}
    pred = sweep_cost.predict(grid, fits, {(1, 64): 0.2, (10, 64): 0.3}, {"x": 1.0, "y": 2.0}, cores=2)
    assert pred["batch_cpu_s"] == pytest.approx({"x": 1.0 + 10 * 0.04, "y": 2.0 + 10 * 1.0})
    assert pred["data_s"] == pytest.approx(0.5)
    assert pred["wall_s"] == pytest.approx(0.5 + 12.0)                # the two batches side by side
    assert pred["bound_s"] == pytest.approx(0.5 + max(13.4 / 2, 12.0))


def test_a_grid_with_scenario_cells_or_a_missing_file_is_refused(tmp_path):
    with pytest.raises(ValueError, match="no file"):
        sweep_cost.load_grid(str(tmp_path / "nope.yaml"))
    bad = tmp_path / "bad.yaml"
    bad.write_text("noise_ug: [1]\nn_samples: [64]\nreplicates: 2\nseed: 1\nmethods: [fft]\ncells: {a: 1}\n")
    with pytest.raises(ValueError, match="scenario cells"):
        sweep_cost.load_grid(str(bad))
    assert sweep_cost.main(["--grid", str(bad)]) == 2


def test_one_cell_is_timed_for_every_entry_and_written(tmp_path, monkeypatch):
    # the entries' configs composed by Hydra as the identify job does; the CSV written under ROOT/results
    grid = tmp_path / "g.yaml"
    grid.write_text("name: g\nnoise_ug: [100]\nn_samples: [64]\nreplicates: 3\nseed: 5\nmethods: [fft, pem]\n")
    monkeypatch.setattr(sweep_cost, "ROOT", tmp_path)
    assert sweep_cost.main(["--grid", str(grid), "--no-startup"]) == 0
    rows = (tmp_path / "results" / "bench" / "sweep_cost" / "g.csv").read_text().splitlines()
    assert rows[0] == "entry,noise_ug,n_samples,cpu_s_per_fit,replicates"
    assert sorted(r.split(",")[0] for r in rows[1:]) == ["fft", "pem"]
    assert all(float(r.split(",")[3]) > 0 and np.isfinite(float(r.split(",")[3])) for r in rows[1:])
