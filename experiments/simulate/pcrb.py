"""The tracking yardstick: the posterior Cramér–Rao bound of a random-walk frequency model, and the bound of
the best sliding window (beside ``crlb.py``, the bound of one free decay).

**The state-space model of the bound.** Per mode i the state is [ξᵢ, ξ̇ᵢ] (the modal oscillator of
``experiments.simulate.timevarying``), then the frequencies ω and, with ``damping=True``, the damping ζ:
z = [ξ₁, ξ̇₁, …, ξₘ, ξ̇ₘ, ω₁…ωₘ, (ζ₁…ζₘ)], and

    z_{k+1} = f_k(z_k) + v_k:   [ξᵢ; ξ̇ᵢ] ← Φ(ωᵢ, ζᵢ)[ξᵢ; ξ̇ᵢ] + Γ(ωᵢ, ζᵢ) bᵢ u_k,   ω ← ω + w_k,   ζ ← ζ,
    y_k = h(z_k) + e_k = Σᵢ cᵢ(−ωᵢ² ξᵢ − 2ζᵢωᵢ ξ̇ᵢ) + D u_k + e_k,

w_k ~ N(0, diag(q)) the random walk, e_k ~ N(0, σ²). The inputs u_k are taken as known (a genie): no tracker
knows them, so a bound that does is still a lower bound for every tracker; the oscillator states then have
no process noise (Q singular).

**Posterior CRB (Tichavský, Muravchik & Nehorai, IEEE TSP 46(5), 1998).** With F̃_k = ∇f_k, H̃_k = ∇h,

    D11 = E[F̃ᵀQ⁻¹F̃],  D12 = D21ᵀ = −E[F̃ᵀ]Q⁻¹,  D22 = Q⁻¹ + E[H̃ᵀH̃]/σ²,  J_{k+1} = D22 − D21(J_k + D11)⁻¹D12,

:func:`tichavsky_recursion` (needs Q invertible). Evaluated along one true trajectory (no average over
trajectories), the matrix-inversion lemma turns it into the covariance form of :func:`pcrb_covariance`,
P⁻ = F̃PF̃ᵀ + Q, P = P⁻ − P⁻H̃ᵀ(H̃P⁻H̃ᵀ + σ²)⁻¹H̃P⁻, P = J⁻¹, which needs no Q⁻¹ (Q singular here). The cell's
bound is this per replicate, along that replicate's own trajectory; tests check the two forms against each
other and against the inverse of the batch Fisher information of the whole (state, frequency) trajectory.

The derivatives of Φ, Γ in ω and ζ are complex-step derivatives (exact to rounding: Φ is analytic).

**Best sliding window.** For a deterministic schedule, an estimator that fits constant frequencies to the
last W samples has at best the CRLB of that window (:func:`window_information`: the same model with q = 0
and no prior, the information form J ← F̃⁻ᵀJF̃⁻¹ + H̃ᵀH̃/σ²) plus the bias of a constant fit to a changing
frequency, taken as |ωᵢ(t_k) − mean of ωᵢ over the window|. The window bound at t_k is
min over W of √(CRLB_W² + bias_W²), per mode, W in powers of two. For a free decay with constant
frequencies the window CRLB is exactly ``crlb.crlb_std`` (the same model in other coordinates; tested).
"""

from __future__ import annotations

import numpy as np

from experiments.simulate.timevarying import ModalModel, oscillator_transition

__all__ = ["COMPLEX_STEP", "RW_FLOOR_REL", "cell_pcrb", "cell_window_bound", "jacobians", "matched_walk_q",
           "pcrb_covariance", "prior_covariance", "random_walk_q", "tichavsky_recursion", "transition_derivatives",
           "window_bound", "window_information"]

COMPLEX_STEP = 1e-30
RW_FLOOR_REL = 1e-4          # the random walk of a constant schedule: 1e-4·ω over the record


