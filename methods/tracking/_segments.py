"""Pulse-free segments of a tracking window: the runs between the samples the pulse detector flags, and a
change test that splits a run at a kick the detector missed.

The fit over them — shared frequencies and damping, each segment's own amplitudes, phases and offset — is
pem's :func:`methods.pem.separable_fit` (variable projection; its docstring gives the model).

**The kick test** (:func:`split_kicks`). With the poles fixed, a free decay of n samples is linear in its
2m amplitudes and offset. The poles are the window's estimate, though, not the truth, and a pole error δs
leaves a misfit c·t·e^{st}·δs that grows along the run — which a test of the amplitudes alone reads as a
change (a while after a step, while the window's shared poles are wrong, it split clean runs as if kicked).
So both hypotheses carry the first-order pole corrections: under H₀ y = Zβ + e,

    Z = [e^{−ζᵢωᵢt}cos ω_dᵢt, e^{−ζᵢωᵢt}sin ω_dᵢt (the 2m amplitudes), t·e^{−ζᵢωᵢt}cos ω_dᵢt,
         t·e^{−ζᵢωᵢt}sin ω_dᵢt (the 2m corrections), 1],   p = 4m + 1 columns,

and a kick at sample k changes the amplitudes and offset from sample k + 1 on while sample k carries the
pulse's feed-through: H₁(k) adds D_k = [X(t)·1{t > k}, e_k], X the 2m + 1 amplitude and offset columns,
q = 2m + 2 more parameters. The corrections stay shared: their coefficients are amplitude × δs, and a kick's
change of them is of second order (a small kick × a small pole error). The F statistic (Chow 1960;
Andrews 1993's sup-F over k) by partitioned regression (Frisch–Waugh–Lovell), r = y − Z(ZᵀZ)⁻¹Zᵀy:

    F(k) = [δ(k) / q] / [(RSS₀ − δ(k)) / (n − p − q)],   RSS₀ = rᵀr,
    δ(k) = (D_kᵀr)ᵀ S_k⁻¹ (D_kᵀr),   S_k = D_kᵀD_k − D_kᵀZ (ZᵀZ)⁻¹ ZᵀD_k,

F(q, n − p − q) under white noise at each k; D_kᵀr, D_kᵀD_k and ZᵀD_k for every k at once from backward
cumulative sums over t > k (and the row of sample k), O(n p q) and K small q × q solves.
The run splits at the k of the largest F when it exceeds the F quantile at level α/K (Bonferroni over the K
splits tested: a family-wise level per run), each side at least ``min_length`` samples (a shorter side is
dropped by :func:`segments` anyway); binary segmentation repeats on both sides, ``rounds`` deep.
Written here because no kept library has it: scipy.stats gives the quantiles, statsmodels (not a dependency)
tests a break only at a given k or by CUSUM of recursive residuals, and ``ruptures`` (not a dependency)
searches change points of a mean or of a regression whose regressors it is handed, without the spike at k
or a test level.
"""

from __future__ import annotations

import numpy as np
import scipy.stats

from methods import pem


