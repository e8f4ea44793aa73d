"""Hankel (delay-embedded) dynamic mode decomposition (``pydmd.HankelDMD``).

A scalar record has no spatial snapshots; DMD works on its delay embedding: ``pydmd.HankelDMD`` stacks d
delayed copies of the record as snapshots, fits the best linear map between successive snapshots in the
subspace of the truncated SVD (rank = the model order) and returns its eigenvalues z, the discrete-time
poles; s = log(z)/Δt and :func:`methods.peers._mode_picker.pick_modes` picks the m modes. (This is ERA's
realisation up to the choice of basis; the libraries differ in how they truncate and solve.)

Settings (methods/peers/README.md): rank 2m + 1 + ``extra_order``; d = ``delays_fraction``·N delays
(at least the rank), chosen on tuning seed 1 (never the scoring seed); ``rows_periods`` caps d by what the
prior needs (:func:`methods.peers._hankel.hankel_rows`), off by default here (it cost accuracy on long
records), on for :mod:`methods.peers.bopdmd`. pydmd is given the embedding already projected on its r
leading left singular vectors (:func:`leading_subspace`; ``svd: full`` gives it the record and pydmd's
``HankelDMD`` its three full SVDs): the same eigenvalues. No uncertainty: ``std`` is NaN.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from methods.peers._hankel import check_rows, hankel_rows
from methods.peers._mode_picker import PeerOptions, check_peer_options, continuous_poles, identify_peer, too_short

__all__ = ["Options", "SVDS", "delays_and_order", "delay_embedding", "leading_subspace", "check_options", "identify"]


@dataclass
class Options(PeerOptions):
    extra_order: int = 1             # spare states beyond modes and offset (tuned on seed 1)
    delays_fraction: float = 0.5     # at most this fraction of N as delays d (the snapshots are N − d + 1)
    rows_periods: float | None = None  # cap: delays for this many of the prior's longest periods (_hankel); null:
    rows_per_order: float = 3.0      # the fraction alone (square: 166 delays lost 13-22 % at 1024-2048 samples)
    svd: str = "truncated"           # "truncated": the leading singular vectors only (svds); "full": pydmd's

    def check(self) -> None:
        super().check()
        if not 0 < self.delays_fraction < 1:
            raise ValueError(f"delays_fraction = {self.delays_fraction} must be in (0, 1)")
        check_rows(self.rows_periods, self.rows_per_order)
        if self.svd not in SVDS:
            raise ValueError(f"svd = {self.svd!r} must be one of {', '.join(map(repr, SVDS))}")


SVDS = ("truncated", "full")


def delay_embedding(y: np.ndarray, d: int) -> np.ndarray:
    """The d × (N − d + 1) delay embedding of a record, row i = y[i : i + N − d + 1] (pydmd's
    ``hankel_preprocessing`` of a 1 × N record), as a read-only view."""
    return np.lib.stride_tricks.sliding_window_view(y, y.size - d + 1)


def leading_subspace(H: np.ndarray, order: int, shifted: bool = True) -> np.ndarray | None:
    """The ``order`` leading left singular vectors of H[:, :-1] (``shifted``; else of H) (d × order), by ARPACK
    (``scipy.sparse.linalg.svds``, to machine precision, deterministic start), or None when ``order`` is
    not below min(d, N − d) (ARPACK's limit; then the full SVD).

    Why: DMD of the delay snapshots X₁ = H[:, :-1], X₂ = H[:, 1:] at rank r only uses X₁'s leading r
    singular triplets (Ã = UᵣᵀX₂VᵣΣᵣ⁻¹), and for Q = Uᵣ the projected snapshots QᵀH give the same Ã, so
    DMD of QᵀH (r × (N − d + 1)) has the same eigenvalues to rounding. pydmd computes three full SVDs of
    H (a condition check, the rank, the basis): O(d²N) each, 1.1 s of the 1.2 s fit at N = 2048 with
    d = N/2; ARPACK's r triplets cost 0.05 s."""
    X1 = H[:, :-1] if shifted else H
    if not order < min(X1.shape):
        return None
    from scipy.sparse.linalg import svds  # only here: the peers' adapters load it with their libraries

    U, sv, _ = svds(np.ascontiguousarray(X1), k=order, solver="arpack", random_state=0)
    return U[:, np.argsort(sv)[::-1]]


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
    from pydmd import DMD, HankelDMD  # optional extra (.[peers])

    H = delay_embedding(y, d)
    Q = leading_subspace(H, order) if opts.svd == "truncated" else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # pydmd warns about ill-conditioned snapshot matrices
        if Q is None:
            dmd = HankelDMD(svd_rank=order, d=d)
            dmd.fit(y[None, :])
        else:                                        # the same DMD on the projected delay snapshots
            dmd = DMD(svd_rank=order)
            dmd.fit(Q.T @ H)
    s = continuous_poles(np.asarray(dmd.eigs), dt)
    return opts.estimate(s, y, dt, prior, order=order, delays=d)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of a Hankel DMD of the record."""
    return identify_peer(check_options, _fit, y, dt, prior, options)