def transition_derivatives(w, zeta, dt_s):
    """Φ, Γ and their derivatives in ω and in ζ, each shape (..., 2, 2) (complex step)."""
    phi, gamma = oscillator_transition(w, zeta, dt_s)
    h = COMPLEX_STEP
    pw, gw = oscillator_transition(np.asarray(w) + 1j * h, zeta, dt_s)
    pz, gz = oscillator_transition(w, np.asarray(zeta) + 1j * h, dt_s)
    return phi, gamma, pw.imag / h, gw.imag / h, pz.imag / h, gz.imag / h


def jacobians(model: ModalModel, w, x, dt_s: float, u=None, *, damping: bool = True):
    """F̃_k (the transition's Jacobian from sample k to k+1) and H̃_k along trajectories.

    Parameters
    ----------
    w : ndarray, shape (N, m)
        The true frequencies per sample.
    x : ndarray, shape (R, N, m, 2)
        The true modal states.
    u : ndarray, shape (R, N, n_inputs), optional

    Returns
    -------
    F : ndarray, shape (R, N, d, d)
    H : ndarray, shape (R, N, d)
        with d = 3m (or 4m with damping).
    """
    x = np.asarray(x, dtype=float)
    r, n, m, _ = x.shape
    zeta = model.damping
    d = (4 if damping else 3) * m
    phi, _, pw, gw, pz, gz = transition_derivatives(w, zeta[None, :], dt_s)     # (N, m, 2, 2)
    force = np.zeros((r, n, m)) if u is None else np.einsum("mj,rnj->rnm", model.input_gain, u)
    F = np.zeros((r, n, d, d))
    H = np.zeros((r, n, d))
    c = model.tip_gain
    for i in range(m):
        o = slice(2 * i, 2 * i + 2)
        F[:, :, o, o] = phi[None, :, i]
        F[:, :, o, 2 * m + i] = (np.einsum("nab,rnb->rna", pw[:, i], x[:, :, i])
                                 + gw[None, :, i, :, 1] * force[:, :, i, None])
        if damping:
            F[:, :, o, 3 * m + i] = (np.einsum("nab,rnb->rna", pz[:, i], x[:, :, i])
                                     + gz[None, :, i, :, 1] * force[:, :, i, None])
        wi = w[None, :, i]
        H[:, :, 2 * i] = -c[i] * wi**2
        H[:, :, 2 * i + 1] = -2.0 * c[i] * zeta[i] * wi
        H[:, :, 2 * m + i] = c[i] * (-2.0 * wi * x[:, :, i, 0] - 2.0 * zeta[i] * x[:, :, i, 1])
        if damping:
            H[:, :, 3 * m + i] = -2.0 * c[i] * wi * x[:, :, i, 1]
    idx = np.arange(2 * m, d)
    F[:, :, idx, idx] = 1.0
    return F, H


