"""The mismatch benchmark runs a grid end to end and refuses a bad axis in one line."""

import pandas as pd
import pytest

from experiments.benchmarks import mismatch

GRID = """name: tiny
noise_ug: [1000]
n_samples: [256]
replicates: 2
seed: 3
dt_s: 0.02
methods: [pem]
scenarios:
  - {}
  - ar1: [0.9]
  - duffing: [-0.01]
"""


def test_scores_every_cell_with_pems_stds_side_by_side(tmp_path):
    (tmp_path / "grid.yaml").write_text(GRID)
    mismatch.main(["--grid", str(tmp_path / "grid.yaml"), "--out", str(tmp_path)])
    table = pd.read_csv(tmp_path / "coverage.csv", dtype={"value": str})
    assert set(table["axis"]) == {"none", "ar1", "duffing"}
    assert {"reported", "white", "robust", "before"} <= set(table["std"])
    ar1 = table[(table["axis"] == "ar1") & (table["std"] == "reported")].iloc[0]
    assert ar1["flagged"] == 1.0                # AR(1) noise of φ = 0.9 never passes for white
    plain = table[(table["axis"] == "none") & (table["std"] == "reported")].iloc[0]
    before = table[(table["axis"] == "none") & (table["std"] == "before")].iloc[0]
    assert plain["coverage_1std"] == before["coverage_1std"]       # white records: the std of before


def test_a_bad_axis_value_is_one_error_line(tmp_path, capsys):
    (tmp_path / "grid.yaml").write_text(GRID.replace("ar1: [0.9]", "ar1: [1.5]"))
    with pytest.raises(SystemExit) as stop:
        mismatch.main(["--grid", str(tmp_path / "grid.yaml"), "--out", str(tmp_path)])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "ar1 = 1.5" in err[0]
    assert not (tmp_path / "coverage.csv").exists()
