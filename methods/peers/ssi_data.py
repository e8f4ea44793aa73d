"""Data-driven stochastic subspace identification (``strid.DataDrivenStochasticSID``).

SSI-data projects the future block rows of the record's Hankel matrix onto the past (an LQ factorisation
instead of SSI-cov's correlations), takes the SVD truncated at the model order, and A from the shifted
observability matrix; poles, picking and settings as in :mod:`methods.peers.ssi_cov` (same adapter, another
strid class; settings chosen on tuning seed 1, never the scoring seed). ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from methods.peers import ssi_cov
from methods.peers._mode_picker import check_peer_options, identify_peer

__all__ = ["Options", "check_options", "identify"]


@dataclass
class Options(ssi_cov.Options):
    """SSI-cov's settings and defaults (block rows capped at N/4 here, by the LQ factorisation)."""


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (no record needed)."""
    return check_peer_options(Options, options, "ssi_data")


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an SSI-data model of the record."""
    return identify_peer(check_options, partial(ssi_cov.fit_strid, "data", "ssi_data"), y, dt, prior, options)