def pcrb_covariance(F, H, Q, noise_var: float, P0, *, cross=None):
    """The PCRB along trajectories, covariance form: P_k = J_k⁻¹ (module docstring).

    With ``cross`` the process noise v_k (driving z_{k+1}) and the measurement noise e_k of sample k are
    correlated, S_k = E[v_k e_k]: one force drives the modes and enters the accelerometer directly. The
    joint density then factors as p(y_k | z_k) p(z_{k+1} | z_k, y_k), the second Gaussian with mean
    f(z_k) + S_k R⁻¹(y_k − h(z_k)) and covariance Q_k − S_k S_kᵀ/R, so the recursion is the same with
    F̃ ← F̃ − S_k H̃_k/R and Q_k ← Q_k − S_k S_kᵀ/R (R = ``noise_var``, the measurement's whole variance).

    Parameters
    ----------
    F : ndarray, shape (R, N, d, d)
    H : ndarray, shape (R, N, d)
    Q : ndarray, shape (d, d) or (N, d, d)
        Process-noise covariance (may be singular), constant or per sample (Q_k drives z_k → z_{k+1}).
    noise_var : float
        The variance of the measurement's noise (σ², plus the direct term's share of an unknown force).
    P0 : ndarray, shape (d, d) or (R, d, d)
        The prior's covariance of z_0.
    cross : ndarray, shape (d,) or (N, d), optional
        S_k = E[v_k e_k].

    Returns
    -------
    ndarray, shape (R, N, d)
        diag(P_k) after the measurement of sample k.
    """
    r, n, d, _ = F.shape
    Q = np.broadcast_to(Q, (n, d, d))
    if cross is not None:
        cross = np.broadcast_to(cross, (n, d))
    P = np.broadcast_to(P0, (r, d, d)).copy()
    out = np.empty((r, n, d))
    for k in range(n):
        if k:
            f, q = F[:, k - 1], Q[k - 1]
            if cross is not None:
                s = cross[k - 1]
                f = f - s[None, :, None] * H[:, k - 1, None, :] / noise_var
                q = q - np.outer(s, s) / noise_var
            P = f @ P @ f.transpose(0, 2, 1) + q
        h = H[:, k]
        ph = np.einsum("rij,rj->ri", P, h)
        s_k = np.einsum("ri,ri->r", h, ph) + noise_var
        P = P - ph[:, :, None] * ph[:, None, :] / s_k[:, None, None]
        P = 0.5 * (P + P.transpose(0, 2, 1))
        out[:, k] = np.diagonal(P, axis1=1, axis2=2)
    return out


def tichavsky_recursion(F, H, Q, noise_var: float, J0):
    """The PCRB information matrices by Tichavský et al.'s recursion (Q invertible).

    J_0 = J_prior + E[H̃₀ᵀH̃₀]/σ²;  J_{k+1} = D22 − D21 (J_k + D11)⁻¹ D12 with D11 = E[F̃ᵀQ⁻¹F̃],
    D12 = −E[F̃ᵀ]Q⁻¹, D21 = D12ᵀ, D22 = Q⁻¹ + E[H̃ᵀH̃]/σ², the expectations the mean over the R trajectories.

    Parameters
    ----------
    F : ndarray, shape (R, N, d, d);  H : ndarray, shape (R, N, d);  Q : (d, d);  J0 : (d, d) prior information.

    Returns
    -------
    ndarray, shape (N, d, d)
        J_k.
    """
    qi = np.linalg.inv(Q)
    hh = np.einsum("rni,rnj->nij", H, H) / H.shape[0] / noise_var
    d11 = np.einsum("rnji,jk,rnkl->nil", F, qi, F) / F.shape[0]
    d12 = -F.mean(axis=0).transpose(0, 2, 1) @ qi
    J = np.empty((F.shape[1],) + Q.shape)
    J[0] = J0 + hh[0]
    for k in range(1, F.shape[1]):
        J[k] = qi + hh[k] - d12[k - 1].T @ np.linalg.solve(J[k - 1] + d11[k - 1], d12[k - 1])
    return J


def random_walk_q(w: np.ndarray, dt_s: float, rw_rel: float | None) -> np.ndarray:
    """The per-sample variance of each frequency's random walk, one number per mode.

    With ``rw_rel``: qᵢ = (rw_rel·ωᵢ(0))²·Δt (a walk of rw_rel·ω per √s). Without: the walk whose spread
    over the record equals the schedule's range, qᵢ = range(ωᵢ)²/N, floored at (RW_FLOOR_REL·ωᵢ)²/N (the
    bounds' rule before :func:`matched_walk_q`; kept for ``rw_rel`` and comparisons).
    """
    n = w.shape[0]
    if rw_rel is not None:
        return (rw_rel * w[0]) ** 2 * dt_s
    spread = np.maximum(np.ptp(w, axis=0), RW_FLOOR_REL * w[0])
    return spread**2 / n


