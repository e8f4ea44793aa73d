"""How many modes, and roughly where: a stabilisation diagram, for a record that comes without a prior.

1. **Poles over increasing orders** by covariance-driven SSI (pyOMA2's ``pyoma2.functions.ssi``:
   ``build_hank(..., "cov")``, ``SSI_fast``, ``SSI_poles`` with its hard criteria — conjugate pairs once,
   0 < ζ < ``max_damping``). One SVD of the block Hankel matrix of output correlations serves every order
   n = 1 … n_max (the observability matrix truncated at n, A from its shift structure).
2. **Stable poles**: a pole at order n is stable when order n − 1 has one within ``freq_tol`` in
   frequency and ``damping_tol`` (relative) in damping — pyOMA2's soft criteria (``SC_apply``) without
   the mode-shape term (one channel). Written here, eight lines of numpy, because pyOMA2's ``SC_apply``
   sits in a module that imports pandas (0.8 s of start-up for a loop over pole pairs).
3. **Clusters**: stable poles grouped by frequency (``scipy.cluster.hierarchy``, single linkage on
   log ω, cut at 2·``freq_tol``); a cluster seen at ``min_orders`` orders or more is a candidate, its
   pole the median of its members.
4. **Detection**: the project's rule (:func:`methods.peers._mode_picker.detected`): the candidates'
   damped sinusoids and a constant are fitted to the record by least squares, and a candidate counts only
   when its energy exceeds 2 ln(N/2α)·σ̂² (α = 1 %), the level white noise alone exceeds with
   probability α. With ``n_modes`` the most energetic ``n_modes`` of them are kept.

pyOMA2 was chosen over the project's own SSI peers because it resolves with the project's pins (numpy
2.4, scipy < 1.18) and is the field's stabilisation-diagram library; only its ``functions.ssi`` module is
imported (0.4 s), not its ``algorithms`` layer, whose clustering imports scikit-learn (2 s).
"""

from __future__ import annotations

import contextlib
import io
import logging
from dataclasses import dataclass

import numpy as np

from methods.peers._mode_picker import detected, physical

MAX_ORDER = 40              # model orders 1 … 40: up to 20 modes in the band
FREQ_TOL = 0.01             # pyOMA2's default err_fn
DAMPING_TOL = 0.05          # pyOMA2's default err_xi
MAX_DAMPING = 0.2           # pyOMA2's hard criterion xi_max (the mode picker's max_damping)
MIN_ORDERS = 5              # a cluster must be stable at this many orders


@dataclass(frozen=True)
class Diagram:
    """A stabilisation diagram and the modes read from it.

    Attributes
    ----------
    order, freq_rad_s, damping, stable : ndarray, shape (P,)
        Every pole of every order (after the hard criteria): its model order, natural frequency |s|,
        damping ratio and whether it is stable.
    modes_rad_s, modes_damping, modes_energy : ndarray, shape (m,)
        The detected modes, by increasing frequency: frequency, damping and least-squares energy.
    n_clusters : int
        How many clusters of stable poles were candidates before detection.
    how : str
        One sentence on how the modes were found.
    """

    order: np.ndarray
    freq_rad_s: np.ndarray
    damping: np.ndarray
    stable: np.ndarray
    modes_rad_s: np.ndarray
    modes_damping: np.ndarray
    modes_energy: np.ndarray
    n_clusters: int
    how: str


