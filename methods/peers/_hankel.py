"""How many rows (block rows, delays) a peer's Hankel matrix gets: from the model order, the prior and Δt.

ERA, Hankel DMD, optimized DMD, N4SID and SSI all factor a Hankel (or Toeplitz) matrix of the record with
L rows, and their libraries take its full SVD (python-control, pydmd, nfoursid and strid call
``numpy.linalg.svd`` on the whole matrix): O(L²K) for L × K, L = N/2 made the N = 2048 fits of ERA, Hankel
DMD and N4SID cost 2 s each, most of the full grid's CPU. The rows only need to

- hold the model: L ≥ ``per_order`` × the order (the row space must carry 2m + 1 + spare states with room
  for the noise), and
- span the longest time the prior asks the model to tell apart: ``periods`` × τ/Δt samples, with
  τ = max(2π/ω_min, 2π/Δω_min) — the slowest mode's period, or the beat period of the closest pair of
  prior entries, whichever is longer (a row space shorter than a beat sees two close modes as one).

so L = min(cap, max(per_order·order, periods·τ/Δt)), with ``cap`` the peer's old count (a fraction of N,
square for ERA and DMD): a short record keeps it, a long one stops growing the rows once they cover what
the prior needs; the columns (N − L or so) still use every sample. Nothing here counts samples of a
particular Δt: τ/Δt is the same time span at any sample rate.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["prior_span_s", "hankel_rows", "check_rows"]


def prior_span_s(prior, dt: float) -> float:
    """τ = max(2π/ω_min, 2π/Δω_min) of the prior frequencies (rad/s), s; Δω over neighbouring entries (only
    the slowest period for one entry)."""
    p = np.sort(np.asarray(prior, dtype=float))
    span = 2 * math.pi / p[0]
    if p.size > 1:
        gap = float(np.min(np.diff(p)))
        if gap > 0:
            span = max(span, 2 * math.pi / gap)
    return span


def hankel_rows(cap: int, order: int, prior, dt: float, per_order: float, periods: float | None) -> int:
    """L = min(cap, max(⌈per_order·order⌉, ⌈periods·τ/Δt⌉)) (module docstring); ``cap`` when ``periods`` is
    None (the fraction-of-N rule alone)."""
    if periods is None:
        return int(cap)
    need = max(math.ceil(per_order * order), math.ceil(periods * prior_span_s(prior, dt) / dt))
    return int(min(cap, need))


def check_rows(rows_periods, rows_per_order) -> None:
    """The two options of :func:`hankel_rows` a peer's ``Options`` carry; ``ValueError`` naming a bad one."""
    if rows_periods is not None and not rows_periods > 0:
        raise ValueError(f"rows_periods = {rows_periods} must be positive (or null: the fraction of N alone)")
    if not rows_per_order >= 1:
        raise ValueError(f"rows_per_order = {rows_per_order} must be at least 1")
