"""The workflow: the Snakemake rules (``rules/*.smk``, included by the top-level ``Snakefile``), the grid
schemas (``schemas/``) and the Python that checks the grids and decides the rules' targets: :mod:`.grids`
(load and check), :mod:`.targets` (what a grid runs), :mod:`.command_line` (what a command line asks for),
:mod:`.triggers` (rerun triggers), :mod:`.resources` (cluster requests), :mod:`.tracking` (the tracking grids).
"""

__all__ = []
