"""A data-driven start for the PEM search: damped sinusoids from the matrix-pencil method, matched to a prior.

The record is modelled as y(k) = Σⱼ cⱼ zⱼᵏ + noise (complex poles zⱼ = e^{sⱼΔt}; a damped mode is a conjugate
pair, a sensor offset is a pole at z = 1). The matrix pencil (Hua & Sarkar, 1990) estimates the poles from
the shift invariance of the Hankel matrix of the data: with Y = [y(i+j)], i < N−L, j ≤ L, and V the M
dominant right singular vectors of Y, the poles are the eigenvalues of V₁⁺V₂ (V₁, V₂: V without its last
or first row). An order M above the number of poles lets the extra poles absorb noise.

No search, no prior: it is the paper's "suboptimal analytical method [...] to generate a set of initial
conditions" (§3.3). The poles are then *matched* to the prior entries, so that a start is a complete set of
frequencies in prior order: the m strongest oscillatory poles (energy over the record), sorted by frequency,
take the prior entries in sorted order; missing ones keep the prior value.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
import scipy.linalg.lapack

from methods.pem.predictor import symmetric_eigh

try:                                       # numpy's LAPACK kernels (private module; numpy 2.4 is pinned)
    from numpy.linalg import _umath_linalg
except ImportError:                        # pragma: no cover - a numpy without it: the public functions
    _umath_linalg = None


def matrix_pencil(y: np.ndarray, order: int, max_columns: int = 120,
                  amplitude_samples: int = 128) -> tuple[np.ndarray, np.ndarray]:
    """Poles zⱼ and complex amplitudes cⱼ of y(k) ≈ Σ cⱼ zⱼᵏ (k = 0…N−1).

    Parameters
    ----------
    y : ndarray, shape (N,)
    order : int
        Number of poles M (clipped to what the record supports, about N/2).
    max_columns : int
        Pencil parameter L is N/3, at most this (and at least M). The cost is O(N·L²) + O(L³) (the
        eigendecomposition: 0.6 ms at L = 85 here, 0.1 ms at L = 32); a smaller L is cheaper but more
        sensitive to noise (``methods.pem`` tries L = 32 first and keeps it only when the fit from it
        explains the record).
    amplitude_samples : int
        The amplitudes are the least-squares fit of the poles to the first this many samples (they only
        rank the poles by energy; a fit to all N samples would cost O(N·M²)).

    The dominant right singular vectors of the Hankel matrix Y are the dominant eigenvectors of its
    (L+1) × (L+1) Gram matrix YᵀY (numpy's ``eigh`` kernel without its wrapper,
    :func:`methods.pem.predictor.symmetric_eigh`; a third of the SVD's time here). Squaring loses the
    directions below 1e-8 of the largest singular value, which a start never needs.
    """
    y = np.ascontiguousarray(y, dtype=float)
    n = y.size
    order = int(min(order, (n - 1) // 2))
    if order < 1:
        return np.zeros(0, complex), np.zeros(0, complex)
    cols = min(max(n // 3, order), max(min(max_columns, n - order - 1), order))
    rows = n - cols
    # the Hankel matrix from a view of y's buffer (sliding_window_view's, without its argument checks and
    # as_strided's array-interface round trip), copied: BLAS's product takes a contiguous matrix only, and
    # numpy's own loop on the overlapping view took twice the copy and product (24 against 16 µs at L = 32)
    Y = np.ndarray((rows, cols + 1), float, y, 0, (8, 8)).copy()
    lam, vecs = symmetric_eigh(Y.T @ Y)                # ascending
    if not lam[-1] > 0:
        return np.zeros(0, complex), np.zeros(0, complex)
    order = min(order, int(np.count_nonzero(lam > lam[-1] * 1e-16)))
    V = vecs[:, ::-1][:, :order]                       # (L+1) × M, strongest first
    V1 = V[:-1]
    z = None
    if V1.shape[0] >= 2 * V1.shape[1]:
        # V₁⁺V₂ = (V₁ᵀV₁)⁻¹V₁ᵀV₂: V has orthonormal columns, so V₁ᵀV₁ = I − vvᵀ (v the last row of V), whose
        # inverse is I + vvᵀ/(1 − vᵀv) (Sherman–Morrison): the solve in two products (a third of LAPACK's
        # call here); |v| = 1 is a pole at infinity
        v = V[-1]
        gap = 1.0 - float(v @ v)
        if gap > 0:
            B = V1.T @ V[1:]
            pencil = B + np.multiply.outer(v / gap, v @ B)
            if np.isfinite(pencil).all():
                try:
                    z = _eigvals(pencil)
                except np.linalg.LinAlgError:          # no convergence: the pseudo-inverse's route below
                    z = None
    if z is None:                                      # few rows (a short record): the pseudo-inverse
        z = np.linalg.eigvals(np.linalg.lstsq(V1, V[1:], rcond=None)[0])
    head = min(n, max(amplitude_samples, 2 * order))
    # the Vandermonde matrix zⱼᵏ by a running product down each column (k·1e-16 relative: the amplitudes
    # only rank the poles; measured 20 against 74 µs for exp(k log z) at 128 × 15); a pole at 0 (no log)
    # or one overflowing over the head is dropped
    z = z.astype(complex)
    vander = np.empty((head, z.size), complex)
    vander[0] = 1.0
    vander[1:] = z
    with np.errstate(over="ignore", invalid="ignore"):
        np.cumprod(vander, axis=0, out=vander)
    keep = np.isfinite(vander[-1]) & (z != 0)
    if not keep.all():
        z, vander = z[keep], vander[:, keep]
    return z, _amplitudes(vander, y[:head].astype(complex))


def _eigvals(a: np.ndarray) -> np.ndarray:
    """``numpy.linalg.eigvals(a)`` of a real a, as complex numbers, through numpy's LAPACK kernel without its
    wrapper (the same values); the wrapper itself where the kernel gave no finite answer (it raises)."""
    if _umath_linalg is not None:
        w = _umath_linalg.eigvals(a, signature="d->D")
        if np.isfinite(w).all():
            return w
    return np.linalg.eigvals(a).astype(complex)


def _amplitudes(vander: np.ndarray, target: np.ndarray) -> np.ndarray:
    """c minimising |target − V c| (complex V, target): the normal equations of the column-scaled V by
    Cholesky (LAPACK ``potrf``/``potrs``) where LAPACK's estimate of their reciprocal condition number
    (``pocon``) is above 1e-10 — c to ~1e-6 relative at worst, and c only ranks the poles — else
    ``numpy.linalg.lstsq`` (SVD), as for every V before (the pencil's start with the three changes
    here: 989 → 748 µs CPU, the same starts to the bit on 2800 records; docs/notes/pem-speed.md)."""
    if vander.shape[1] == 0:
        return np.zeros(0, complex)
    Vh = vander.conj().T
    H = Vh @ vander
    d = 1.0 / np.sqrt(H.diagonal().real)
    Hs = H * np.multiply.outer(d, d)
    chol, info = scipy.linalg.lapack.zpotrf(Hs, lower=1)
    if info == 0:
        rcond, info = scipy.linalg.lapack.zpocon(chol, float(np.abs(Hs).sum(axis=0).max()), uplo="L")
        if info == 0 and rcond > 1e-10:
            c, info = scipy.linalg.lapack.zpotrs(chol, (Vh @ target) * d, lower=1)
            if info == 0 and np.isfinite(c).all():
                return c * d
    return np.linalg.lstsq(vander, target, rcond=None)[0]


def modes_from_poles(z: np.ndarray, amp: np.ndarray, n_samples: int, dt: float):
    """Oscillatory modes (upper half plane, below Nyquist) as (ω = |s|, ζ = −Re s/|s|, energy), strongest first.

    The energy over the record of the real mode 2 Re(c zᵏ) is ≈ 2|c|² Σ|z|^{2k} = 2|c|²(|z|^{2N} − 1)/(|z|² − 1)
    (N where |z|² = 1 to 1e-12; 0 where it overflows)."""
    out = np.array(_pole_modes(z, amp, n_samples, dt), dtype=float).reshape(-1, 3)
    return out[:, 0], out[:, 1], out[:, 2]


def _pole_modes(z: np.ndarray, amp: np.ndarray, n_samples: int, dt: float) -> list[tuple[float, float, float]]:
    """:func:`modes_from_poles` as a list of (ω, ζ, energy) triples, strongest first. Over the ≤ 2m + 7 poles
    as Python numbers: the same operations as numpy's on arrays, in a third of the time of a dozen calls on
    ~8 values; the order is numpy's argsort of −energy (:func:`argsort_few`; ties e.g. two overflowing
    modes' 0)."""
    modes = []
    for zj, cj in zip(z.tolist(), amp.tolist(), strict=True):
        r = abs(zj)
        if not (zj.imag > 1e-12 and r > 1e-6):
            continue
        s = cmath.log(zj) / dt
        omega = abs(s)
        r2 = r * r
        r2_1 = r2 - 1.0
        try:
            geo = n_samples if abs(r2_1) < 1e-12 else (r2 ** n_samples - 1.0) / r2_1
            energy = 2.0 * abs(cj) ** 2 * geo
        except OverflowError:
            energy = math.inf
        modes.append((omega, -s.real / omega, energy if math.isfinite(energy) else 0.0))
    return [modes[i] for i in argsort_few([-mode[2] for mode in modes])]


def argsort_few(keys: list[float]) -> list[int]:
    """numpy's ``argsort`` of a few Python floats, as a list: Python's sort where no two keys are equal (every
    sort then agrees, without numpy's call overhead), numpy's own where some are (its order of ties)."""
    if len(set(keys)) == len(keys):
        return sorted(range(len(keys)), key=keys.__getitem__)
    return np.argsort(np.array(keys, dtype=float)).tolist()


def match_to_prior(omega: np.ndarray, zeta: np.ndarray, prior: np.ndarray, default_zeta: float,
                   max_relative_distance: float = 0.6):
    """Frequencies and damping ratios in prior order from candidate modes (strongest first).

    The m strongest candidates within ``max_relative_distance`` of some prior entry are sorted by frequency
    and given to the prior entries in sorted order. With fewer candidates than prior entries, each candidate
    goes to the nearest free prior entry (log distance) in order of strength; the rest keep the prior.
    (Over Python numbers: a handful of candidates and m ≤ 20 entries.)
    """
    freq, damp = _match(np.asarray(omega, float).tolist(), np.asarray(zeta, float).tolist(),
                        np.asarray(prior, dtype=float).tolist(), float(default_zeta), max_relative_distance)
    return np.array(freq), np.array(damp)


def _match(omega: list[float], zeta: list[float], p: list[float], default_zeta: float,
           max_relative_distance: float = 0.6) -> tuple[list[float], list[float]]:
    """:func:`match_to_prior` over Python lists."""
    m = len(p)
    reach = 1.0 + max_relative_distance
    bands = [(pj / reach, pj * reach) for pj in p]          # |log(ω/pⱼ)| ≤ log(1 + d) for some j
    cand = [(w, z) for w, z in zip(omega, zeta, strict=True) if any(a <= w <= b for a, b in bands)][:m]
    freq, damp = list(p), [default_zeta] * m
    if len(cand) == m:
        cand.sort(key=lambda c: c[0])
        for i, (w, z) in zip(sorted(range(m), key=p.__getitem__), cand, strict=True):
            freq[i], damp[i] = w, z
    else:
        taken: set[int] = set()
        for w, z in cand:
            i = min((j for j in range(m) if j not in taken), key=lambda j: abs(math.log(w / p[j])))
            taken.add(i)
            freq[i], damp[i] = w, z
    return freq, damp


PENCIL_WINDOW = 4096   # samples the start looks at: its cost is then bounded whatever N is


def pencil_start(y: np.ndarray, dt: float, prior: np.ndarray, *, extra_order: int, default_zeta: float,
                 max_zeta: float = 0.3, window: int = PENCIL_WINDOW, max_columns: int = 120):
    """A start (ω, ζ) in prior order from the matrix pencil of order 2m + 1 + extra_order.

    Only the first ``window`` samples are used: the pencil's SVD is O(rows·L²) and its Vandermonde fit
    O(rows·M²), so on the whole of a 10⁶-sample record it would cost seconds and a gigabyte, while a start
    only has to land in the basin of the search on the full record. (A damped mode's energy is in the
    record's beginning anyway; the basin in ω is ~2π/(NΔt) wide, the windowed pencil's error ~ its CRLB at
    ``window`` samples — far smaller for the grid's noise levels.) ``max_columns``: see :func:`matrix_pencil`."""
    prior = np.asarray(prior, dtype=float)
    y = np.asarray(y, dtype=float)[:window]
    z, amp = matrix_pencil(y, 2 * prior.size + 1 + extra_order, max_columns=max_columns)
    nyquist = math.pi / dt                              # (np.pi / dt: the same float)
    ok = [(w, zj) for w, zj, _ in _pole_modes(z, amp, y.size, dt) if w < nyquist and -0.05 < zj < max_zeta]
    freq, damp = _match([w for w, _ in ok], [zj for _, zj in ok], prior.tolist(), float(default_zeta))
    # np.clip's values (np.maximum, then np.minimum: the same comparisons), over m Python floats
    return np.array(freq), np.array([min(max(d, 0.0), max_zeta) for d in damp])
