"""``rpem_ambient``: Ljung's recursive prediction-error method on the innovation form of the modal model.

The modal model of ``akf_ambient`` (:mod:`methods.tracking._ambient`: oscillators (ξᵢ, ξ̇ᵢ) in tip units,
y = Σᵢ(−ωᵢ²ξᵢ − 2ζᵢωᵢξ̇ᵢ) + noise) under **any** stationary white excitation — one force or several, with or
without a direct term correlated with it — has the innovation form (Ljung 1999, §4.3)

    x̂(k+1) = Φ(θ) x̂(k) + K(θ) e(k),    y(k) = C(θ) x̂(k) + e(k),    e white, variance Λ,

with θ = [ω₁…ωₘ, ζ₁…ζₘ, K] and K (2m numbers) free: the family holds the true spectrum whatever the forces'
gains, which the extended Kalman filter's diagonal force model does not, and the prediction-error estimate
is asymptotically the maximum-likelihood one. (The EKF of the augmented state is moreover biased as a
parameter estimator because its gain's dependence on θ is ignored: Ljung, IEEE TAC 24(1), 1979; RPEM is
his fix.) K is scaled by the prior, Kᵢ = [k̃ᵢ₀/ω̄ᵢ², k̃ᵢ₁/ω̄ᵢ].

Per sample (Ljung & Söderström 1983, §3.7, the Gauss–Newton direction in Kalman form: θ walks at random
instead of a forgetting factor, so that its walk is the frequencies' stated rate):

    ŷ = C x̂,  e = y − ŷ,  ψ = ∂ŷ/∂θ = C W + (∂C/∂θ) x̂
    P⁻ = P + Q_θ;  S = ψᵀP⁻ψ + Λ;  L = P⁻ψ/S;  θ ← θ + L e;  P = P⁻ − L ψᵀ P⁻
    x̂ ← Φ x̂ + K e;  W ← (Φ − K C) W + (∂Φ/∂θ) x̂ + (∂K/∂θ) e − K (∂C/∂θ) x̂
    Λ ← Λ + (Δt/T) (e² − Λ)

W = ∂x̂/∂θ (2m × p), Φ and ∂Φ/∂ω in closed form (``methods.kalman.modal_transition``), ∂Φ/∂ζ by
complex step. Q_θ: (ν ωᵢ)²Δt on ωᵢ (ν = rate·√horizon, as ``akf_ambient``), and on ζᵢ, k̃ a walk whose spread
over the window is a tenth of their start's scale.

Start, restarts, pulses: as ``akf_ambient`` — the first window's periodogram gives the starting ω (its peaks),
q and r, from which K starts at the steady Kalman gain of the diagonal-force model
(``scipy.linalg.solve_discrete_are``) and the predictor is run over that window to start x̂; every hop the
periodogram's peaks are compared with ω̂ and a mode that disagrees ``restart_after`` times in a row restarts
at the peak; a sample whose e²/S exceeds ``pulse_gate`` does not update θ.

Written by hand: no maintained Python library has a recursive prediction-error method for a state-space
innovations model (filterpy has Kalman filters; padasip adaptive FIR/RLS filters).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from methods.estimate import make_options
from methods.kalman import modal_transition
from methods.tracking import _ambient
from methods.tracking._track import Track


@dataclass
class Options(_ambient.SharedOptions):
    """Options of ``rpem_ambient``: :class:`methods.tracking._ambient.SharedOptions` and

    Attributes
    ----------
    estimate_damping : bool
        ζᵢ are parameters (True, started at ``damping_ratio``) or held at ``damping_ratio``.
    """

    estimate_damping: bool = True


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None) -> Options:
    opts = make_options(Options, options, name)
    _ambient.check_shared(name, opts, prior, dt, n_samples)
    if not isinstance(opts.estimate_damping, bool):
        raise ValueError(f"{name}: estimate_damping = {opts.estimate_damping!r} must be true or false")
    return opts


def _phi_dzeta(w: np.ndarray, z: np.ndarray, dt: float) -> np.ndarray:
    """∂Φ/∂ζ per mode by complex step (exact to rounding)."""
    h = 1e-20
    return modal_transition(w, z + 1j * h, dt)[0].imag / h


def _steady_gain(w, z, dt, q, r):
    """Steady predictor gain of the diagonal-force model (Φ x + Γ w, y = Cx + v), (2m,)."""
    m = w.size
    F = np.zeros((2 * m, 2 * m))
    Q = np.zeros((2 * m, 2 * m))
    C = np.zeros((1, 2 * m))
    for i in range(m):
        ph, _ = modal_transition(w[i:i + 1], float(z[i]), dt)
        g = _ambient._gamma(ph, w[i:i + 1], float(z[i]))[0]
        F[2 * i:2 * i + 2, 2 * i:2 * i + 2] = ph[0]
        Q[2 * i:2 * i + 2, 2 * i:2 * i + 2] = q[i] * np.outer(g, g)
        C[0, 2 * i:2 * i + 2] = [-w[i] ** 2, -2 * z[i] * w[i]]
    P = scipy.linalg.solve_discrete_are(F.T, C.T, Q + 1e-30 * np.eye(2 * m), np.array([[r]]))
    return (F @ P @ C.T / (C @ P @ C.T + r)).ravel()


@dataclass
class _Run(_ambient._Run):
    """The ambient filter's run, and the damping ratios the recursion also estimates."""

    damping: np.ndarray = None