def stabilisation_diagram(y, dt: float, *, band_rad_s=(0.0, np.inf), n_modes: int | None = None,
                          max_order: int = MAX_ORDER, freq_tol: float = FREQ_TOL,
                          damping_tol: float = DAMPING_TOL, max_damping: float = MAX_DAMPING,
                          min_orders: int = MIN_ORDERS) -> Diagram:
    """Poles of SSI-cov models of orders 1 … ``max_order``, stable ones clustered, clusters detected.

    Parameters
    ----------
    y : ndarray, shape (N,)
        The free decay (any units).
    dt : float
        Sample interval, s.
    band_rad_s : (float, float)
        Only poles with lo ≤ |s| ≤ hi are candidates.
    n_modes : int, optional
        Keep at most this many modes (the most energetic); default: every detected one.

    Returns
    -------
    Diagram
    """
    from pyoma2.functions import ssi  # the stabilisation diagram's library (optional extra .[measurements])

    y = np.asarray(y, float)
    if n_modes is not None and n_modes < 1:
        raise ValueError(f"n_modes = {n_modes} must be at least 1")
    max_order = int(min(max_order, (y.size - 2) // 4))
    if max_order < 2:
        raise ValueError(f"record of {y.size} samples too short for a stabilisation diagram")
    br = max_order + 1                                     # one output: the order is at most the block rows
    Y = (y - y.mean())[None, :]
    log = logging.getLogger("pyoma2")
    level = log.level
    log.setLevel(logging.WARNING)                          # pyOMA2 logs every step at INFO
    try:
        with contextlib.redirect_stderr(io.StringIO()):    # and draws tqdm progress bars
            H, _ = ssi.build_hank(Y, Y, br, "cov")
            obs, A, C, _ = ssi.SSI_fast(H, br, max_order)
            lam = ssi.SSI_poles(obs, A, C, max_order, dt, HC=True, xi_max=max_damping)[3]
    finally:
        log.setLevel(level)
    # lam: (max_order poles, orders 0 … max_order); NaN where a pole failed the hard criteria
    order, poles = [], []
    for n in range(lam.shape[1]):
        s = physical(lam[:, n][np.isfinite(lam[:, n])], dt, (0.0, max_damping))
        order += [n] * s.size
        poles.append(s)
    s_all = np.concatenate(poles) if poles else np.zeros(0, complex)
    order = np.asarray(order, int)
    w, z = np.abs(s_all), -s_all.real / np.maximum(np.abs(s_all), 1e-300)
    stable = _stable(order, w, z, freq_tol, damping_tol)
    lo, hi = band_rad_s
    cand = _clusters(order, w, z, stable & (w >= lo) & (w <= hi), freq_tol, min_orders)
    n_clusters = int(cand.size)
    e = np.zeros(0)
    if cand.size:
        e, real = detected(cand, y, dt)
        cand, e = cand[real], e[real]
    if n_modes is not None and cand.size > n_modes:
        keep = np.argsort(-e, kind="stable")[:n_modes]
        cand, e = cand[keep], e[keep]
    by_freq = np.argsort(np.abs(cand))
    cand, e = cand[by_freq], e[by_freq]
    how = (f"stabilisation diagram: SSI-cov (pyOMA2) at orders 1–{max_order}, stable poles (Δf < {freq_tol:.0%}, "
           f"Δζ < {damping_tol:.0%}) clustered, clusters at ≥ {min_orders} orders detected above the noise "
           f"(α = 1 %): {cand.size} mode{'s' if cand.size != 1 else ''}"
           + (f" (n_modes = {n_modes})" if n_modes is not None else ""))
    return Diagram(order, w, z, stable, np.abs(cand), -cand.real / np.abs(cand) if cand.size else np.zeros(0),
                   e, n_clusters, how)


def _stable(order, w, z, freq_tol: float, damping_tol: float) -> np.ndarray:
    """Stable: the previous order has a pole within ``freq_tol`` in ω and ``damping_tol`` (relative) in ζ."""
    stable = np.zeros(w.size, bool)
    for n in np.unique(order):
        cur, prev = np.flatnonzero(order == n), np.flatnonzero(order == n - 1)
        if prev.size == 0:
            continue
        j = prev[np.argmin(np.abs(w[cur, None] - w[None, prev]), axis=1)]     # nearest pole of order n − 1
        stable[cur] = ((np.abs(w[cur] - w[j]) < freq_tol * w[cur])
                       & (np.abs(z[cur] - z[j]) < damping_tol * np.abs(z[cur])))
    return stable


def _clusters(order, w, z, mask, freq_tol: float, min_orders: int) -> np.ndarray:
    """The median pole of each cluster of stable poles seen at ``min_orders`` orders or more."""
    from scipy.cluster.hierarchy import fcluster, linkage

    idx = np.flatnonzero(mask)
    if idx.size < min_orders:
        return np.zeros(0, complex)
    labels = fcluster(linkage(np.log(w[idx])[:, None], method="single"), t=2 * np.log1p(freq_tol),
                      criterion="distance")
    out = []
    for lab in np.unique(labels):
        members = idx[labels == lab]
        if np.unique(order[members]).size >= min_orders:
            wm, zm = np.median(w[members]), np.median(z[members])
            out.append(complex(-zm * wm, wm * np.sqrt(1 - zm**2)))
    return np.asarray(out, complex)
