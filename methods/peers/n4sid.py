"""N4SID subspace identification (``nfoursid``) of the record as an output-only state-space model.

``nfoursid.NFourSID`` with the record as its only output column (no input: the excitation is the initial
state) forms the block Hankel matrices of ``num_block_rows`` past and future rows, its oblique projection
and SVD, and ``system_identification(rank=order)`` returns (A, B, C, D); the eigenvalues of A become
continuous-time poles s = log(z)/Δt and :func:`methods.peers._mode_picker.pick_modes` picks the m modes.

Settings (methods/peers/README.md): order 2m + 1 + ``extra_order``; block rows = ``rows_fraction`` · N,
at least the order, chosen on tuning seed 1 (never the scoring seed), capped by what the prior needs
(:func:`methods.peers._hankel.hankel_rows`; the library's QR and SVD grow with the rows squared).
The library's covariance matrices describe the innovation, not the frequencies: ``std`` is NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.peers._hankel import check_rows, hankel_rows
from methods.peers._mode_picker import PeerOptions, check_peer_options, continuous_poles, identify_peer, too_short

__all__ = ["Options", "check_options", "identify"]


@dataclass
class Options(PeerOptions):
    extra_order: int = 3             # spare states beyond modes and offset (tuned on seed 1)
    rows_fraction: float = 0.25      # at most this fraction of N as block rows (past and future each)
    rows_periods: float | None = 2.0  # rows span at least this many of the prior's longest periods (_hankel)
    rows_per_order: float = 3.0      # and at least this many times the model order; null periods: the fraction

    def check(self) -> None:
        super().check()
        if not 0 < self.rows_fraction < 0.5:
            raise ValueError(f"rows_fraction = {self.rows_fraction} must be in (0, 0.5)")
        check_rows(self.rows_periods, self.rows_per_order)


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    return check_peer_options(Options, options, "n4sid")


def _fit(y, dt, prior, opts: Options):
    import pandas as pd  # nfoursid takes a DataFrame; 0.4 s no other method pays
    from nfoursid.nfoursid import NFourSID  # optional extra (.[peers])

    order = opts.model_order(prior.size)
    # the block Hankel matrix has `rows` rows and N − 2·rows + 1 columns; the order needs both
    cap = int(round(opts.rows_fraction * y.size))
    rows = max(hankel_rows(cap, order, prior, dt, opts.rows_per_order, opts.rows_periods), order)
    if 2 * rows >= y.size - order:
        rows = (y.size - order - 1) // 2
        order = min(order, rows)
    if order < 2 * prior.size:
        return too_short(prior, y.size, "N4SID")
    model = NFourSID(pd.DataFrame({"y": y}), output_columns=["y"], num_block_rows=rows)
    model.subspace_identification()
    ss, _ = model.system_identification(rank=order)
    s = continuous_poles(np.linalg.eigvals(ss.a), dt)
    return opts.estimate(s, y, dt, prior, order=order, block_rows=rows)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an N4SID model of the record."""
    return identify_peer(check_options, _fit, y, dt, prior, options)