def matched_walk_q(w: np.ndarray) -> np.ndarray:
    """The per-sample variances of a random walk whose every step has the size of the schedule's own step
    (the bounds' rule), shape (N, m): q_{k,i} = (ωᵢ(t_{k+1}) − ωᵢ(t_k))², floored at
    (RW_FLOOR_REL·ωᵢ)²/N (the last sample repeats the one before).

    A drift's walk moves at the drift's rate, a slosh's at the modulation's instantaneous rate, and a step's
    walk is still except at the step, where it jumps by the step's size in an unknown direction: the bound
    knows when and how fast the frequencies move, not where to. A walk spread over the record
    (:func:`random_walk_q`) moves far more than a drift does on short time scales: with the force unknown its
    bound on the grid's drift at 100 µg was 2.7/1.2/1.3/0.6 % of ω, of the order of the trackers' own errors
    there, so it bounded nothing a trend-following tracker could not beat.
    """
    w = np.asarray(w, dtype=float)
    n = w.shape[0]
    step = np.diff(w, axis=0, append=w[-1:] + (w[-1:] - w[-2:-1] if n > 1 else 0.0)) ** 2
    return np.maximum(step, (RW_FLOOR_REL * w[0]) ** 2 / n)


def prior_covariance(model: ModalModel, w, x, prior, *, prior_rel_std: float | None = None,
                     damping: bool = True) -> np.ndarray:
    """The diagonal of the bound's prior covariance of z_0, shape (d,) (``cell_pcrb``'s docstring)."""
    w = np.asarray(w, dtype=float)
    m = w.shape[1]
    d = (4 if damping else 3) * m
    if prior_rel_std is None:
        spread = np.max(np.abs(np.asarray(prior) / w[0][None, :] - 1.0))
        prior_rel_std = max(spread, 0.05) / np.sqrt(3.0)
    p0 = np.zeros(d)
    scale = 10.0 * np.abs(np.asarray(x, dtype=float)).reshape(-1, m, 2).max(axis=0)
    p0[: 2 * m] = (np.maximum(scale, 1e-12).reshape(-1)) ** 2
    p0[2 * m: 3 * m] = (prior_rel_std * w[0]) ** 2
    if damping:
        p0[3 * m:] = (0.5 * model.damping) ** 2
    return p0


def cell_pcrb(model: ModalModel, w, x, dt_s: float, noise_std: float, prior, *, rw_rel=None, u=None,
              prior_rel_std: float | None = None, damping: bool = True) -> np.ndarray:
    """The **genie** PCRB std (rad/s) of every frequency at every sample, per replicate: shape (R, N, m).

    The inputs ``u`` are known to it (no process noise on the oscillators); the bound that does not know a
    white force is ``experiments.simulate.pcrb_force.unknown_force_pcrb``; the two share the random walk
    (:func:`matched_walk_q`, or :func:`random_walk_q` with ``rw_rel``) and the prior, so the genie is the
    lower of the two everywhere. The prior of z_0
    (:func:`prior_covariance`): ω ~ N(prior, (s·ω/√3)²) with s the prior's spread (the uniform U(−s, s)'s
    variance; ``prior_rel_std`` gives s/√3 directly, default from the prior's distance to the truth, at least
    5 %/√3), ζ ~ N(ζ, (ζ/2)²), and the oscillators N(0, (10·max|x|)²): a tracker starts knowing nothing of
    the phase.
    """
    w = np.asarray(w, dtype=float)
    x = np.asarray(x, dtype=float)
    m = x.shape[2]
    F, H = jacobians(model, w, x, dt_s, u, damping=damping)
    d = F.shape[-1]
    q = matched_walk_q(w) if rw_rel is None else np.broadcast_to(random_walk_q(w, dt_s, rw_rel), w.shape)
    Q = np.zeros((w.shape[0], d, d))
    Q[:, np.arange(2 * m, 3 * m), np.arange(2 * m, 3 * m)] = q
    p0 = prior_covariance(model, w, x, prior, prior_rel_std=prior_rel_std, damping=damping)
    var = pcrb_covariance(F, H, Q, noise_std**2, np.diag(p0))
    return np.sqrt(np.maximum(var[:, :, 2 * m: 3 * m], 0.0))


