"""Covariance-driven stochastic subspace identification (``strid.CovarianceDrivenStochasticSID``).

SSI-cov is the operational-modal-analysis workhorse: the record's output correlations at lags 1…2i fill a
block Toeplitz matrix, whose SVD truncated at the model order gives the observability matrix and, by its
shift structure, A. The eigenvalues of A become continuous-time poles s = log(z)/Δt and
:func:`methods.peers._mode_picker.pick_modes` picks the m modes. (SSI assumes a stationary response to white
excitation; a free decay is not one, and the correlations of a decaying record are biased estimates —
this is how a practitioner would call it on such a record, and what the benchmark measures.)

Settings (methods/peers/README.md): order 2m + 1 + ``extra_order``; block rows i = ``rows_fraction``·N
capped by what the prior needs (:func:`methods.peers._hankel.hankel_rows`), at least the order (strid
requires order ≤ i for one output), 2i < N (SSI-cov) or 4i ≤ N + 1 (SSI-data); chosen on tuning seed 1
(never the scoring seed). strid gives no frequency uncertainty: ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from methods.peers._hankel import check_rows, hankel_rows
from methods.peers._mode_picker import PeerOptions, check_peer_options, continuous_poles, identify_peer, too_short

__all__ = ["Options", "check_options", "fit_strid", "identify"]


@dataclass
class Options(PeerOptions):
    extra_order: int = 11            # spare states beyond modes and offset (tuned on seed 1)
    rows_fraction: float = 0.25      # at most this fraction of N as block rows
    rows_periods: float | None = 2.0  # rows span at least this many of the prior's longest periods (_hankel)
    rows_per_order: float = 3.0      # and at least this many times the model order; null periods: the fraction

    def check(self) -> None:
        super().check()
        if not 0 < self.rows_fraction < 0.5:
            raise ValueError(f"rows_fraction = {self.rows_fraction} must be in (0, 0.5)")
        check_rows(self.rows_periods, self.rows_per_order)


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (no record needed)."""
    return check_peer_options(Options, options, "ssi_cov")


def fit_strid(kind: str, method: str, y, dt, prior, opts: Options):
    """Shared by ``ssi_cov`` and ``ssi_data``: fit strid's ``kind`` SSI and pick the modes."""
    import strid  # optional extra (.[peers])

    order = opts.model_order(prior.size)
    cap = int(round(opts.rows_fraction * y.size))
    rows = max(hankel_rows(cap, order, prior, dt, opts.rows_per_order, opts.rows_periods), order)
    # SSI-cov's Toeplitz matrix needs correlations up to lag 2i < N; SSI-data's LQ factorisation of the
    # 2i-row Hankel matrix needs at least as many columns (N − 2i + 1) as rows
    limit = (y.size - 2) // 2 if kind == "covariance" else (y.size + 1) // 4
    if rows > limit:
        rows = limit
        order = min(order, rows)
    if order < 2 * prior.size:
        return too_short(prior, y.size, method)
    cls = strid.CovarianceDrivenStochasticSID if kind == "covariance" else strid.DataDrivenStochasticSID
    A, *_ = cls(y[None, :], 1.0 / dt).perform(order, rows)
    s = continuous_poles(np.linalg.eigvals(A), dt)
    return opts.estimate(s, y, dt, prior, order=order, block_rows=rows)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an SSI-cov model of the record."""
    return identify_peer(check_options, partial(fit_strid, "covariance", "ssi_cov"), y, dt, prior, options)
