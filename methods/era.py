"""Eigensystem realization algorithm (python-control's ``control.era``) on the free-decay record.

A free decay from an initial state, yₖ = C Aᵏ x₀, is the impulse response of (A, x₀, C): its samples are
the Markov parameters ERA realises. ``control.era`` builds the block Hankel matrix of the record, truncates
its SVD at the model order and returns a balanced discrete-time realisation; its eigenvalues z become
continuous-time poles s = log(z)/Δt and :func:`methods.modal_poles.pick_modes` picks the m modes.

Settings (methods/README_peers.md): order 2m + 1 + ``extra_order`` (modes, offset, spare states for the
noise) and a Hankel matrix with ``rows_fraction`` of the usable samples as rows, both chosen on tuning
seeds 1-10 (never the scoring seed); control.era drops the first sample (the feedthrough D), so rows +
columns = N − 1. ERA gives no uncertainty: ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.estimate import check_inputs, failed, flat_record, make_options
from methods.modal_poles import check_common, continuous_poles, order_rule, to_estimate


@dataclass
class Options:
    order: int | None = None         # model order; None: 2m + 1 + extra_order (clipped to what N allows)
    extra_order: int = 3             # spare states beyond modes and offset (tuned on seed 1)
    rows_fraction: float = 0.5       # Hankel rows / (N − 1); the rest are columns (square: the usual rule)
    band: float = 0.5                # mode picker: a pole matches prior ω within ω·1.5^±1
    min_damping: float = -0.02       # mode picker: accepted damping ratios
    max_damping: float = 0.2


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    opts = make_options(Options, options, "era")
    check_common(opts)
    if not 0 < opts.rows_fraction < 1:
        raise ValueError(f"rows_fraction = {opts.rows_fraction} must be in (0, 1)")
    return opts


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an ERA realisation of the record."""
    y, dt, prior = check_inputs(y, dt, prior)
    opts = check_options(prior, dt, **options)
    if why := flat_record(y):
        return failed(prior, why, converged_per_mode=[False] * prior.size)
    import control  # imported here: python-control is an optional extra (.[peers])

    usable = y.size - 1
    rows = min(max(int(round(opts.rows_fraction * usable)), 1), usable - 1)
    cols = usable - rows
    order = opts.order if opts.order is not None else order_rule(prior.size, opts.extra_order)
    order = min(order, rows, cols)           # the Hankel matrix's rank limits the realisation
    if order < 2 * prior.size:
        return failed(prior, f"record of {y.size} samples too short for {prior.size} modes by ERA",
                      converged_per_mode=[False] * prior.size)
    sysd, _ = control.era(y, order, m=rows, n=cols, dt=dt)
    s = continuous_poles(np.linalg.eigvals(sysd.A), dt)
    return to_estimate(s, y, dt, prior, band=opts.band, min_damping=opts.min_damping,
                       max_damping=opts.max_damping, order=order, hankel_rows=rows)
