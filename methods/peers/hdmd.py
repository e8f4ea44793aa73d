"""Hankel (delay-embedded) dynamic mode decomposition (``pydmd.HankelDMD``).

A scalar record has no spatial snapshots; DMD works on its delay embedding: ``pydmd.HankelDMD`` stacks d
delayed copies of the record as snapshots, fits the best linear map between successive snapshots in the
subspace of the truncated SVD (rank = the model order) and returns its eigenvalues z, the discrete-time
poles; s = log(z)/Δt and :func:`methods.peers._mode_picker.pick_modes` picks the m modes. (This is ERA's
realisation up to the choice of basis; the libraries differ in how they truncate and solve.)

Settings (methods/peers/README.md): rank 2m + 1 + ``extra_order``; d = ``delays_fraction``·N delays
(at least the rank), chosen on tuning seed 1 (never the scoring seed); ``rows_periods`` caps d by what the
prior needs (:func:`methods.peers._hankel.hankel_rows`: pydmd takes full SVDs of the d × (N − d + 1)
embedding), off by default here (it cost accuracy on long records), on for :mod:`methods.peers.bopdmd`.
No uncertainty: ``std`` is NaN.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from methods.peers._hankel import check_rows, hankel_rows
from methods.peers._mode_picker import PeerOptions, check_peer_options, continuous_poles, identify_peer, too_short

__all__ = ["Options", "delays_and_order", "check_options", "identify"]


@dataclass
class Options(PeerOptions):
    extra_order: int = 1             # spare states beyond modes and offset (tuned on seed 1)
    delays_fraction: float = 0.5     # at most this fraction of N as delays d (the snapshots are N − d + 1)
    rows_periods: float | None = None  # cap: delays for this many of the prior's longest periods (_hankel); null:
    rows_per_order: float = 3.0      # the fraction alone (square: 166 delays lost 13-22 % at 1024-2048 samples)

    def check(self) -> None:
        super().check()
        if not 0 < self.delays_fraction < 1:
            raise ValueError(f"delays_fraction = {self.delays_fraction} must be in (0, 1)")
        check_rows(self.rows_periods, self.rows_per_order)


def delays_and_order(n: int, prior, dt: float, opts) -> tuple[int, int]:
    """The delay count d (:func:`methods.peers._hankel.hankel_rows`, at most ``delays_fraction``·N) and the
    rank, clipped so that the d × (N − d + 1) embedding has that rank."""
    order = opts.model_order(np.size(prior))
    d = hankel_rows(int(round(opts.delays_fraction * n)), order, prior, dt, opts.rows_per_order, opts.rows_periods)
    d = min(max(d, order), n - order - 1)
    return d, min(order, d, n - d)


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    return check_peer_options(Options, options, "hdmd")


def _fit(y, dt, prior, opts: Options):
    d, order = delays_and_order(y.size, prior, dt, opts)
    if order < 2 * prior.size:
        return too_short(prior, y.size, "Hankel DMD")
    from pydmd import HankelDMD  # optional extra (.[peers])

    dmd = HankelDMD(svd_rank=order, d=d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # pydmd warns about ill-conditioned snapshot matrices
        dmd.fit(y[None, :])
    s = continuous_poles(np.asarray(dmd.eigs), dt)
    return opts.estimate(s, y, dt, prior, order=order, delays=d)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of a Hankel DMD of the record."""
    return identify_peer(check_options, _fit, y, dt, prior, options)
