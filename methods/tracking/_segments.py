"""Pulse-free segments of a tracking window: the runs between the samples the pulse detector flags, and a
change test that splits a run at a kick the detector missed.

The fit over them — shared frequencies and damping, each segment's own amplitudes, phases and offset — is
pem's :func:`methods.pem.separable_fit` (variable projection; its docstring gives the model).

**The kick test** (:func:`split_kicks`). With the poles fixed, a free decay of n samples is linear in its
p = 2m + 1 amplitudes and offset, y = Xc + e, X = [e^{−ζᵢωᵢt}cos ω_dᵢt, e^{−ζᵢωᵢt}sin ω_dᵢt, 1]. A kick at
sample k changes c from sample k + 1 on, and sample k itself carries the pulse's feed-through; so the
alternative at k is c₁ on [0, k), a free value at k, c₂ on [k + 1, n) — p + 1 more parameters — and its
F statistic is (Chow 1960; Andrews 1993's sup-F over k)

    F(k) = [(RSS₀ − RSS₁(k)) / (p + 1)] / [RSS₁(k) / (n − 2p − 1)],
    RSS₁(k) = RSS([0, k)) + RSS([k + 1, n)),   RSS(S) = Σ_S y² − b_Sᵀ G_S⁻¹ b_S,   G_S = Σ_S x xᵀ,  b_S = Σ_S x y,

F(p + 1, n − 2p − 1) under white noise at each k; every k at once from cumulative Gram matrices (forward for
[0, k), backward for [k + 1, n): sums of positive terms, no cancellation), O(n p²) and K small p × p solves.
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


def segments(flags: np.ndarray, min_length: int) -> list[tuple[int, int]]:
    """Runs [a, b) of unflagged samples at least ``min_length`` long: a flagged sample belongs to no segment
    (its sample carries the pulse's feed-through) and the next free decay starts after it."""
    good = ~np.asarray(flags, dtype=bool)
    edges = np.diff(np.concatenate(([0], good.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True) if b - a >= min_length]


def free_decay_basis(n: int, dt: float, w: np.ndarray, zeta: np.ndarray) -> np.ndarray:
    """X (n × (2m + 1)): e^{−ζωt}cos ω_d t, e^{−ζωt}sin ω_d t per mode and a constant, t = kΔt from the run's
    start, ω_d = ω√(1 − ζ²) (the segment model of :func:`methods.pem.separable_fit`)."""
    t = np.arange(n) * dt
    s = -zeta * w + 1j * w * np.sqrt(1.0 - zeta * zeta)
    p = np.exp(np.multiply.outer(t, s))
    return np.hstack([p.real, p.imag, np.ones((n, 1))])


def kick_statistic(y: np.ndarray, dt: float, w: np.ndarray, zeta: np.ndarray,
                   min_length: int) -> tuple[np.ndarray, np.ndarray, int] | None:
    """(candidate k, F(k), residual dof) of the kick test on one run ``y`` (module docstring); None when no
    split leaves ``min_length`` samples on both sides or a Gram matrix is singular."""
    n = y.size
    X = free_decay_basis(n, dt, w, zeta)
    p = X.shape[1]
    lo, hi = max(min_length, p), n - 1 - max(min_length, p)
    dof = n - 2 * p - 1
    if hi < lo or dof < 1:
        return None
    X = X / np.linalg.norm(X, axis=0)              # unit columns: the Gram matrices' conditioning
    outer = X[:, :, None] * X[:, None, :]
    xy, yy = X * y[:, None], y * y
    k = np.arange(lo, hi + 1)
    # [0, k): forward sums up to k − 1; [k + 1, n): backward sums from k + 1
    fwd_G, fwd_b, fwd_y = (np.cumsum(a, axis=0) for a in (outer, xy, yy))
    bwd_G, bwd_b, bwd_y = (np.cumsum(a[::-1], axis=0)[::-1] for a in (outer, xy, yy))
    G = np.concatenate([fwd_G[k - 1], bwd_G[k + 1], fwd_G[-1:]])
    b = np.concatenate([fwd_b[k - 1], bwd_b[k + 1], fwd_b[-1:]])
    try:
        c = np.linalg.solve(G, b[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        return None
    fit = np.einsum("ij,ij->i", b, c)
    K = k.size
    rss1 = np.maximum(fwd_y[k - 1] - fit[:K], 0.0) + np.maximum(bwd_y[k + 1] - fit[K:2 * K], 0.0)
    rss0 = max(fwd_y[-1] - fit[-1], 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        F = ((rss0 - rss1) / (p + 1)) / (rss1 / dof)
    return k, np.where(np.isfinite(F), F, 0.0), dof


def split_kicks(y: np.ndarray, dt: float, runs: list[tuple[int, int]], w: np.ndarray, zeta: np.ndarray,
                min_length: int, level: float, rounds: int) -> tuple[list[tuple[int, int]], list[int]]:
    """(runs split at the kicks the test finds, the kick samples) — binary segmentation of each run of ``y``
    at family-wise ``level`` per run, ``rounds`` deep (module docstring); the kick sample itself joins no
    run."""
    m = np.size(w)
    out, kicks = [], []
    stack = [(a, b, 0) for a, b in runs]
    while stack:
        a, b, depth = stack.pop()
        found = kick_statistic(y[a:b], dt, w, zeta, min_length) if depth < rounds else None
        if found is not None:
            k, F, dof = found
            j = int(np.argmax(F))
            if F[j] > scipy.stats.f.isf(level / k.size, 2 * m + 2, dof):
                s = a + int(k[j])
                kicks.append(s)
                stack += [(a, s, depth + 1), (s + 1, b, depth + 1)]
                continue
        out.append((a, b))
    return sorted(out), sorted(kicks)
