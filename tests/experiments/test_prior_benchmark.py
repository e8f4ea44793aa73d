"""experiments.benchmarks.prior: the yardstick's convergence check runs end to end; bad input is refused."""

from __future__ import annotations

from experiments.benchmarks import prior


def test_yardstick_part_writes_its_table(tmp_path):
    out = tmp_path / "yard.md"
    assert prior.main(["--part", "yardstick", "--records", "2", "--draws", "20", "--n-samples", "20",
                       "--noise-ug", "1000", "--out", str(out)]) == 0
    rows = [line for line in out.read_text().splitlines() if line.startswith("| 1000 | 20 |")]
    assert len(rows) == 4                                          # one per mode
    cells = rows[3].split("|")[4:8]                                # mode 4: four finite posterior-mean RMSEs
    assert all(float(c) > 0 for c in cells)


def test_scoring_seed_and_bad_sizes_are_refused(tmp_path, capsys):
    out = tmp_path / "x.md"
    assert prior.main(["--part", "yardstick", "--seed", str(prior.SCORING_SEED), "--out", str(out)]) == 2
    assert prior.main(["--part", "yardstick", "--records", "1", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert all(line.startswith("error:") for line in err) and len(err) == 2
    assert not out.exists()
