"""The tracking grid's jobs end to end on a tiny grid, with a stand-in tracker, and their refusals."""

import json

import numpy as np
import pandas as pd
import pytest
import yaml

from experiments.io import read_npz
from experiments.jobs.track_job import hold_on, main
from tests.experiments.jobs import _stand_in_tracker

GRID = {
    "name": "tracking_test", "noise_ug": [100], "duration_s": [8], "replicates": 2, "seed": 7,
    "trackers": ["all"],
    "schedules": {"step": {"step": [0, 0, 0.06, 0], "step_time_s": 4.0}},
    "excitations": {"thrusters": {"thruster_torque_n_m": 100.0, "thruster_period_s": 1.0}},
}


@pytest.fixture
def grid_file(tmp_path, monkeypatch):
    _stand_in_tracker.install(monkeypatch)

    def write(**change):
        path = tmp_path / "tracking_test.yaml"
        path.write_text(yaml.safe_dump({**GRID, **change}))
        return str(path)
    return write


def test_data_then_run_writes_tracks_and_scores(grid_file, tmp_path):
    grid = grid_file()
    main(["data", grid, "--out", str(tmp_path / "data")])
    cell = "step_thrusters_noise100ug_8s"
    data = read_npz(tmp_path / "data" / f"{cell}.npz")
    assert data["accel_m_s2"].shape == (2, 400)
    main(["run", grid, "--tracker", "stand_in", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "t")])
    tracks = read_npz(tmp_path / "t" / f"{cell}.npz")
    assert tracks["frequencies"].shape == (2, 16, 4)
    table = pd.read_csv(tmp_path / "t" / f"{cell}.csv")
    assert list(table["replicate"]) == [0, 1] and set(table["tracker"]) == {"stand_in"}
    assert {"err_rel_median", "t_reconverge_s", "cpu_per_sample_s", "onboard_ok", "diverged"} <= set(table.columns)
    # the stand-in's 2 s periodogram cannot resolve modes 2 and 3 (1.76 rad/s apart): never within 1 %
    assert table["share_within_1pct"].max() < 0.5
    record = json.loads((tmp_path / "t" / f"{cell}.json").read_text())
    assert record["tracker"] == "stand_in" and record["dataset"]["digest"] == str(data["checksum_sha256"])


def test_a_tracker_that_raises_is_recorded_per_record(grid_file, tmp_path):
    grid = grid_file()
    main(["data", grid, "--out", str(tmp_path / "data")])
    main(["run", grid, "--tracker", "broken", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "b")])
    table = pd.read_csv(tmp_path / "b" / "step_thrusters_noise100ug_8s.csv")
    assert table["diverged"].all() and table["message"].str.contains("on purpose").all()
    assert np.isnan(read_npz(tmp_path / "b" / "step_thrusters_noise100ug_8s.npz")["frequencies"]).all()


def test_hold_on_takes_the_latest_estimate_made_at_or_before_each_time():
    dt = 0.1
    t_s = np.array([0.3, 0.7, 1.2])                    # estimates at samples 3, 7, 12
    f = np.array([[1.0], [2.0], [3.0]])
    conv = np.array([[False], [True], [True]])
    t_ref = np.array([0.2, 0.3, 0.5, 0.7000000000000001, 1.1, 1.2, 2.0])
    held_f, held_c = hold_on(t_ref, t_s, dt, f, conv)
    np.testing.assert_array_equal(held_f[:, 0], [np.nan, 1.0, 1.0, 2.0, 2.0, 3.0, 3.0])
    np.testing.assert_array_equal(held_c[:, 0], [False, False, False, True, True, True, True])


def test_replicates_whose_prior_sets_other_times_are_all_scored(grid_file, tmp_path):
    """A tracker whose hop follows the prior reports on other times in each replicate; every replicate is
    scored on the time axis of the one with the most estimates, none thrown away."""
    grid = grid_file()
    main(["data", grid, "--out", str(tmp_path / "data")])
    cell = "step_thrusters_noise100ug_8s"
    data = read_npz(tmp_path / "data" / f"{cell}.npz")
    hops = [_stand_in_tracker.prior_hop(p) for p in data["prior_rad_s"]]
    assert hops[0] != hops[1]                          # the premise: the two replicates' times differ
    main(["run", grid, "--tracker", "prior_hop", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "t")])
    tracks = read_npz(tmp_path / "t" / f"{cell}.npz")
    table = pd.read_csv(tmp_path / "t" / f"{cell}.csv")
    assert (table["message"] == "stand-in").all()        # no replicate set aside for its times
    finest = int(np.argmin(hops))
    np.testing.assert_allclose(tracks["t_s"], np.arange(hops[finest] - 1, 400, hops[finest]) * 0.02)
    own = _stand_in_tracker.track("prior_hop", data["accel_m_s2"][1 - finest], 0.02, data["prior_rad_s"][1 - finest])
    held = tracks["frequencies"][1 - finest]
    k = np.searchsorted(own.t_s, tracks["t_s"] + 1e-12, side="right") - 1
    np.testing.assert_array_equal(held[k >= 0], own.frequencies[k[k >= 0]])
    assert np.isnan(held[k < 0]).all() and np.isfinite(held[k >= 0]).all()