def window_information(F, H, noise_var: float, ends: np.ndarray, width: int) -> np.ndarray:
    """The Fisher information of z at each window end from the ``width`` samples ending there, no prior, no
    process noise: J ← F̃⁻ᵀ J F̃⁻¹ + H̃ᵀH̃/σ² (one trajectory: F (N, d, d), H (N, d)); shape (len(ends), d, d)."""
    starts = np.asarray(ends) - width + 1
    if np.any(starts < 0):
        raise ValueError(f"a window of {width} samples ending at sample {int(np.min(ends))} starts before the record")
    finv = np.linalg.inv(F)
    J = H[starts][:, :, None] * H[starts][:, None, :] / noise_var
    for s in range(1, width):
        idx = starts + s
        a = finv[idx - 1]
        J = a.transpose(0, 2, 1) @ J @ a + H[idx][:, :, None] * H[idx][:, None, :] / noise_var
    return J


def _omega_std(J: np.ndarray, m: int) -> np.ndarray:
    """√[J⁻¹]ωω per window, from the diagonally scaled J (as crlb.py, through an SVD); inf if singular."""
    scale = np.sqrt(np.maximum(np.diagonal(J, axis1=1, axis2=2), 1e-300))
    Js = J / scale[:, :, None] / scale[:, None, :]
    u, s, vt = np.linalg.svd(Js)
    bad = s[:, -1] <= s[:, 0] * 1e-13
    cov = np.einsum("bji,bj,bjk->bik", vt, 1.0 / np.maximum(s, 1e-300), u.transpose(0, 2, 1))
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        var = np.diagonal(cov, axis1=1, axis2=2)[:, 2 * m: 3 * m] / scale[:, 2 * m: 3 * m] ** 2
        out = np.sqrt(np.abs(var))
    out[bad] = np.inf
    return out


def window_bound(model: ModalModel, w, x, dt_s: float, noise_std: float, *, ends=None, widths=None,
                 damping: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The best sliding window's bound (module docstring) on one trajectory ``x`` (N, m, 2).

    Returns
    -------
    ends : ndarray, shape (E,)
        The window ends (sample indices) it is evaluated at.
    bound : ndarray, shape (E, m)
        min over W of √(CRLB_W² + bias_W²), rad/s (inf where no window fits or determines the mode).
    """
    w = np.asarray(w, dtype=float)
    n, m = w.shape
    F, H = jacobians(model, w, np.asarray(x, dtype=float)[None], dt_s, damping=damping)
    F, H = F[0], H[0]
    if ends is None:
        ends = np.unique(np.linspace(n // 20, n - 1, 100).astype(int))
    ends = np.asarray(ends)
    if widths is None:
        widths = [2**p for p in range(5, 13) if 2**p <= n]
    csum = np.vstack([np.zeros((1, m)), np.cumsum(w, axis=0)])
    best = np.full((ends.size, m), np.inf)
    for width in widths:
        ok = ends - width + 1 >= 0
        if not ok.any():
            continue
        e = ends[ok]
        std = _omega_std(window_information(F, H, noise_std**2, e, width), m)
        bias = np.abs(w[e] - (csum[e + 1] - csum[e + 1 - width]) / width)
        best[ok] = np.minimum(best[ok], np.sqrt(std**2 + bias**2))
    return ends, best


def cell_window_bound(model: ModalModel, w, x, dt_s: float, noise_std: float) -> np.ndarray:
    """The window bound of replicate 0 as an (N, m) array, NaN between its evaluation times."""
    ends, best = window_bound(model, w, np.asarray(x[0], dtype=float), dt_s, noise_std)
    out = np.full(np.shape(w), np.nan)
    out[ends] = best
    return out
