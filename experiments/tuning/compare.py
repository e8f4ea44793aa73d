"""Score method configs side by side (e.g. the paper's setting against the tuned variant) on the scoring seed.

    python -m experiments.tuning.compare --methods akf akf_tuned wkf wkf_tuned pll pll_tuned \\
        --cells 10:256 1000:256 100:2048 --replicates 20 --out results/tuning/compare

The cells are simulated in memory exactly as the grids' dataset files (``make_cell``; default seed: the
paper grid's scoring seed, so the numbers are those of the grid's cells). Writes ``<out>_modes.{csv,md}``
(RMSE/CRLB and failure rate per method, cell and mode) and ``<out>.{csv,md}`` (per method and cell: median
RMSE/CRLB over the modes that delivered, failure rate, and the tuning objective J of
``experiments.report.objective``). Nothing here tunes: it only reads the method configs.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from experiments import paths
from experiments.cli import ArgumentParser
from experiments.config_schema import method_of_config, variant_label
from experiments.hydra_app.command_line import fail, one_line
from experiments.hydra_app.config_store import register
from experiments.io import atomic_write_text, markdown_table, write_table
from experiments.report.objective import DEFAULT_PENALTY, cell_objective
from experiments.simulate.datasets import DatasetConfig, make_cell
from experiments.tuning.tune import base_method, evaluate

__all__ = ["parse_cell", "compare", "main"]


def parse_cell(text: str) -> tuple[float, int]:
    try:
        noise, n = text.split(":")
        return float(noise), int(n)
    except ValueError:
        raise ValueError(f"--cells '{text}' is not noise_ug:n_samples (e.g. 10:256)") from None


def compare(config_names: list[str], cells: list[tuple[float, int]], replicates: int, seed: int,
            penalty: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    register(with_methods=sorted({method_of_config(c) for c in config_names if method_of_config(c)}))
    data = [make_cell(DatasetConfig(noise_ug=nz, n_samples=n, replicates=replicates, seed=seed)) for nz, n in cells]
    modes, per_cell = [], []
    for config in config_names:
        name = method_of_config(config)
        if name is None:
            raise ValueError(f"--methods: '{config}' is not a method config (configs/method/<name>.yaml)")
        m = base_method(config)
        label = variant_label(name, m.variant)
        options = OmegaConf.to_container(m.options, resolve=True)
        _, summary = evaluate(name, label, np.asarray(list(m.prior_rad_s), float), options, data, penalty)
        modes.append(summary)
        for (noise, n), g in summary.groupby(["noise_ug", "n_samples"], sort=True):
            parts = cell_objective(g, penalty)
            per_cell.append({"method": label, "noise_ug": noise, "n_samples": n,
                             "median_rmse_over_crlb": parts["median_rmse_over_crlb"],
                             "failure_rate": parts["failure_rate"], "objective": parts["value"],
                             **{f"mode{r.mode}_rmse_over_crlb": r.rmse_over_crlb for r in g.itertuples()}})
        print(f"scored {label}", file=sys.stderr, flush=True)
    return pd.DataFrame(per_cell), pd.concat(modes, ignore_index=True)


def main(argv: list[str] | None = None) -> None:
    p = ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--methods", nargs="+", required=True, help="method configs, e.g. akf akf_tuned")
    p.add_argument("--cells", nargs="+", default=["10:256", "1000:256"], help="noise_ug:n_samples")
    p.add_argument("--replicates", type=int, default=20)
    p.add_argument("--seed", type=int, default=None, help="default: the paper grid's scoring seed")
    p.add_argument("--penalty", type=float, default=DEFAULT_PENALTY)
    p.add_argument("--out", default="results/tuning/compare")
    args = p.parse_args(argv)
    try:
        cells = [parse_cell(c) for c in args.cells]
        if args.replicates < 1:
            raise ValueError(f"--replicates {args.replicates} must be at least 1")
        paper_grid = paths.GRIDS / "paper.yaml"
        seed = args.seed if args.seed is not None else int(OmegaConf.load(paper_grid).seed)
        table, modes = compare(args.methods, cells, args.replicates, seed, args.penalty)
    except (ValueError, FileNotFoundError, KeyError) as exc:
        fail(one_line(exc))
    out = Path(args.out)
    written = write_table(table, out) + write_table(modes, out.with_name(out.name + "_modes"))
    title = (f"# Paper vs tuned: {args.replicates} replicates per cell, seed {seed}\n\n"
             "median RMSE/CRLB over the modes that delivered; failure rate = mean over modes; objective J = "
             f"log10(median) + {args.penalty:g} × failure rate (experiments/report/objective.py)\n\n")
    atomic_write_text(out.with_suffix(".md"), title + markdown_table(table) + "\n")
    print(title + markdown_table(table))
    for f in written:
        print(f"wrote {f}", file=sys.stderr)


if __name__ == "__main__":
    main()
