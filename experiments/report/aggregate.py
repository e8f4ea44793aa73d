"""Aggregate a grid's per-job result tables into comparison tables, figures and one summary page.

    python -m experiments.report.aggregate --grid smoke --out results/smoke results/smoke/identify/*/*.csv

Reads the per-job CSV files (the record; not MLflow) and writes, under ``--out``:
``tables/comparison.{csv,md,html}``, ``tables/coverage_by_method.{csv,md,html}`` (how honest each method's
reported std is), ``tables/paper_tables.{md,html}``, one HTML page of tables per paper reproduction,
``figures/*.{png,svg}``, a caption ``<name>.rst`` beside every figure and HTML table (from
experiments/report/captions/, see experiments.report.catalog) for the Snakemake report, and ``README.md``,
the page that links all of it (written last: its presence means the rest is complete).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from experiments import paths
from experiments.cli import ArgumentParser
from experiments.io import atomic_write_text, markdown_table, write_table
from experiments.report import axes, catalog, htmltables, pareto, plots, variants
from experiments.report.coverage import coverage_table, honesty_lines
from experiments.report.summary import attach_yardstick, cell_keys, summarize

__all__ = ["PRINTED", "reference_noise", "read_results", "paper_tables", "PAPER_TABLES_INTRO", "render_paper_tables",
           "headline", "bayes_headline", "main", "experiment_tables", "html_twins", "write_captions", "page",
           "experiments_section"]

PRINTED = paths.CONFIGS / "paper" / "printed.yaml"


def read_results(paths) -> pd.DataFrame:
    frames = [pd.read_csv(p) for p in paths]
    if not frames:
        raise ValueError("no result tables given")
    return pd.concat(frames, ignore_index=True)


def _cell(summary, method, noise):
    """The summary rows of ``method`` at ``noise`` and the longest record of the grid."""
    sub = summary[(summary["method"] == method) & (summary["noise_ug"] == noise)]
    if sub.empty:
        return sub, None
    n = int(sub["n_samples"].max())
    return sub[sub["n_samples"] == n].sort_values("mode"), n


def paper_tables(summary: pd.DataFrame, results: pd.DataFrame) -> list[tuple[str, str, pd.DataFrame]]:
    """Tables 3–6 of the paper regenerated beside its printed numbers, from whichever methods ran.

    Returns one (title, note, table) per table of the paper; ``render_paper_tables`` makes it Markdown.
    """
    printed = yaml.safe_load(PRINTED.read_text())
    true = np.asarray(printed["true_rad_s"])
    out = []
    for key, title in (("table3", "Table 3 (augmented and weighted Kalman filters)"),
                       ("table4", "Table 4/5 (PEM, a-priori frequencies)"),
                       ("table5", "Table 5 (PEM, identified frequencies)"),
                       ("table6", "Table 6 (PLL a-priori frequencies)")):
        spec = printed[key]
        noise = spec["noise_ug"]
        notes = []
        rows = {"true (paper), rad/s": true}
        if "prior_rad_s" in spec:
            prior = np.asarray(spec["prior_rad_s"])
            rows["a priori (paper), rad/s"] = prior
            if "deviation_pct" in spec:
                rows["deviation printed, %"] = np.asarray(spec["deviation_pct"])
            rows["deviation actual, %"] = np.round(100 * np.abs(prior - true) / true, 1)
        if "estimate_rad_s" in spec:
            rows["estimated (paper), rad/s"] = np.asarray(spec["estimate_rad_s"])
        n_used = None
        for method in spec["method"]:
            cell, n = _cell(summary, method, noise)
            if n is None or len(cell) != true.size:
                notes.append(f"{method}: not run at {noise:g} µg in this grid.")
                continue
            n_used = n
            res = results[(results["method"] == method) & (results["noise_ug"] == noise)
                          & (results["n_samples"] == n)]
            ok = res[res["converged"]]
            mean = ok.groupby("mode")["estimate_rad_s"].mean().reindex(range(1, true.size + 1))
            std = ok.groupby("mode")["estimate_rad_s"].std().reindex(range(1, true.size + 1))
            rows[f"{method}: mean ± std, rad/s"] = [f"{m:.4f} ± {s:.2g}" for m, s in zip(mean, std,
                                                                                        strict=True)]
            rows[f"{method}: RMSE/CRLB"] = cell["rmse_over_crlb"].to_numpy()
            rows[f"{method}: failure rate"] = cell["failure_rate"].to_numpy()
            rows[f"{method}: errors within ±1σ / ±2σ of its std"] = [
                "no std" if np.isnan(c1) else f"{100 * c1:.0f} % / {100 * c2:.0f} %"
                for c1, c2 in zip(cell["coverage_1std"], cell["coverage_2std"], strict=True)]
        if n_used is not None:
            cell = summary[(summary["noise_ug"] == noise) & (summary["n_samples"] == n_used)]
            rows["CRLB std, rad/s"] = cell.drop_duplicates("mode").sort_values("mode")["crlb_std_rad_s"]
            notes.append(f"Noise {noise:g} µg (1σ), {n_used} samples at the grid's dt.")
        table = pd.DataFrame({"": list(rows)} | {f"mode {i + 1}": [np.asarray(v, dtype=object)[i]
                                                                   for v in rows.values()]
                                                 for i in range(true.size)})
        out.append((title, " ".join(notes), table))
    return out


PAPER_TABLES_INTRO = ("Each table shows the paper's printed numbers beside ours: the mean ± std over the Monte-Carlo "
                      "replicates of the grid at the paper's noise level and the grid's longest record, the CRLB "
                      "std, the failure rate, and the share of errors within ±1σ / ±2σ of the method's own std "
                      "(ideal 68 % / 95 %). Our true frequencies are the eigenfrequencies of the generating "
                      "model.")


def render_paper_tables(tables) -> str:
    out = ["# The paper's tables, regenerated", "", PAPER_TABLES_INTRO, ""]
    for title, note, table in tables:
        out += [f"## {title}", "", f"*{note}*" if note else "", "", markdown_table(table), ""]
    return "\n".join(out)


def _wins(frame: pd.DataFrame, cells: str, label: str, ratio: str) -> list[str]:
    """Per mode, a line: each method that has the lowest RMSE in some cell of ``frame``, in how many, and the
    median of column ``ratio`` (called ``label``) over those cells."""
    lines = []
    for mode, g in frame.groupby("mode"):
        best = g.loc[g.groupby(cell_keys(g), dropna=False)["rmse_rad_s"].idxmin()]
        counts = best["method"].value_counts()
        parts = [f"{m} wins {c} of {len(best)} {cells} (median {label} "
                 f"{best[best['method'] == m][ratio].median():.2f})" for m, c in counts.items()]
        lines.append(f"- mode {mode}: " + "; ".join(parts))
    return lines


def headline(summary: pd.DataFrame) -> str:
    """Per mode: which method is best most often among identifiable cells, and how far from the bound."""
    ident = summary[summary["identifiable"] & (summary["failure_rate"] <= 0.1)].dropna(subset=["rmse_rad_s"])
    lines = _wins(ident, "identifiable cells", "RMSE/CRLB", "rmse_over_crlb")
    per_method = (summary[summary["identifiable"]].groupby("method")
                  .agg(median_rmse_over_crlb=("rmse_over_crlb", "median"),
                       median_rmse_over_crlb_offset=("rmse_over_crlb_offset", "median"),
                       mean_failure_rate=("failure_rate", "mean"),
                       median_runtime_s=("median_runtime_s", "median")).reset_index())
    return ("\n".join(lines) + "\n\nOver identifiable (mode, cell) pairs:\n\n" + markdown_table(per_method)
            + bayes_headline(summary))


def bayes_headline(summary: pd.DataFrame) -> str:
    """Where the classical bound is loose (the cells with a posterior-mean yardstick): per mode who has the
    lowest RMSE among the methods failing ≤ 10 %, and each method's RMSE over the posterior mean's RMSE on the
    same records."""
    if "rmse_over_posterior_mean" not in summary.columns:
        return ""
    loose = summary[summary["rmse_over_posterior_mean"].notna()]
    if loose.empty:
        return ""
    ok = loose[loose["failure_rate"] <= 0.1]
    lines = ["", "", "Where the CRLB is loose (cells where some mode's CRLB > 0.1 × the prior's 1σ), against the "
             "Bayesian yardstick: the RMSE of the posterior mean under the grid's prior on the same records "
             "(docs/prior.md); < 1 is closer to this truth than that estimator, which no method beats on average "
             "over truths drawn from the prior:", ""]
    lines += _wins(ok, "cells", "RMSE/posterior mean", "rmse_over_posterior_mean")
    per_method = (ok.groupby("method")
                  .agg(pairs=("rmse_over_posterior_mean", "size"),
                       median_rmse_over_posterior_mean=("rmse_over_posterior_mean", "median"),
                       max_rmse_over_posterior_mean=("rmse_over_posterior_mean", "max"),
                       mean_failure_rate=("failure_rate", "mean")).reset_index()
                  .sort_values("median_rmse_over_posterior_mean"))
    n_pairs = len(loose.drop_duplicates([*cell_keys(loose), "mode"]))
    return ("\n".join(lines) + f"\n\nOver those {n_pairs} (mode, cell) pairs, where the method fails ≤ 10 %:\n\n"
            + markdown_table(per_method))


def reference_noise(levels) -> float:
    """The grid's noise level nearest 1 mg on a log scale (1000 µg itself where the grid has it): the level of
    the figures drawn at one noise. Always a level of the grid (the median of an even count is not)."""
    levels = np.unique(np.asarray(levels, float))
    return float(levels[np.argmin(np.abs(np.log10(levels / 1000.0)))])


def main(argv=None) -> int:
    ap = ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", required=True, help="grid name (a title for the page)")
    ap.add_argument("--out", required=True, type=Path, help="folder to write into, e.g. results/smoke")
    ap.add_argument("--experiments", nargs="*", type=Path, default=[],
                    help="folders of paper reproductions to link from the page")
    ap.add_argument("--page", type=Path, default=None,
                    help="the summary page to write (default: <out>/README.md; the workflow writes "
                         "<out>/summary.md and the runlog step makes README.md of it)")
    ap.add_argument("--yardstick", nargs="*", type=Path, default=[],
                    help="the grid's Bayesian yardstick table (experiments.jobs.yardstick), if it has one")
    ap.add_argument("results", nargs="+", type=Path, help="per-job result tables (CSV)")
    args = ap.parse_args(argv)
    try:
        results = read_results(args.results)
        yardstick = read_results(args.yardstick) if args.yardstick else None
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary = summarize(results)
    if yardstick is not None:
        summary = attach_yardstick(summary, yardstick)
    cov = coverage_table(results, summary)
    out = args.out
    tables, figs = out / "tables", out / "figures"
    longest = int(summary["n_samples"].max())
    noise_ref = reference_noise(summary["noise_ug"])
    context = {"grid": args.grid, "longest": longest, "noise_ref": f"{noise_ref:g}"}

    files = write_table(summary, tables / "comparison")
    files += write_table(cov, tables / "coverage_by_method")
    paper = paper_tables(summary, results)
    files.append(atomic_write_text(tables / "paper_tables.md", render_paper_tables(paper) + "\n"))
    files.append(htmltables.write(tables / "paper_tables.html", "The paper's tables, regenerated",
                                  [("", PAPER_TABLES_INTRO)] + [(f"{t}. {n}", d) for t, n, d in paper]))
    for d in args.experiments:
        files.append(experiment_tables(d, tables / f"{d.name}.html"))

    # the noise x length figures show the plain cells (no scenario axis), if the grid has any
    scenario_cols = cell_keys(summary)[2:]
    plain = summary[summary[scenario_cols].isna().all(axis=1)] if scenario_cols else summary
    if not plain.empty:
        files += plots.rmse_against(plain, figs / "rmse_vs_noise", x="noise_ug", fixed="n_samples",
                                    fixed_value=longest)
        files += plots.rmse_against(plain, figs / "rmse_vs_length", x="n_samples", fixed="noise_ug",
                                    fixed_value=noise_ref)
        files += plots.winner_map(plain, figs / "winner_map")
        files += plots.failure_map(plain, figs / "failure_map")
    files += plots.coverage(summary, cov, figs / "coverage")
    scenario_text = ""
    if scenario_cols:                      # per-axis figures and the basin of attraction
        axis_files, scenario_text = axes.figures(summary, results, out)
        files += axis_files
    classes = pareto.class_table(summary)
    files += write_table(classes, tables / "cell_classes")
    files += pareto.figure(classes, figs / "pareto")
    var = variants.table(summary)
    if len(var):
        files += write_table(var, tables / "variants")
        files.append(htmltables.write(tables / "variants.html", f"{args.grid}: method variants side by side",
                                      [("", var)] + variants.provenance(var["variant"])))
        files += variants.figure(var, figs / "variants")

    files += html_twins(tables, args.grid, files)
    files += write_captions(figs, "png", context) + write_captions(tables, "html", context)
    text = (page(args.grid, summary, cov, out, context, classes) + scenario_text
            + experiments_section(args.experiments, out))
    page_path = args.page or out / "README.md"
    atomic_write_text(page_path, text)
    print(f"wrote {page_path} and {len(files)} tables/figures/captions")
    return 0


def experiment_tables(folder: Path, path: Path) -> Path:
    """All tables (CSV) and notes (Markdown without a CSV twin) of one paper reproduction, as one HTML page."""
    sections = []
    for f in sorted(folder.glob("*.csv")):
        sections.append((f.stem, pd.read_csv(f)))
    for f in sorted(folder.glob("*.md")):
        if not f.with_suffix(".csv").exists():
            sections.append((f.stem, f.read_text(encoding="utf-8")))
    return htmltables.write(path, f"Paper reproduction {folder.name}", sections)


def html_twins(folder: Path, grid: str, written) -> list[Path]:
    """An HTML page beside every CSV table of ``folder`` (anyone's) unless one was ``written`` already."""
    done = {Path(f) for f in written}
    return [htmltables.write(f.with_suffix(".html"), f"{grid}: {catalog.title_of(f.stem)}", [("", pd.read_csv(f))])
            for f in sorted(folder.glob("*.csv")) if f.with_suffix(".html") not in done]


def write_captions(folder: Path, suffix: str, context: dict) -> list[Path]:
    """``<name>.rst`` beside every ``<name>.<suffix>`` in ``folder`` (anyone's), for the HTML report."""
    return [atomic_write_text(f.with_suffix(".rst"), catalog.caption_of(f.stem, context))
            for f in sorted(folder.glob(f"*.{suffix}"))]


def _outputs(folder: Path, suffix: str) -> list[str]:
    return sorted((f.stem for f in folder.glob(f"*.{suffix}")), key=catalog.sort_key)


def page(grid, summary, cov, out: Path, context, classes=None) -> str:
    n_rep = int(summary["replicates"].max())
    lines = [f"# Results of the `{grid}` grid", "",
             f"{summary['method'].nunique()} methods × {summary['noise_ug'].nunique()} noise levels × "
             f"{summary['n_samples'].nunique()} record lengths, {n_rep} Monte-Carlo replicates per cell.",
             "Generated by `python -m experiments.report.aggregate`; do not edit. All of it, with captions, in one "
             f"HTML file: `snakemake --cores 1 --report results/{grid}/report.html results/{grid}/README.md`.", "",
             "## Headline", "", headline(summary), "",
             "## Who wins where", "",
             "Per cell class (short < 128 samples or long; ≤ 100 µg or higher noise), the three most accurate "
             "methods failing ≤ 10 % (median RMSE/CRLB over identifiable pairs, median time per fit; "
             "[table](tables/cell_classes.md), [figure](figures/pareto.png)):", "",
             pareto.winners_text(classes) if classes is not None and len(classes) else "(no identifiable pairs)",
             "",
             "Is each method's reported std honest? (coverage on identifiable cells; "
             "[table](tables/coverage_by_method.md), [figure](figures/coverage.png))", "",
             *honesty_lines(cov), "",
             "## Tables", ""]
    for name in _outputs(out / "tables", "html"):
        md = out / "tables" / f"{name}.md"
        csv = out / "tables" / f"{name}.csv"
        links = [f"[{f.suffix[1:]}](tables/{f.name})" for f in (md, csv) if f.exists()]
        lines.append(f"- {catalog.title_of(name)} ({catalog.category_of(name)}): "
                     f"{', '.join(links) or f'[html](tables/{name}.html)'}")
    lines += ["", "## Figures", ""]
    for name in _outputs(out / "figures", "png"):
        caption = " ".join(catalog.caption_of(name, context).split())
        svg = f" ([SVG](figures/{name}.svg))" if (out / "figures" / f"{name}.svg").exists() else ""
        lines += [f"### {catalog.title_of(name)} ({catalog.category_of(name)})", "", f"![{name}](figures/{name}.png)"
                  f"{svg}", "", caption, ""]
    return "\n".join(lines) + "\n"


def experiments_section(dirs, out: Path) -> str:
    """Links to the paper reproductions: their figures shown, their tables linked."""
    if not dirs:
        return ""
    lines = ["## The paper's figures and tables, reproduced", ""]
    for d in sorted(dirs):
        lines += [f"### {d.name}", ""]
        for f in sorted(d.glob("*")):
            rel = f.relative_to(out).as_posix() if f.is_relative_to(out) else f.as_posix()
            if f.suffix == ".png":
                lines += [f"![{f.stem}]({rel})", ""]
            elif f.suffix in (".md", ".csv"):
                lines.append(f"- [{f.name}]({rel})")
        lines.append("")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
