"""A benchmark command writes what it printed to its generated page, and nothing when it fails."""

from __future__ import annotations

import pytest

from experiments.benchmarks import run_with_page


def table_main(argv):
    print("| N | ms |")
    print("|---|---|")
    print(f"| 256 | {len(argv)} |")


def text_main(argv):
    print(" samples  ms/record")
    print("     256       0.90")
    return 0


def test_page_holds_the_command_and_the_printed_table(tmp_path, capsys):
    assert run_with_page(table_main, "demo", ["--repeats", "3"], page_dir=tmp_path) == 0
    page = (tmp_path / "demo.md").read_text()
    assert "`python -m experiments.benchmarks.demo --repeats 3`" in page
    assert "UTC, commit " in page and "load average" in page
    assert "| 256 | 2 |\n" in page and "```" not in page          # a Markdown table stays a table
    assert "| 256 | 2 |" in capsys.readouterr().out               # and is still printed


def test_plain_text_output_is_fenced(tmp_path):
    run_with_page(text_main, "demo", [], page_dir=tmp_path)
    page = (tmp_path / "demo.md").read_text()
    assert "```\n samples  ms/record\n     256       0.90\n```\n" in page


def test_a_failed_run_writes_no_page(tmp_path):
    assert run_with_page(lambda argv: 2, "demo", [], page_dir=tmp_path) == 2

    def refused(argv):
        raise SystemExit("seed 20261121 is the grid's scoring seed")

    with pytest.raises(SystemExit):
        run_with_page(refused, "demo", [], page_dir=tmp_path)
    assert not list(tmp_path.iterdir())


def test_a_benchmark_started_by_another_writes_no_page_of_its_own(tmp_path):
    def parent(argv):
        run_with_page(table_main, "child", [], page_dir=tmp_path)

    run_with_page(parent, "parent", [], page_dir=tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["parent.md"]
    assert "| 256 | 0 |" in (tmp_path / "parent.md").read_text()    # the child's output is on the parent's page
