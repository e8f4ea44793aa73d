"""Eigensystem realization algorithm (python-control's ``control.era``) on the free-decay record.

A free decay from an initial state, yₖ = C Aᵏ x₀, is the impulse response of (A, x₀, C): its samples are
the Markov parameters ERA realises. ``control.era`` builds the block Hankel matrix of the record, truncates
its SVD at the model order and returns a balanced discrete-time realisation; its eigenvalues z become
continuous-time poles s = log(z)/Δt and :func:`methods.peers._mode_picker.pick_modes` picks the m modes.

Settings (methods/peers/README.md): order 2m + 1 + ``extra_order`` (modes, offset, spare states for the
noise) and a Hankel matrix with ``rows_fraction`` of the usable samples as rows, both chosen on tuning
seeds 1-10 (never the scoring seed); ``rows_periods`` caps the rows by what the prior needs
(:func:`methods.peers._hankel.hankel_rows`; the library's full SVD costs O(rows²·columns)), off by default:
two periods lost 13–22 % of RMSE/CRLB at 1024–2048 samples (methods/peers/README.md); control.era drops
the first sample (the feedthrough D), so rows + columns = N − 1. ERA gives no uncertainty: ``std`` is NaN.
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
    rows_fraction: float = 0.5       # at most this fraction of N − 1 as Hankel rows; the rest are columns
    rows_periods: float | None = None  # cap: rows for this many of the prior's longest periods (_hankel); null:
    rows_per_order: float = 3.0      # the fraction alone (square: 166 rows lost 13-22 % at 1024-2048 samples)

    def check(self) -> None:
        super().check()
        if not 0 < self.rows_fraction < 1:
            raise ValueError(f"rows_fraction = {self.rows_fraction} must be in (0, 1)")
        check_rows(self.rows_periods, self.rows_per_order)


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    return check_peer_options(Options, options, "era")


def _fit(y, dt, prior, opts: Options):
    import control  # imported here: python-control is an optional extra (.[peers])

    usable = y.size - 1
    cap = int(round(opts.rows_fraction * usable))
    rows = hankel_rows(cap, opts.model_order(prior.size), prior, dt, opts.rows_per_order, opts.rows_periods)
    rows = min(max(rows, 1), usable - 1)
    cols = usable - rows
    order = min(opts.model_order(prior.size), rows, cols)   # the Hankel matrix's rank limits the realisation
    if order < 2 * prior.size:
        return too_short(prior, y.size, "ERA")
    sysd, _ = control.era(y, order, m=rows, n=cols, dt=dt)
    s = continuous_poles(np.linalg.eigvals(sysd.A), dt)
    return opts.estimate(s, y, dt, prior, order=order, hankel_rows=rows)


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an ERA realisation of the record."""
    return identify_peer(check_options, _fit, y, dt, prior, options)
