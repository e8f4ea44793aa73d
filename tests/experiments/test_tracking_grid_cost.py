"""The tracking grid's wall-time prediction from a finished run's logs (``tracking_grid_cost --run``)."""

import pytest

from experiments.benchmarks.tracking_grid_cost import main, predict_run, run_costs
from experiments.cli import cpu_line, read_cpu_line


def _run(tmp_path):
    logs = tmp_path / "logs"
    (logs / "track").mkdir(parents=True)
    (logs / "data.log").write_text("cell 1 of 2 (a) in 20 s CPU\n2 cells on 2 processes\ntotal: 40.000 s CPU (x)\n")
    for name, cpu in (("a", 100), ("b", 60), ("c", 50)):
        (logs / "track" / f"{name}.log").write_text(f"{name}: cell 1 of 1 (a) in {cpu - 3} s CPU\n"
                                                    f"total: {cpu}.000 s CPU (x)\n")
    (logs / "track" / "d.log").write_text("killed before the end\n")                 # no CPU line: left out
    for name, cpu in (("report", 30), ("runlog_jobs", 20), ("runlog", 5)):
        (logs / f"{name}.log").write_text(f"total: 1.000 s CPU\nlater\ntotal: {cpu}.000 s CPU (x)\n")
    return tmp_path


def test_each_steps_cpu_is_its_logs_last_cpu_line(tmp_path):
    assert run_costs(_run(tmp_path)) == {"data": 40.0, "track/a": 100.0, "track/b": 60.0, "track/c": 50.0,
                                         "report": 30.0, "runlog_jobs": 20.0, "runlog": 5.0}
    assert read_cpu_line(cpu_line()) >= 0 and read_cpu_line("no such line") is None


def test_the_wall_time_places_the_trackers_longest_first_and_the_report_beside_the_job_runs(tmp_path):
    costs = run_costs(_run(tmp_path))
    two = predict_run(costs, cores=2, data_workers=2)
    # records 40/2; trackers 100 | 60 + 50; report 30 beside the job runs 20; the grid's run 5
    assert two["data"] == 20 and two["trackers"] == 110 and two["report and job runs"] == 30
    assert two["wall"] == pytest.approx(20 + 110 + 30 + 5) and two["cpu"] == 305
    one = predict_run(costs, cores=1, data_workers=2)
    assert one["wall"] == pytest.approx(305)


def test_the_command_prints_the_prediction_and_refuses_a_folder_without_a_run(tmp_path, capsys):
    assert main(["--run", str(_run(tmp_path / "run")), "--cores", "2"]) == 0
    assert "**165 s (2.8 min)**" in capsys.readouterr().out
    assert main(["--run", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --run") and err.count("\n") == 1
