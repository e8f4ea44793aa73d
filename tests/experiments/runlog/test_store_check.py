"""A damaged MLflow store is refused in one line before any work, and never silently rebuilt."""

from __future__ import annotations

import sqlite3
import subprocess
import sys

import pytest

from experiments.runlog.store import check_store


def _real_store(path):
    """An SQLite database of several pages, as a store that held runs is."""
    with sqlite3.connect(path) as db:
        db.execute("CREATE TABLE runs (id INTEGER PRIMARY KEY, payload TEXT)")
        db.executemany("INSERT INTO runs (payload) VALUES (?)", [("x" * 500,)] * 400)
    return path


def test_a_sound_store_and_a_missing_one_pass(tmp_path):
    check_store(f"sqlite:///{_real_store(tmp_path / 'mlflow.db')}")
    check_store(f"sqlite:///{tmp_path / 'not-yet.db'}")        # created on first use
    check_store("http://127.0.0.1:5000")                        # a server is not checked here


@pytest.mark.parametrize("damage, words", [
    (lambda p: p.write_bytes(b""), "is empty (0 bytes)"),
    (lambda p: p.write_bytes(p.read_bytes()[: p.stat().st_size // 2]), "is truncated"),
    (lambda p: p.write_bytes(b"not a database at all" * 10), "not an SQLite database"),
])
def test_an_empty_truncated_or_foreign_store_is_one_line_naming_it_and_the_way_out(tmp_path, damage, words):
    path = _real_store(tmp_path / "mlflow.db")
    damage(path)
    before = path.read_bytes()
    with pytest.raises(ValueError) as err:
        check_store(f"sqlite:///{path}")
    message = str(err.value)
    assert words in message and str(path) in message and "runlog.enabled=false" in message
    assert "\n" not in message
    assert path.read_bytes() == before                          # left as it was, never rebuilt


def test_a_page_damaged_inside_is_caught_by_sqlites_own_check(tmp_path):
    path = _real_store(tmp_path / "mlflow.db")
    data = bytearray(path.read_bytes())
    page = int.from_bytes(data[16:18], "big")
    data[2 * page: 2 * page + 64] = b"\xff" * 64                 # a b-tree page header overwritten
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="corrupt|cannot be read"):
        check_store(f"sqlite:///{path}")


def test_the_track_step_refuses_a_truncated_store_in_one_line(tmp_path):
    path = _real_store(tmp_path / "mlflow.db")
    path.write_bytes(path.read_bytes()[:4096])
    proc = subprocess.run([sys.executable, "-m", "experiments.runlog.identify_runs", "--grid", "g", "--out",
                           str(tmp_path / "runs.json"), str(tmp_path / "x.csv")],
                          capture_output=True, text=True, env={"MLFLOW_TRACKING_URI": f"sqlite:///{path}",
                                                               "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: the MLflow store") and proc.stderr.count("\n") == 1
    assert not (tmp_path / "runs.json").exists()


@pytest.mark.parametrize("content, words", [
    ("a,b\n1,2\n", "not an identify job's result table (no column method"),
    (None, "no such result table"),
    (b"\x8f\x00binary", "not a CSV result table"),
    ("", "not a CSV result table (no header line)"),
])
def test_the_track_step_refuses_a_file_that_is_no_job_table_in_one_line(tmp_path, content, words):
    table = tmp_path / "x.csv"
    if isinstance(content, str):
        table.write_text(content)
    elif content is not None:
        table.write_bytes(content)
    proc = subprocess.run([sys.executable, "-m", "experiments.runlog.identify_runs", "--grid", "g", "--out",
                           str(tmp_path / "runs.json"), str(table)], capture_output=True, text=True,
                          env={"MLFLOW_TRACKING_URI": f"sqlite:///{tmp_path / 'm.db'}", "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and words in proc.stderr, proc.stderr
    assert not (tmp_path / "runs.json").exists() and not (tmp_path / "m.db").exists()
