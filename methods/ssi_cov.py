"""Covariance-driven stochastic subspace identification (``strid.CovarianceDrivenStochasticSID``).

SSI-cov is the operational-modal-analysis workhorse: the record's output correlations at lags 1…2i fill a
block Toeplitz matrix, whose SVD truncated at the model order gives the observability matrix and, by its
shift structure, A. The eigenvalues of A become continuous-time poles s = log(z)/Δt and
:func:`methods.modal_poles.pick_modes` picks the m modes. (SSI assumes a stationary response to white
excitation; a free decay is not one, and the correlations of a decaying record are biased estimates —
this is how a practitioner would call it on such a record, and what the benchmark measures.)

Settings (methods/README_peers.md): order 2m + 1 + ``extra_order``; block rows i = ``rows_fraction``·N,
at least the order (strid requires order ≤ i for one output), 2i < N (SSI-cov) or 4i ≤ N + 1
(SSI-data); chosen on tuning seed 1
(never the scoring seed). strid gives no frequency uncertainty: ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.estimate import check_inputs, failed, flat_record, make_options
from methods.modal_poles import check_common, continuous_poles, order_rule, to_estimate


@dataclass
class Options:
    order: int | None = None         # model order; None: 2m + 1 + extra_order
    extra_order: int = 11            # spare states beyond modes and offset (tuned on seed 1)
    rows_fraction: float = 0.25      # block rows / N
    band: float = 0.5                # mode picker: a pole matches prior ω within ω·1.5^±1
    min_damping: float = -0.02       # mode picker: accepted damping ratios
    max_damping: float = 0.2


def check_strid_options(options_cls, options: dict, method: str):
    """The options check of ``ssi_cov`` and ``ssi_data`` (no record needed)."""
    opts = make_options(options_cls, options, method)
    check_common(opts)
    if not 0 < opts.rows_fraction < 0.5:
        raise ValueError(f"rows_fraction = {opts.rows_fraction} must be in (0, 0.5)")
    return opts


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (no record needed)."""
    return check_strid_options(Options, options, "ssi_cov")


def run_strid(kind: str, y, dt, prior, options, method: str, options_cls):
    """Shared by ``ssi_cov`` and ``ssi_data``: fit strid's ``kind`` SSI and pick the modes."""
    y, dt, prior = check_inputs(y, dt, prior)
    opts = check_strid_options(options_cls, options, method)
    if why := flat_record(y):
        return failed(prior, why, converged_per_mode=[False] * prior.size)
    import strid  # optional extra (.[peers])

    order = opts.order if opts.order is not None else order_rule(prior.size, opts.extra_order)
    rows = max(int(round(opts.rows_fraction * y.size)), order)
    # SSI-cov's Toeplitz matrix needs correlations up to lag 2i < N; SSI-data's LQ factorisation of the
    # 2i-row Hankel matrix needs at least as many columns (N − 2i + 1) as rows
    limit = (y.size - 2) // 2 if kind == "covariance" else (y.size + 1) // 4
    if rows > limit:
        rows = limit
        order = min(order, rows)
    if order < 2 * prior.size:
        return failed(prior, f"record of {y.size} samples too short for {prior.size} modes by {method}",
                      converged_per_mode=[False] * prior.size)
    cls = strid.CovarianceDrivenStochasticSID if kind == "covariance" else strid.DataDrivenStochasticSID
    A, *_ = cls(y[None, :], 1.0 / dt).perform(order, rows)
    s = continuous_poles(np.linalg.eigvals(A), dt)
    return to_estimate(s, y, dt, prior, band=opts.band, min_damping=opts.min_damping,
                       max_damping=opts.max_damping, order=order, block_rows=rows)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an SSI-cov model of the record."""
    return run_strid("covariance", y, dt, prior, options, "ssi_cov", Options)
