"""The aggregate on a small hand-made results table: coverage in the tables and headline, HTML tables, a
caption beside every figure and table (anyone's), and the paper reproductions' tables as one HTML page."""

import numpy as np
import pandas as pd

from experiments.report import aggregate
from experiments.report.scoring import COLUMNS

TRUE = [3.23, 20.24, 22.0, 56.67]


def results_csv(path, method="pem", std_scale=1.0, replicates=12, seed=3, noise_levels=(1000.0,)):
    rng = np.random.default_rng(seed)           # not the scoring seed
    rows = []
    for r in range(replicates):
        for mode, true in enumerate(TRUE, start=1):
            for noise in noise_levels:
                sigma = 1e-3 * true * noise / 1000.0
                err = sigma * rng.standard_normal()
                rows.append(dict(method=method, noise_ug=noise, n_samples=256, replicate=r, mode=mode,
                                 prior_rad_s=true, true_rad_s=true, estimate_rad_s=true + err,
                                 std_rad_s=std_scale * sigma, error_rad_s=err, crlb_std_rad_s=sigma,
                                 crlb_offset_std_rad_s=sigma, identifiable=True, converged=True, iterations=3,
                                 runtime_s=0.01, message=""))
    pd.DataFrame(rows, columns=COLUMNS).to_csv(path, index=False)
    return path


def test_aggregate_writes_coverage_html_tables_and_captions(tmp_path):
    honest = results_csv(tmp_path / "pem.csv")
    liar = results_csv(tmp_path / "akf.csv", method="akf", std_scale=0.05)     # claims 20x too small a std
    exp = tmp_path / "paper" / "paper_fig4"
    exp.mkdir(parents=True)
    pd.DataFrame({"loop": [1, 2], "pull_in_rad_s": [0.5, 1.5]}).to_csv(exp / "fig4_pullin.csv", index=False)
    (exp / "fig4_pullin.md").write_text("| loop |\n")
    (exp / "notes.md").write_text("Loop 1 needs 21 s to lock.\n")
    out = tmp_path / "out"
    assert aggregate.main(["--grid", "t", "--out", str(out), "--experiments", str(exp), "--",
                           str(honest), str(liar)]) == 0

    summary = pd.read_csv(out / "tables" / "comparison.csv")
    assert (summary.loc[summary["method"] == "akf", "coverage_1std"] < 0.2).all()
    cov = pd.read_csv(out / "tables" / "coverage_by_method.csv")
    verdicts = cov[cov["cells"] == "identifiable"].set_index("method")["verdict"]
    assert verdicts["akf"].startswith("std understated") and verdicts["pem"].startswith("consistent")
    page = (out / "README.md").read_text()
    assert "**akf: its reported std is not honest**" in page
    assert "pem: std consistent" in page

    assert "| pem: errors within ±1σ / ±2σ of its std |" in (out / "tables" / "paper_tables.md").read_text()
    html = (out / "tables" / "paper_fig4.html").read_text()
    assert "pull_in_rad_s" in html and "Loop 1 needs 21 s to lock." in html
    assert "| loop |" not in html                       # a Markdown twin of a CSV is not repeated
    for folder, suffix in (("figures", "png"), ("tables", "html")):
        outputs = sorted((out / folder).glob(f"*.{suffix}"))
        assert outputs
        for f in outputs:
            assert f.with_suffix(".rst").read_text().strip()


def test_a_figure_someone_else_adds_gets_a_caption_that_says_it_has_none(tmp_path):
    (tmp_path / "basin_of_attraction_xyz.png").write_bytes(b"")
    (written,) = aggregate.write_captions(tmp_path, "png", {})
    assert written.name == "basin_of_attraction_xyz.rst"
    assert "no caption written yet" in written.read_text()


def test_a_grid_without_1_mg_draws_its_figures_at_a_level_it_has(tmp_path):
    # an even number of levels, none of them 1000 µg: the median (5050 µg) is no level of the grid, and the
    # one-noise figures found no data there
    assert aggregate.reference_noise([100.0, 10000.0]) == 100.0
    assert aggregate.reference_noise([10.0, 3000.0, 1e5]) == 3000.0
    assert aggregate.reference_noise([1000.0, 10.0]) == 1000.0
    results = results_csv(tmp_path / "pem.csv", replicates=4, noise_levels=(100.0, 10000.0))
    out = tmp_path / "out"
    assert aggregate.main(["--grid", "t", "--out", str(out), "--", str(results)]) == 0
    assert sorted(p.name for p in (out / "figures").glob("*.png"))
