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


def test_the_sampled_column_runs_and_a_bad_draw_count_is_refused(tmp_path, capsys):
    out = tmp_path / "map.md"
    assert prior.main(["--records", "2", "--draws", "20", "--n-samples", "20", "--noise-ug", "1000",
                       "--posterior-draws", "32", "--out", str(out)]) == 0
    lines = out.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if "| sampled RMSE |" in line)
    row = lines[head + 2]                                          # the sampled table's one cell
    assert row.startswith("| 1000 | 20 |")
    sampled = [float(v) for v in row.split("|")[5].split(",")]
    assert len(sampled) == 4 and all(v > 0 for v in sampled)
    capsys.readouterr()
    bad = tmp_path / "bad.md"
    assert prior.main(["--posterior-draws", "-1", "--out", str(bad)]) == 2
    assert capsys.readouterr().err.strip() == "error: --posterior-draws -1 must be in 0…100000"
    assert not bad.exists()