@pytest.mark.parametrize("change, words", [
    ({"schedules": {"bad": {"drift": [0, 0.2, 0, 0]}}}, "crosses modes 2 and 3"),
    ({"schedules": {"bad": {"drift": [0, 0, 0, 2.0]}}}, "Nyquist"),
    ({"excitations": {"none": {}}}, "excitation is empty"),
    ({"noise_ug": [-1]}, "noise_ug"),
    ({"trackers": ["nope"]}, "unknown tracker 'nope'"),
    ({"trackers": ["stand_in", "stand_in:nope"]}, "unknown tracker variant 'stand_in:nope'"),
    ({"trackers": ["stand_in:x-y"]}, "trackers"),
    ({"tracker_options": {"stand_in": {"window_samples": 9}}}, "unknown option 'window_samples'"),
    ({"trackers": ["stand_in"], "tracker_options": {"hdmd": {"hop_samples": 9}}}, "tracker_options.hdmd"),
])
def test_bad_input_is_one_error_line_exit_2_nothing_written(grid_file, tmp_path, capsys, change, words):
    grid = grid_file(**change)
    step = ["run", grid, "--tracker", "stand_in", "--data", str(tmp_path)] if "tracker" in json.dumps(change) else \
        ["data", grid]
    with pytest.raises(SystemExit) as exit_:
        main([*step, "--out", str(tmp_path / "out")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and words in err and "\n" not in err
    assert not (tmp_path / "out").exists()


def test_report_and_mlflow_steps_write_tables_figures_page_and_runs_once(grid_file, tmp_path, monkeypatch):
    import mlflow

    from experiments.report.tracking_report import main as report
    from experiments.runlog.tracker_runs import main as log

    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    grid = grid_file(noise_ug=[100, 1000])
    main(["data", grid, "--out", str(tmp_path / "data")])
    folders = []
    for tracker in ("stand_in", "broken"):
        folders.append(str(tmp_path / "track" / tracker))
        main(["run", grid, "--tracker", tracker, "--data", str(tmp_path / "data"), "--out", folders[-1]])
    out = tmp_path / "res"
    report(["--grid", grid, "--data", str(tmp_path / "data"), "--out", str(out), "--page", str(out / "summary.md"),
            "--", *folders])
    table = pd.read_csv(out / "tables" / "tracking_table.csv")
    assert len(table) == 2 * 2 and set(table["tracker"]) == {"stand_in", "broken"}
    assert (table.loc[table["tracker"] == "broken", "diverged_rate"] == 1.0).all()
    for fig in ("tracking_estimates_step", "tracking_error_vs_time", "tracking_reconvergence",
                "tracking_accuracy_vs_cpu"):
        assert (out / "figures" / f"{fig}.png").stat().st_size > 10_000
        assert "category" not in (out / "figures" / f"{fig}.rst").read_text()     # the caption body only
    assert "## Verdict per cell" in (out / "summary.md").read_text()
    args = ["--grid", "tracking_test", "--out", str(out / "mlflow_runs.json"), "--summary", str(out / "summary.md"),
            "--page", str(out / "README.md"), "--aggregate", str(out / "tables"), "--", *folders]
    # the (tracker, cell) runs first, as the workflow logs them beside the report, then the grid's run
    log(["--grid", "tracking_test", "--jobs-only", "--out", str(out / "runlog" / "jobs.json"), "--", *folders])
    jobs = json.loads((out / "runlog" / "jobs.json").read_text())["runs"]
    log(args)
    log(args)                                                    # again: nothing new
    client = mlflow.MlflowClient(f"sqlite:///{tmp_path / 'mlflow.db'}")
    exp = client.get_experiment_by_name("grid-tracking_test")
    runs = client.search_runs([exp.experiment_id])
    assert len(runs) == 1 + 2 * 2
    parent = json.loads((out / "mlflow_runs.json").read_text())["parent_run"]
    children = {r.data.tags["run_key"]: r for r in runs if r.data.tags["kind"] == "job"}
    assert {k: r.info.run_id for k, r in children.items()} == jobs
    assert all(r.data.tags["mlflow.parentRunId"] == parent for r in children.values())
    assert "## Tracking" in (out / "README.md").read_text()


def test_the_data_step_on_two_processes_writes_the_same_bytes(grid_file, tmp_path, capsys):
    grid = grid_file(noise_ug=[100, 1000])
    main(["data", grid, "--out", str(tmp_path / "one")])
    main(["data", grid, "--out", str(tmp_path / "two"), "--workers", "2"])
    assert "2 cells on 2 processes" in capsys.readouterr().out
    files = sorted(p.name for p in (tmp_path / "one").glob("*.npz"))
    assert len(files) == 2 and files == sorted(p.name for p in (tmp_path / "two").glob("*.npz"))
    assert all((tmp_path / "one" / f).read_bytes() == (tmp_path / "two" / f).read_bytes() for f in files)
    with pytest.raises(SystemExit) as exit_:
        main(["data", grid, "--out", str(tmp_path / "none"), "--workers", "0"])
    assert exit_.value.code == 2 and "--workers = 0" in capsys.readouterr().err
    assert not (tmp_path / "none").exists()


def test_score_step_scores_stored_tracks_again_identically(grid_file, tmp_path):
    grid = grid_file()
    main(["data", grid, "--out", str(tmp_path / "data")])
    args = ["--tracker", "stand_in", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "t")]
    main(["run", grid, *args])
    first = pd.read_csv(tmp_path / "t" / "step_thrusters_noise100ug_8s.csv")
    main(["score", grid, *args])
    again = pd.read_csv(tmp_path / "t" / "step_thrusters_noise100ug_8s.csv")
    pd.testing.assert_frame_equal(first, again)


def test_a_variant_runs_under_its_label_with_its_options(grid_file, tmp_path, monkeypatch):
    """``hdmd:fast`` beside ``all``: its file's options reach the check (a bad one is refused naming the
    variant) and the run, and its rows carry the label."""
    from experiments import tracker_variants

    monkeypatch.setattr(tracker_variants, "VARIANT_DIR", tmp_path / "tracker")
    (tmp_path / "tracker").mkdir()
    (tmp_path / "tracker" / "hdmd_fast.yaml").write_text("tracker: hdmd\nvariant: fast\noptions: {hop_samples: 50}\n")
    grid = grid_file(trackers=["all", "hdmd:fast"])
    main(["data", grid, "--out", str(tmp_path / "data")])
    main(["run", grid, "--tracker", "hdmd:fast", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "v")])
    table = pd.read_csv(tmp_path / "v" / "step_thrusters_noise100ug_8s.csv")
    assert set(table["tracker"]) == {"hdmd:fast"}
    record = json.loads((tmp_path / "v" / "step_thrusters_noise100ug_8s.json").read_text())
    assert record["options"] == {"hop_samples": 50}
    (tmp_path / "tracker" / "hdmd_fast.yaml").write_text("tracker: hdmd\nvariant: fast\noptions: {nope: 1}\n")
    with pytest.raises(SystemExit):
        main(["run", grid, "--tracker", "hdmd:fast", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "w")])
    assert not (tmp_path / "w").exists()


def test_a_tracker_excluded_from_a_cell_runs_and_scores_again_without_it(grid_file, tmp_path):
    # exclude: {tracker, schedule}: the run step writes no track of that cell, and the score step does not ask
    # for one (it used to refuse: "no tracks of cell ...")
    grid = grid_file(schedules={"step": {"step": [0, 0, 0.06, 0], "step_time_s": 4.0}, "still": {}},
                     exclude=[{"tracker": "stand_in", "schedule": "still"}])
    main(["data", grid, "--out", str(tmp_path / "data")])
    assert len(list((tmp_path / "data").glob("*.npz"))) == 2
    run = ["--tracker", "stand_in", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "t")]
    main(["run", grid, *run])
    assert sorted(p.stem for p in (tmp_path / "t").glob("*.npz")) == ["step_thrusters_noise100ug_8s"]
    before = (tmp_path / "t" / "step_thrusters_noise100ug_8s.csv").read_text()
    main(["score", grid, *run])
    assert (tmp_path / "t" / "step_thrusters_noise100ug_8s.csv").read_text() == before
