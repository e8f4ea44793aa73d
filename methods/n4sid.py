"""N4SID subspace identification (``nfoursid``) of the record as an output-only state-space model.

``nfoursid.NFourSID`` with the record as its only output column (no input: the excitation is the initial
state) forms the block Hankel matrices of ``num_block_rows`` past and future rows, its oblique projection
and SVD, and ``system_identification(rank=order)`` returns (A, B, C, D); the eigenvalues of A become
continuous-time poles s = log(z)/Δt and :func:`methods.modal_poles.pick_modes` picks the m modes.

Settings (methods/README_peers.md): order 2m + 1 + ``extra_order``; block rows = ``rows_fraction`` · N,
at least the order; chosen on tuning seed 1 (never the scoring seed). The library's covariance
matrices describe the innovation, not the frequencies: ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.estimate import check_inputs, failed, flat_record, make_options
from methods.modal_poles import check_common, continuous_poles, order_rule, to_estimate


@dataclass
class Options:
    order: int | None = None         # model order; None: 2m + 1 + extra_order
    extra_order: int = 3             # spare states beyond modes and offset (tuned on seed 1)
    rows_fraction: float = 0.25      # block rows / N (the past and the future each have this many)
    band: float = 0.5                # mode picker: a pole matches prior ω within ω·1.5^±1
    min_damping: float = -0.02       # mode picker: accepted damping ratios
    max_damping: float = 0.2


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    opts = make_options(Options, options, "n4sid")
    check_common(opts)
    if not 0 < opts.rows_fraction < 0.5:
        raise ValueError(f"rows_fraction = {opts.rows_fraction} must be in (0, 0.5)")
    return opts


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an N4SID model of the record."""
    y, dt, prior = check_inputs(y, dt, prior)
    opts = check_options(prior, dt, **options)
    if why := flat_record(y):
        return failed(prior, why, converged_per_mode=[False] * prior.size)
    import pandas as pd  # nfoursid takes a DataFrame
    from nfoursid.nfoursid import NFourSID  # optional extra (.[peers])

    order = opts.order if opts.order is not None else order_rule(prior.size, opts.extra_order)
    # the block Hankel matrix has `rows` rows and N − 2·rows + 1 columns; the order needs both
    rows = max(int(round(opts.rows_fraction * y.size)), order)
    if 2 * rows >= y.size - order:
        rows = (y.size - order - 1) // 2
        order = min(order, rows)
    if order < 2 * prior.size:
        return failed(prior, f"record of {y.size} samples too short for {prior.size} modes by N4SID",
                      converged_per_mode=[False] * prior.size)
    model = NFourSID(pd.DataFrame({"y": y}), output_columns=["y"], num_block_rows=rows)
    model.subspace_identification()
    ss, _ = model.system_identification(rank=order)
    s = continuous_poles(np.linalg.eigvals(ss.a), dt)
    return to_estimate(s, y, dt, prior, band=opts.band, min_damping=opts.min_damping,
                       max_damping=opts.max_damping, order=order, block_rows=rows)