def rpem_filter(y: np.ndarray, dt: float, prior: np.ndarray, opts: Options) -> _Run:
    """The recursion of the module docstring over the record."""
    m, n = prior.size, y.size
    W_len, hop = _ambient._window_samples(opts, dt, prior)
    horizon = opts.horizon_s if opts.horizon_s is not None else W_len * dt
    nu2 = opts.rate_rel_per_s ** 2 * horizon
    est_z = bool(opts.estimate_damping)
    iw = np.arange(m)
    iz = np.arange(m, 2 * m) if est_z else np.arange(0)
    ik = np.arange(m + iz.size, m + iz.size + 2 * m)
    p = m + iz.size + 2 * m
    kscale = np.empty(2 * m)
    kscale[0::2], kscale[1::2] = 1 / prior ** 2, 1 / prior
    freq = np.full((n, m), np.nan)
    var = np.full((n, m), np.nan)
    damp = np.full((n, m), np.nan)
    started = np.zeros(n, dtype=bool)
    seen = np.zeros((n, m), dtype=bool)
    lo_w, hi_w = prior / (1 + opts.band), prior * (1 + opts.band)
    nyq = math.pi / dt
    hist_d: list[list[float]] = [[] for _ in range(m)]
    strikes = np.zeros(m, dtype=int)
    n_restarts = n_pulses = 0
    gam = dt / (W_len * dt)                     # innovation variance memory: one window
    if n < W_len:
        return _Run(freq, var, started, 0, 0, seen, damping=damp)

    def unpack(th):
        w = th[iw]
        z = th[iz] if est_z else np.full(m, opts.damping_ratio)
        return w, z, th[ik] * kscale

    # start: the first window's periodogram
    seg = y[:W_len]
    peak, r0, v0, _ = _ambient.periodogram_look(seg, dt, prior, opts.band, opts.damping_ratio)
    seen_now = np.isfinite(peak) & _ambient.visible(v0, r0, prior, opts.band, dt)
    w0 = np.where(np.isfinite(peak), peak, prior)
    if np.any(np.diff(w0) <= 0):
        w0 = prior.copy()
    z0 = np.full(m, opts.damping_ratio)
    q0 = np.maximum(4 * z0 * v0 / (w0 * dt), 1e-12 * max(r0, 1e-30))
    try:
        K0 = _steady_gain(w0, z0, dt, q0, max(r0, 1e-30))
    except (ValueError, np.linalg.LinAlgError):     # nothing to learn from (a flat window): the gain starts at 0
        K0 = np.zeros(2 * m)
    theta = np.concatenate([w0, z0 if est_z else [], K0 / kscale])
    P = np.zeros((p, p))
    P[iw, iw] = (0.01 * w0) ** 2
    if est_z:
        P[iz, iz] = (0.5 * z0) ** 2
    P[ik, ik] = np.maximum(0.3 * np.abs(theta[ik]), 0.05) ** 2
    Qth = np.zeros(p)
    Qth[iz] = (0.1 * 0.5 * z0) ** 2 / W_len if est_z else 0.0
    Qth[ik] = np.diag(P)[ik] * 0.01 / W_len
    # the predictor over the first window starts x̂
    w, z, K = unpack(theta)
    phi, _ = modal_transition(w, z, dt)
    C = np.column_stack([-w * w, -2 * z * w]).ravel()
    Fb = scipy.linalg.block_diag(*phi)
    x = np.zeros(2 * m)
    lam = float(np.var(seg))
    for k in range(W_len):
        e = y[k] - C @ x
        x = Fb @ x + K * e
        lam += gam * (e * e - lam)
    Wm = np.zeros((2 * m, p))
    for k in range(W_len, n):
        w, z, K = unpack(theta)
        phi, dphi = modal_transition(w, z, dt)
        C = np.column_stack([-w * w, -2 * z * w]).ravel()
        xi = x.reshape(m, 2)
        yh = C @ x
        e = y[k] - yh
        dC_x = np.zeros(p)
        dC_x[iw] = -2 * w * xi[:, 0] - 2 * z * xi[:, 1]
        if est_z:
            dC_x[iz] = -2 * w * xi[:, 1]
        psi = C @ Wm + dC_x
        theta_prev = theta
        Pm = P.copy()
        Pm[iw, iw] += nu2 * dt * w * w
        Pm[np.arange(p), np.arange(p)] += np.where(np.arange(p) >= m, Qth, 0.0)
        Ppsi = Pm @ psi
        S = float(psi @ Ppsi) + lam
        if not S > 0:                      # nothing seen yet (a zero record): no step
            P = Pm
        elif e * e > opts.pulse_gate * S:
            n_pulses += 1
            P = Pm
        else:
            L = Ppsi / S
            theta = theta + L * e
            P = Pm - np.outer(L, Ppsi)
            P = 0.5 * (P + P.T)
            lam += gam * (e * e - lam)
            theta[iw] = np.clip(theta[iw], lo_w, np.minimum(hi_w, nyq))
            if est_z:
                theta[iz] = np.clip(theta[iz], 1e-4, 0.2)
        # predictor and its sensitivities at θ(k−1)
        wp, zp, Kp = unpack(theta_prev)
        Fb = scipy.linalg.block_diag(*phi)
        M = np.zeros((2 * m, p))
        dxi = np.einsum("mab,mb->ma", dphi, xi)
        M[2 * iw, iw], M[2 * iw + 1, iw] = dxi[:, 0], dxi[:, 1]
        if est_z:
            dphz = _phi_dzeta(wp, zp, dt)
            dxz = np.einsum("mab,mb->ma", dphz, xi)
            M[2 * iw, iz], M[2 * iw + 1, iz] = dxz[:, 0], dxz[:, 1]
        M[np.arange(2 * m), ik] = kscale * e
        M -= np.outer(Kp, dC_x)
        Wm = (Fb - np.outer(Kp, C)) @ Wm + M
        x = Fb @ x + Kp * e
        # every hop: the periodogram's peaks against ω̂ (restarts, as akf_ambient)
        if (k + 1 - W_len) % hop == 0:
            ref = theta[iw].copy()
            peak, r_f, v_f, _ = _ambient.periodogram_look(y[k + 1 - W_len:k + 1], dt, ref, opts.band,
                                                          opts.damping_ratio)
            seen_now = np.isfinite(peak) & _ambient.visible(v_f, r_f, ref, opts.band, dt)
            d = np.log(peak / theta[iw])
            for i, s_i in _ambient.modes_to_restart(np.flatnonzero(np.isfinite(d)), d, np.ones(m), -np.inf, d,
                                                    strikes, hist_d, opts):
                theta[iw[i]] = peak[i]
                P[iw[i], :] = 0.0
                P[:, iw[i]] = 0.0
                P[iw[i], iw[i]] = (s_i * peak[i]) ** 2
                Wm[:, iw[i]] = 0.0
                n_restarts += 1
            if np.max(np.abs(np.linalg.eigvals(Fb - np.outer(Kp, C)))) >= 1.0:   # unstable predictor
                theta[ik] = K0 / kscale
                Wm[:] = 0.0
        started[k] = True
        seen[k] = seen_now
        freq[k] = theta[iw]
        var[k] = np.diag(P)[iw]
        damp[k] = theta[iz] if est_z else opts.damping_ratio
    return _Run(freq, var, started, n_restarts, n_pulses, seen, damping=damp)


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    opts = make_options(Options, options, name)
    out = rpem_filter(y, dt, prior, opts)
    k = np.flatnonzero(out.started)
    std = np.sqrt(np.clip(out.var[k], 0.0, None))
    return Track(k * dt, out.freq[k], std, out.seen[k] & (std <= _ambient.DETERMINED_REL_STD * out.freq[k]),
                 message=f"{name}: {out.n_restarts} restarts, {out.n_pulses} pulse samples",
                 extra={"n_restarts": out.n_restarts, "n_pulses": out.n_pulses, "damping": out.damping[k]})