def segments(flags: np.ndarray, min_length: int) -> list[tuple[int, int]]:
    """Runs [a, b) of unflagged samples at least ``min_length`` long: a flagged sample belongs to no segment
    (its sample carries the pulse's feed-through) and the next free decay starts after it."""
    good = ~np.asarray(flags, dtype=bool)
    edges = np.diff(np.concatenate(([0], good.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True) if b - a >= min_length]


def free_decay_basis(n: int, dt: float, w: np.ndarray, zeta: np.ndarray, *,
                     pole_corrections: bool = False) -> np.ndarray:
    """X (n × (2m + 1)): e^{−ζωt}cos ω_d t, e^{−ζωt}sin ω_d t per mode and a constant, t = kΔt from the run's
    start, ω_d = ω√(1 − ζ²) (the segment model of :func:`methods.pem.separable_fit`); with
    ``pole_corrections`` also t·e^{−ζωt}cos ω_d t, t·e^{−ζωt}sin ω_d t per mode (n × (4m + 1): the
    derivatives of the first columns in the pole, the kick test's first-order pole errors)."""
    w, zeta = np.atleast_1d(np.asarray(w, float)), np.atleast_1d(np.asarray(zeta, float))
    m = w.size
    phi = pem.predictor.modal_basis(w, zeta, dt, n)          # pem's basis: [cos₁, sin₁, …, cosₘ, sinₘ, 1]
    cols = [phi[:, 0:2 * m:2], phi[:, 1:2 * m:2]]
    if pole_corrections:
        t = np.arange(n) * dt
        cols += [t[:, None] * cols[0], t[:, None] * cols[1]]
    return np.hstack(cols + [phi[:, 2 * m:]])


def kick_statistic(y: np.ndarray, dt: float, w: np.ndarray, zeta: np.ndarray, min_length: int, *,
                   pole_corrections: bool = True) -> tuple[np.ndarray, np.ndarray, int, int] | None:
    """(candidate k, F(k), numerator dof q, residual dof n − p − q) of the kick test on one run ``y`` (module
    docstring: Z the p = 4m + 1 columns with the pole corrections, D_k the q = 2m + 2 change columns; without
    ``pole_corrections`` Z = X, p = 2m + 1: Chow's test of the amplitudes alone); None when no split leaves
    ``min_length`` samples on both sides or a Gram matrix is singular."""
    n = y.size
    m = np.size(w)
    Z = free_decay_basis(n, dt, w, zeta, pole_corrections=pole_corrections)
    Z = Z / np.linalg.norm(Z, axis=0)              # unit columns: the Gram matrices' conditioning
    # the columns that change at a kick: amplitudes and offset
    X = Z[:, np.r_[0:2 * m, 4 * m]] if pole_corrections else Z
    p, q = Z.shape[1], X.shape[1] + 1
    lo, hi = max(min_length, q), n - 1 - max(min_length, q)
    dof = n - p - q
    if hi < lo or dof < 1:
        return None
    try:
        Gi = np.linalg.inv(Z.T @ Z)                # the whole run's Gram: well conditioned
        r = y - Z @ (Gi @ (Z.T @ y))
        k = np.arange(lo, hi + 1)
        # backward sums over t ≥ k + 1 of X(t)X(t)ᵀ, Z(t)X(t)ᵀ and X(t)r(t)
        XX, ZX, Xr = (np.cumsum(a[::-1], axis=0)[::-1][k + 1]
                      for a in (X[:, :, None] * X[:, None, :], Z[:, :, None] * X[:, None, :], X * r[:, None]))
        K = k.size
        DtD = np.zeros((K, q, q))
        DtD[:, :-1, :-1] = XX
        DtD[:, -1, -1] = 1.0
        ZtD = np.concatenate([ZX, Z[k][:, :, None]], axis=2)            # (K, p, q)
        Dtr = np.concatenate([Xr, r[k][:, None]], axis=1)               # (K, q)
        S = DtD - np.swapaxes(ZtD, 1, 2) @ (Gi @ ZtD)
        drop = np.einsum("ki,ki->k", Dtr, np.linalg.solve(S, Dtr[:, :, None])[:, :, 0])
    except np.linalg.LinAlgError:
        return None
    rss0 = float(r @ r)
    rss1 = np.maximum(rss0 - drop, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        F = (drop / q) / (rss1 / dof)
    return k, np.where(np.isfinite(F), F, 0.0), q, dof


def split_kicks(y: np.ndarray, dt: float, runs: list[tuple[int, int]], w: np.ndarray, zeta: np.ndarray,
                min_length: int, level: float, rounds: int, *,
                pole_corrections: bool = True) -> tuple[list[tuple[int, int]], list[int]]:
    """(runs split at the kicks the test finds, the kick samples) — binary segmentation of each run of ``y``
    at family-wise ``level`` per run, ``rounds`` deep (module docstring); the kick sample itself joins no
    run.

    A run whose pieces still reject the free decay after ``rounds`` rounds (a kick found at depth ``rounds``)
    is not a few missed pulses but a continuing force (under a white force every sample is a kick: the
    segmentation saturates, 4–5 kicks per 512-sample run against ≤ 0.5 per run under sparse pulses): it is
    returned whole, with no kick, so that the fit stays the one free-decay fit of the run it was without
    the test."""
    out, kicks = [], []
    for run in runs:
        pieces, found_kicks = [], []
        stack = [(run[0], run[1], 0)]
        continuing = False
        while stack:
            a, b, depth = stack.pop()
            found = kick_statistic(y[a:b], dt, w, zeta, min_length, pole_corrections=pole_corrections)
            if found is not None:
                k, F, dfn, dof = found
                j = int(np.argmax(F))
                if F[j] > scipy.stats.f.isf(level / k.size, dfn, dof):
                    if depth == rounds:
                        continuing = True
                        break
                    s = a + int(k[j])
                    found_kicks.append(s)
                    stack += [(a, s, depth + 1), (s + 1, b, depth + 1)]
                    continue
            pieces.append((a, b))
        if continuing:
            out.append(run)
        else:
            out += pieces
            kicks += found_kicks
    return sorted(out), sorted(kicks)
