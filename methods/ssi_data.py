"""Data-driven stochastic subspace identification (``strid.DataDrivenStochasticSID``).

SSI-data projects the future block rows of the record's Hankel matrix onto the past (an LQ factorisation
instead of SSI-cov's correlations), takes the SVD truncated at the model order, and A from the shifted
observability matrix; poles, picking and settings as in :mod:`methods.ssi_cov` (same adapter, another
strid class; settings chosen on tuning seed 1, never the scoring seed). ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

from methods.ssi_cov import check_strid_options, run_strid


@dataclass
class Options:
    order: int | None = None         # model order; None: 2m + 1 + extra_order
    extra_order: int = 11            # spare states beyond modes and offset (tuned on seed 1)
    rows_fraction: float = 0.25      # block rows / N
    band: float = 0.5                # mode picker: a pole matches prior ω within ω·1.5^±1
    min_damping: float = -0.02       # mode picker: accepted damping ratios
    max_damping: float = 0.2


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (no record needed)."""
    return check_strid_options(Options, options, "ssi_data")


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an SSI-data model of the record."""
    return run_strid("data", y, dt, prior, options, "ssi_data", Options)
