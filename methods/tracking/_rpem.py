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
over the window is a tenth of their start's scale. ``frequency_model="trend"`` appends each frequency's rate
ω̇ᵢ to θ and gives the time update a local linear trend, θ⁻ = Fθ (ωᵢ ← ωᵢ + Δt ω̇ᵢ), P⁻ = F P Fᵀ + Q_θ, θ ← θ⁻ + L e
(ω̇ᵢ's prior 0 ± rate·ω̄ᵢ, its walk (rate·ω̄ᵢ)²/``trend_horizon_s`` per s, as ``akf_ambient``'s ``trend``);
ψ's entries for ω̇ are 0 (x̂ does not depend on the rate within a step), so the rate learns through P.

Start, restarts, pulses: as ``akf_ambient`` — the first window's periodogram gives the starting ω (its peaks,
each with 1σ max(1 % ω, a quarter of the window's resolution 2π/T), as ``akf_ambient``'s start: five periods of
the slowest mode resolve a fifth of its ω, and its first peak is 3–12 % off on the benchmark's records),
q and r, from which K starts at the steady Kalman gain of the diagonal-force model
(``scipy.linalg.solve_discrete_are``) and the predictor is run over that window to start x̂; every hop the
periodogram's peaks are compared with ω̂ and a mode that disagrees ``restart_after`` times in a row restarts
at the peak; a sample whose e²/S exceeds ``pulse_gate`` does not update θ. With the rate (``"trend"``) the
peak, the frequency about the window's middle, is compared with ω̂ − ω̇ (W − 1)Δt/2, beyond ``akf_ambient``'s
floor (the window's resolution), so that a drift the filter follows is no disagreement; a restart resets the
mode's rate. With ``pair_peaks`` a mode whose band's maximum lies on its edge toward a neighbour takes the
largest other local maximum between the neighbour's peak and its far edge (the peaks of a close pair assigned
together), so that a stepped mode of the pair whose new peak lies beyond the midpoint of the two estimates
can still disagree and restart.

Two memories (``recursions="two"``, with the rate). A walk of ω over a horizon is a memory of that horizon: it lags
a drift less than a window does, but it forgets; a constant rate (ω's walk over one sample, Δt, and no walk
of ω̇) keeps the whole record, as the bound does, and cannot leave a step. So two recursions of the same model
run side by side on the same samples: the window-memory one above (its walks and restarts) and the
whole-record one, which is reported. Each keeps its one-step log-likelihood ℓ = ½(ln S + e²/S) per sample;
over the last window (the periodogram's, five periods of the slowest prior mode) their ratio
Λ_W = Σ (ℓ_whole − ℓ_window) is the log posterior odds of "the window recursion is right" at equal prior
odds. Every look:

* when Λ_W > ``restart_gate``²/2 (the signed root of the likelihood ratio, about N(0, 1) without a change,
  beyond ``restart_gate`` σ), each mode whose two estimates differ by more than ``reset_gate`` σ of their
  difference, |ω̂ᵢ − ω̂ᵢ'| > ``reset_gate`` √(Pᵢ + Pᵢ'), starts again in the whole-record recursion from the
  window recursion's ω, rate and their covariance (the interaction step of an interacting multiple model, made
  hard and per mode); its sensitivities to them start at 0;
* the reported variance is the mean square error of reporting the whole-record ω̂ under the two models'
  posterior, μ = 1/(1 + e^(−Λ_W)): (1 − μ) P + μ (P' + (ω̂ − ω̂')²) (the output step of an interacting multiple
  model, its mean kept at the whole-record recursion's).

With ``score_reset`` the per-mode part also asks the whole-record recursion itself which of its modes the
window contradicts: each ωᵢ's score over the last window (since that mode's last reset), zᵢ = Σ ψᵢe/S /
√(Σ ψᵢ²/S), about N(0, 1) while its ω̂ᵢ is right (e is then white, the score a martingale of that variance);
beyond ``reset_gate`` σ and pointing toward ω̂ᵢ', the mode is reset even when the two estimates are within
``reset_gate`` σ of their difference — a stepped mode the window recursion follows by its walk, which the
whole-record one would only creep after (the per-parameter score test of the local approach to change
detection: Benveniste, Basseville & Moustakides, IEEE TAC 32(7), 1987). A reset mode then takes ω̂ᵢ' and its
variance, and its rate starts again at 0 ± the stated rate, as a restart's does: after a step the window
recursion's rate holds the step's climb, which the whole-record recursion (no walk of the rate) would keep.

A test of the rates (``rate_test``, with ``score_reset``). The whole-record recursion models each frequency as a
line; a mode that does not move is then reported at a line's end point, whose variance is about four times
that of a constant fitted to the same samples (least squares over [0, T]: 4σ²/N against σ²/N), and its ω̂
wanders by its own score and the rate that score teaches (docs/measured/tracking_ambient.md: the slow mode 1 after
the benchmark's steps is this, the same with the step removed). Two nested models are averaged instead: the
rate free (the recursion's posterior) and the rate 0 (that posterior conditioned on ω̇ = 0, which for a
linear-Gaussian model is the rate-0 model's own posterior), weighted at equal prior odds by the Savage–Dickey
density ratio of the rate's posterior and prior at 0 — per mode (``"mode"``) or for every rate at once
(``"all"``: a change of mass moves every mode). The conditional keeps what the rate absorbed in the recursion:
the start's transient (a first peak 3–12 % off, linearised far from the truth) and a reset to a still-walking
estimate, which the rate-0 estimate then carries; on the design seeds from the start (``"mode"``, ``"all"``) it
wins the 100 µg steps and loses some drifts and the 1000 µg step. ``"after_change"`` tests the rates only from
the first look at which the reset gate opens (a record that never changes keeps its rates: every drift the
same), and is in the variant ``rpem_ambient:two`` (configs/tracker/rpem_ambient_two.yaml); the default stays
``"off"``.

A frequency error barely changes one sample's prediction under a white force (its own innovation dominates),
but summed over a window it does: in the 20 s after the benchmark's steps the window recursion is ahead by
16–155 nats over 10 s, on its drifts by at most 4.2 (design seeds 7 and 11, docs/measured/tracking_ambient.md).
filterpy's ``IMMEstimator`` mixes the states of Kalman filters of one state vector by a Markov chain of model
switches; a recursion here is (θ, P, x̂, W, Λ) stepped by a CasADi function, and a soft mix of two θ would blur a step's
before and after — so the interaction is a hard reset of the modes that disagree, and written here.

Written by hand: no maintained Python library has a recursive prediction-error method for a state-space
innovations model (filterpy has Kalman filters; padasip adaptive FIR/RLS filters). The per-sample step is one
CasADi SX function (:func:`_step_function`, its derivatives algorithmic), repeated between two looks with
``Function.mapaccum`` (the way ``methods.pem.predictor`` runs its Kalman predictor): the same arithmetic as
the numpy loop it replaced (tested against it step by step), a sixth of its CPU (some forty numpy calls per
sample cost 0.4–0.6 ms on this machine). The step is built once per process and (m, ζ estimated or not, rate or
not), in about 0.04 s.

Tried and not kept (each off by default, measured on design seeds only, then removed; the option and its
section's commands run at commit 681eb87, "measured at 681eb87"; sections of
docs/measured/tracking_ambient_tried.md):

* ``reset_peak``: a reset mode starts at the look's peak beyond the walking window estimate — "Mode 3 after the
  grid's step: a reset to the look's peak", measured at 681eb87;
* ``mode_gate``: each mode's own likelihood gain as a second gate — "What holds ``rpem_ambient:two`` after a step
  under a white force, and each mode's own gate", measured at 681eb87;
* ``reset_from="change"``: a reset back-dated to the estimated change time and re-run — "A reset back-dated to
  the change", measured at 681eb87;
* ``unresolved_start``: one bin's 1σ at the start for a pair closer than the Hann lobe — "The close pair on a
  drift: where its errors come from, and a start for a pair the first window cannot separate", measured at
  681eb87;
* ``gate="cusum"``: Page's CUSUM of the two recursions' log-likelihood increments as the reset gate — "After a
  step: the modes that did not step, and a gate that opens late", measured at 681eb87;
* ``second_pass``: the whole-record recursion run again once from its start — "A second pass over the start",
  measured at 681eb87;
* ``rate_zero="recursion"``: a third, constant-frequency recursion as the rate-0 model — "A third recursion with
  a constant frequency as the rate-0 model", measured at 681eb87;
* ``restart_scale="trimmed"``, ``restart_sigma="start"``: the window recursion's restart scale trimmed at half
  the gate, a restart's 1σ at least the start's — "The window recursion after a step: a scale the step
  inflates, a restart's σ", measured at 681eb87;
* ``restart_confirm``: a confirming restart below the one-bin floor — "A confirming restart of the window
  recursion", measured at 681eb87;
* ``start_look="era"``: the start's close pair from NExT + ERA on the first window — "The close pair from a
  parametric look", measured at 681eb87;
* ``change_search``: once the reset gate opens, the modes searched on the samples after it by the likelihood of
  the recursion's own innovation form — "A search of the modes after a change", measured at e3d3ca6;
* ``refit``: the whole-record recursion's ω refitted once a window by that likelihood — "That refit inside the
  tracker", measured at 16b0576 (the first section of docs/measured/tracking_ambient_tried.md holds both);
* ``change_refit``: at the first opening of the reset gate, every mode refitted as a constant over the samples
  before the last window by that likelihood, each kept where putting it back costs 8 nats — "A refit at the first
  change", measured at 016310c (the same section).
"""

from __future__ import annotations

import functools
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
    frequency_model : str
        ``"walk"`` (default): ωᵢ walks at random; ``"trend"``: θ also carries each frequency's rate ω̇ᵢ, a local
        linear trend in the parameters' time update (module docstring).
    trend_horizon_s : float or None
        ``"trend"``: the rate may change by the stated rate over this horizon (as ``akf_ambient``'s); None: ten
        windows.
    recursions : str
        ``"one"`` (default): the recursion above, its walks' memory a horizon; ``"two"``: beside it a
        recursion of the same model whose frequencies have a constant rate (ω's walk over one sample, no walk
        of the rate), a memory of the whole record since its last reset, which it reports; a mode of it starts
        again from the window-memory recursion's ω and rate when the window's likelihood ratio favours that
        one and the two disagree (module docstring). Needs ``frequency_model="trend"``.
    reset_gate : float
        ``recursions="two"``: a mode is reset when the two recursions' ω̂ differ by more than this many σ of their
        difference (√(P + P'), both recursions' own variances), once the likelihood ratio has said that the
        window recursion predicts the last window better.
    score_reset : bool
        ``recursions="two"``: once the likelihood ratio has opened the gate, a mode is also reset when the
        whole-record recursion's score of its ω over the last window, Σψᵢe/S over √(Σψᵢ²/S), is beyond
        ``reset_gate`` σ and points toward the window recursion's ω̂ᵢ' (a mode that creeps after a step), and a
        reset mode's rate starts again at 0 ± the stated rate (module docstring).
    pair_peaks : bool
        The looks assign a close pair's peaks together: a mode whose search band's maximum lies on its edge
        toward a neighbour (the geometric midpoint of the two estimates) takes the largest other local maximum
        between the neighbour's peak and its far edge (:func:`methods.tracking._ambient._pair_edge_peaks`),
        instead of no peak. After a step of a close pair the stepped mode's new peak can lie beyond that
        midpoint, and the mode would not restart until its walk had carried it there. Measured with
        ``recursions="two"``; with one recursion it loses on the drifts (docs/measured/tracking_ambient.md).
    rate_test : str
        ``"off"`` (default); with ``score_reset``, ``"mode"``: the reported ω̂ᵢ of the whole-record recursion is
        the average of two nested models, its rate free (the recursion's ω̂ᵢ, Pᵢ) and its rate 0 (the same
        posterior conditioned on ω̇ᵢ = 0), weighted by their posterior probabilities at equal prior odds — the
        Savage–Dickey density ratio of the rate's posterior and prior at 0 (:func:`_zero_rate_average`);
        ``"all"``: one such test of every rate at once (the structure drifts or it does not: a change of mass
        moves every mode). A mode that does not drift is then reported with the variance of a constant
        frequency instead of the ~4× of a line's end point (module docstring); ``"after_change"``: as
        ``"mode"``, from the first look at which the last window's likelihood ratio opens the reset gate (Λ_W >
        ``restart_gate``²/2: the record has changed, so every mode's rate since the start is in doubt), the
        whole-record recursion's ω̂ before it — a record that never opens the gate keeps its rates.
    """

    estimate_damping: bool = True
    frequency_model: str = "walk"
    trend_horizon_s: float | None = None
    recursions: str = "one"
    reset_gate: float = 3.0
    score_reset: bool = False
    pair_peaks: bool = False
    rate_test: str = "off"


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None) -> Options:
    opts = make_options(Options, options, name)
    _ambient.check_shared(name, opts, prior, dt, n_samples)
    for field in ("estimate_damping", "score_reset", "pair_peaks"):
        if not isinstance(getattr(opts, field), bool):
            raise ValueError(f"{name}: {field} = {getattr(opts, field)!r} must be true or false")
    for field, allowed in (("frequency_model", ("trend", "walk")), ("recursions", ("one", "two")),
                           ("rate_test", ("off", "mode", "all", "after_change"))):
        if getattr(opts, field) not in allowed:
            raise ValueError(f"{name}: {field} = {getattr(opts, field)!r} must be {' or '.join(map(repr, allowed))}")
    if opts.rate_test != "off" and not opts.score_reset:
        raise ValueError(f"{name}: rate_test = {opts.rate_test!r} needs score_reset = true (got {opts.score_reset!r})")
    if opts.score_reset and opts.recursions != "two":
        raise ValueError(f"{name}: score_reset = true needs recursions = 'two' (got {opts.recursions!r})")
    if opts.recursions == "two" and opts.frequency_model != "trend":
        raise ValueError(f"{name}: recursions = 'two' needs frequency_model = 'trend' (got {opts.frequency_model!r})")
    g = opts.reset_gate
    if isinstance(g, bool) or not (isinstance(g, (int, float)) and math.isfinite(g) and g > 0):
        raise ValueError(f"{name}: reset_gate = {g!r} must be a positive number")
    h = opts.trend_horizon_s
    if h is not None and not (isinstance(h, (int, float)) and math.isfinite(h) and h >= dt):
        raise ValueError(f"{name}: trend_horizon_s = {h!r} must be None or at least one sample ({dt} s)")
    return opts


# The starting 1σ of each ω, as a share of the first window's Fourier resolution (``akf_ambient``'s start and
# restarts, :func:`methods.tracking._ambient._restart`).
START_RESOLUTION_SHARE = 0.25

_H = 1e-20      # the complex step in ζ: f(ζ + ih) = f(ζ) + ih f'(ζ) + O(h²), exact to rounding at this h


def _transitions(w: np.ndarray, z: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Φ, ∂Φ/∂ω and ∂Φ/∂ζ per mode, (m, 2, 2) each, from one complex-step call of ``modal_transition``
    (the real parts are Φ and ∂Φ/∂ω to rounding, the imaginary part of Φ over h is ∂Φ/∂ζ)."""
    phi, dphi = modal_transition(w, z + 1j * _H, dt)
    return phi.real, dphi.real, phi.imag / _H


def _blocks_times(phi: np.ndarray, X: np.ndarray) -> np.ndarray:
    """blockdiag(Φ₁…Φₘ) @ X for X of 2m rows (a vector or a matrix), without forming the block matrix."""
    m = phi.shape[0]
    return np.einsum("mab,mb...->ma...", phi, X.reshape((m, 2) + X.shape[1:])).reshape(X.shape)


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


def _sx_transition(w, z, dt):
    """Φ of one oscillator (``methods.kalman.modal_transition``'s closed form), for CasADi symbols."""
    import casadi as ca  # only the symbolic step needs it (the caller imports it too)

    r = ca.sqrt(1 - z * z)
    e, c, s = ca.exp(-z * w * dt), ca.cos(w * r * dt), ca.sin(w * r * dt)
    return ca.vertcat(ca.horzcat(e * (c + z / r * s), e * s / (w * r)),
                      ca.horzcat(-e * w * s / r, e * (c - z / r * s)))


@functools.lru_cache(maxsize=8)
def _step_function(m: int, est_z: bool, trend: bool = False):
    """One sample of the recursion (module docstring) as a CasADi SX function, its derivatives algorithmic:

        (state, y(k), const) ↦ (state', [ω̂; P_ωω; ζ̂; ψe/S; ψ²/S; (ω̇; vec P_ωω̇; vec P_ω̇ω̇); ½(ln S + e²/S); pulse]),
        state = [θ, vec P, x̂, vec W, Λ] (the ω̇ rows with the rate only),
        const = [Δt, ν²·horizon, Δt/T, pulse_gate, ζ, k̃ scale (2m), Q_θ (ω entries 0), ω low (m), ω high (m)].

    ∂Φ/∂θ, ∂K/∂θ and ∂C/∂θ are ``casadi.jacobian`` of Φ(θ)x̂ + K(θ)ε and C(θ)x̂ with x̂ and ε held (the
    closed forms ``modal_transition`` and the complex step give, to rounding). The branches of the numpy
    loop (no step while S ≤ 0; a pulse: no update of θ and Λ) are ``if_else``.
    """
    import casadi as ca  # 0.2 s of start-up, paid only by this tracker, once per process (cached)

    nz = m if est_z else 0
    na = m if trend else 0
    p = 3 * m + nz + na
    n_state = p + p * p + 2 * m + 2 * m * p + 1
    st, yk = ca.SX.sym("state", n_state), ca.SX.sym("y")
    c = ca.SX.sym("const", 5 + 2 * m + p + 2 * m)
    dt, nu2, gam, gate, zeta0 = c[0], c[1], c[2], c[3], c[4]
    kscale, q_fixed = c[5:5 + 2 * m], c[5 + 2 * m:5 + 2 * m + p]
    lo_w, hi_w = c[5 + 2 * m + p:5 + 3 * m + p], c[5 + 3 * m + p:5 + 4 * m + p]
    th = st[:p]
    P = ca.reshape(st[p:p + p * p], p, p)
    x = st[p + p * p:p + p * p + 2 * m]
    W = ca.reshape(st[p + p * p + 2 * m:n_state - 1], 2 * m, p)
    lam = st[n_state - 1]
    w = th[:m]
    z = th[m:2 * m] if est_z else ca.repmat(zeta0, m, 1)
    K = th[m + nz:3 * m + nz] * kscale
    C = ca.vertcat(*[v for i in range(m) for v in (-w[i] * w[i], -2 * z[i] * w[i])])
    Cx = ca.dot(C, x)
    e = yk - Cx
    psi = (ca.mtimes(C.T, W) + ca.jacobian(Cx, th)).T
    q = ca.diag(ca.vertcat(nu2 * dt * w * w, q_fixed[m:]))
    if trend:       # θ's time update: ω ← ω + Δt ω̇ (the rest held), P ← F P Fᵀ + Q
        F = ca.SX.eye(p)
        for i in range(m):
            F[i, 3 * m + nz + i] = dt
        th_pred = ca.mtimes(F, th)
        Pm = ca.mtimes(ca.mtimes(F, P), F.T) + q
    else:
        th_pred, Pm = th, P + q
    Ppsi = ca.mtimes(Pm, psi)
    S = ca.dot(psi, Ppsi) + lam
    ok = ca.logic_and(S > 0, e * e <= gate * S)
    pulse = ca.logic_and(S > 0, e * e > gate * S)
    L = Ppsi / ca.if_else(S > 0, S, 1)
    th_up = th_pred + L * e
    th_up = ca.vertcat(ca.fmin(ca.fmax(th_up[:m], lo_w), hi_w),
                       ca.fmin(ca.fmax(th_up[m:m + nz], 1e-4), 0.2), th_up[m + nz:])
    P_up = Pm - ca.mtimes(L, Ppsi.T)
    P_up = 0.5 * (P_up + P_up.T)
    th_new = ca.if_else(ok, th_up, th_pred)
    P_new = ca.if_else(ok, P_up, Pm)
    lam_new = ca.if_else(ok, lam + gam * (e * e - lam), lam)
    # the predictor and its sensitivities at θ(k−1): W ← Φ W − K ψ + (∂Φ/∂θ)x̂ + (∂K/∂θ)ε
    es = ca.SX.sym("e")
    blocks = [_sx_transition(w[i], z[i], dt) for i in range(m)]
    Phi = ca.diagcat(*blocks)
    nxt = ca.mtimes(Phi, x) + K * es
    M = ca.substitute(ca.jacobian(nxt, th), es, e)
    W_new = ca.mtimes(Phi, W) - ca.mtimes(K, psi.T) + M
    x_new = ca.substitute(nxt, es, e)
    state = ca.vertcat(th_new, ca.vec(P_new), x_new, ca.vec(W_new), lam_new)
    nll = 0.5 * (ca.log(ca.if_else(S > 0, S, 1)) + e * e / ca.if_else(S > 0, S, 1))
    # each frequency's score ψᵢe/S and Fisher information ψᵢ²/S of this sample (0 on a pulse)
    s_safe = ca.if_else(S > 0, S, 1)
    score = ca.if_else(ok, psi[:m] * e / s_safe, ca.SX.zeros(m))
    info = ca.if_else(ok, psi[:m] * psi[:m] / s_safe, ca.SX.zeros(m))
    # with the rate (``rate_test``): the rates, the block P_ωω̇ and the block P_ω̇ω̇ (column-major)
    ia = list(range(3 * m + nz, 3 * m + nz + na))
    rate = [th_new[ia], ca.vec(P_new[:m, ia]), ca.vec(P_new[ia, ia])] if trend else []
    out = ca.vertcat(th_new[:m], ca.diag(P_new)[:m], th_new[m:m + nz], score, info, *rate, nll, pulse)
    return ca.Function("rpem_step", [st, yk, c], [state, out])


@functools.lru_cache(maxsize=32)
def _run_function(m: int, est_z: bool, trend: bool, n_samples: int):
    """:func:`_step_function` repeated over ``n_samples`` samples (``Function.mapaccum``): one call per hop
    instead of some forty numpy calls per sample, which cost 0.4–0.6 ms per sample on this machine."""
    return _step_function(m, est_z, trend).mapaccum("rpem_run", n_samples)


@dataclass
class _Run(_ambient._Run):
    """The ambient filter's run, and the damping ratios the recursion also estimates."""

    damping: np.ndarray = None
    n_resets: int = 0
    reset_times_s: tuple = ()


def _start_again(theta: np.ndarray, P: np.ndarray, W: np.ndarray, idx, value, cov) -> None:
    """The parameters ``idx`` of one recursion start again, in place: θ[idx] = ``value``, their covariance with
    every other parameter and their sensitivities W 0, their own block of P ``cov`` (a block, or the variances of a
    diagonal one) — a restart or a reset."""
    idx = np.atleast_1d(np.asarray(idx, dtype=int))
    cov = np.asarray(cov, dtype=float)
    theta[idx] = value
    P[idx, :] = 0.0
    P[:, idx] = 0.0
    P[np.ix_(idx, idx)] = cov if cov.ndim == 2 else np.diag(np.broadcast_to(cov, idx.shape))
    W[:, idx] = 0.0


def _advance(m: int, est_z: bool, trend: bool, filt, y_seg: np.ndarray, const: np.ndarray):
    """One mapaccum call of the recursion over ``y_seg``: (θ, P, x̂, W, Λ) of ``filt`` after it, and the
    per-sample outputs (ω̂; P_ωω; ζ̂; pulse) as rows."""
    theta, P, x, Wm, lam = filt
    p = theta.size
    state = np.concatenate([theta, P.ravel(), x, Wm.ravel(order="F"), [lam]])
    state, out = _run_function(m, est_z, trend, y_seg.size)(state, y_seg[None, :], const)
    state = np.asarray(state)[:, -1]
    return (state[:p].copy(), state[p:p + p * p].reshape(p, p).copy(), state[p + p * p:p + p * p + 2 * m].copy(),
            state[p + p * p + 2 * m:-1].reshape((2 * m, p), order="F").copy(), float(state[-1]), np.asarray(out))


def _unstable(wzk, dt: float) -> bool:
    """The predictor Φ − K C at (ω, ζ, K) has an eigenvalue on or outside the unit circle."""
    w, z, K = wzk
    phi, _ = modal_transition(w, z, dt)
    C = np.column_stack([-w * w, -2 * z * w]).ravel()
    return bool(np.max(np.abs(np.linalg.eigvals(scipy.linalg.block_diag(*phi) - np.outer(K, C)))) >= 1)


def _variance_two(w_long, v_long, w_win, v_win, odds):
    """``recursions="two"``: the reported variance of the whole-record recursion's ω̂ under the two recursions'
    posterior, as an interacting multiple model weighs them: equal prior odds and the last window's likelihood
    ratio ``odds`` = Σ (ℓ_long − ℓ_window) give the window recursion the probability μ = 1/(1 + e^(−odds)),
    and the mean square error of reporting ω̂ is (1 − μ) P + μ (P' + (ω̂ − ω̂')²). Rows are samples (``odds``
    one per row), or one sample."""
    mu = 1.0 / (1.0 + np.exp(-np.clip(odds, -50.0, 50.0)))
    mu = mu[:, None] if np.ndim(mu) else mu
    return (1 - mu) * v_long + mu * (v_win + (w_long - w_win) ** 2)


def _zero_rate_average(w, v, a, v_wa, v_aa, prior_var, joint: bool = False):
    """``rate_test``: the reported (ω̂, variance) of each mode averaged over two nested models, the rate free and
    the rate 0, from the rate model's Gaussian posterior: ω̂ and its variance ``v`` (…, m), the rates ``a``
    (…, m), the blocks P_ωω̇ ``v_wa`` and P_ω̇ω̇ ``v_aa`` (…, m, m), the rates' prior N(0, diag ``prior_var``).

    The rate-0 model's posterior is the rate model's conditioned on ω̇ = 0 (for a linear-Gaussian model with
    independent priors the two are the same): ω̂₀ = ω̂ − P_ωω̇ P_ω̇ω̇⁻¹ ω̇, V₀ = P_ωω − P_ωω̇ P_ω̇ω̇⁻¹ P_ω̇ω. Its
    Bayes factor against the rate model is the Savage–Dickey density ratio (Dickey, Ann. Math. Stat. 42(1),
    1971) of the rates' posterior and prior at 0, B = N(0; ω̇, P_ω̇ω̇)/N(0; 0, prior), so at equal prior odds
    μ₀ = B/(1 + B), and the average is ω̄ = μ₀ω̂₀ + (1 − μ₀)ω̂ with the mixture's variance
    μ₀(V₀ + (ω̂₀ − ω̄)²) + (1 − μ₀)(P_ωω + (ω̂ − ω̄)²). Per mode (``joint`` False: each mode's own rate, the
    diagonals of the blocks) or every rate at once (``joint``: one B and μ₀ for all modes). A rate block that
    is not positive definite leaves the modes as they are."""
    a = np.asarray(a, dtype=float)
    v_wa, v_aa = np.asarray(v_wa, dtype=float), np.asarray(v_aa, dtype=float)
    if joint:
        sign, logdet = np.linalg.slogdet(v_aa)
        ok = sign > 0
        v_aa = np.where(ok[..., None, None], v_aa, np.eye(a.shape[-1]))
        gain_t = np.linalg.solve(v_aa, np.swapaxes(v_wa, -1, -2))          # (P_ωω̇ P_ω̇ω̇⁻¹)ᵀ
        w0 = w - np.einsum("...ji,...j->...i", gain_t, a)
        v0 = v - np.einsum("...ji,...ij->...i", gain_t, v_wa)
        log_b = (0.5 * np.sum(np.log(prior_var)) - 0.5 * np.where(ok, logdet, 0.0)
                 - 0.5 * np.einsum("...i,...i->...", a, np.linalg.solve(v_aa, a[..., None])[..., 0]))
        mu0 = np.where(ok, 1.0 / (1.0 + np.exp(-np.clip(log_b, -50.0, 50.0))), 0.0)[..., None]
    else:
        d_wa = np.diagonal(v_wa, axis1=-2, axis2=-1)
        d_aa = np.diagonal(v_aa, axis1=-2, axis2=-1)
        ok = d_aa > 0
        d_aa = np.where(ok, d_aa, 1.0)
        log_b = 0.5 * np.log(prior_var / d_aa) - 0.5 * a * a / d_aa
        mu0 = np.where(ok, 1.0 / (1.0 + np.exp(-np.clip(log_b, -50.0, 50.0))), 0.0)
        w0 = w - d_wa / d_aa * a
        v0 = v - d_wa * d_wa / d_aa
    v0 = np.maximum(v0, 0.0)
    w_bar = mu0 * w0 + (1 - mu0) * w
    return w_bar, mu0 * (v0 + (w0 - w_bar) ** 2) + (1 - mu0) * (v + (w - w_bar) ** 2)


def _reset_from_window(long: list, theta: np.ndarray, P: np.ndarray, iw, ia, gain: float, opts,
                       z_score: np.ndarray | None = None, rate_var: np.ndarray | None = None) -> np.ndarray:
    """``recursions="two"``: modes of the whole-record recursion ``long`` ([θ, P, x̂, W, Λ], changed in place)
    start again from the window-memory recursion's (θ, P) when the window recursion predicts the last window
    better, by a log-likelihood ratio ``gain`` = Σ (ℓ_long − ℓ_window) > ``restart_gate``²/2 (its signed root,
    about N(0, 1) without a change, beyond ``restart_gate``), and only the modes where the two disagree,
    |ω̂ᵢ − ω̂ᵢ'| > ``reset_gate`` √(Pᵢ + Pᵢ'): their ω and rate and their covariance become the window
    recursion's, their sensitivities 0.

    ``score_reset`` (``z_score``, the whole-record recursion's score of each ωᵢ over the last window in σ, and
    ``rate_var``, the rates' prior variance): a mode is also reset when its score is beyond ``reset_gate`` σ
    and points toward the window recursion's ω̂ᵢ', and a reset mode takes only the window recursion's ω and
    its variance; its rate starts again at 0 ± the stated rate, as a restart does (the window recursion's rate
    after a step holds the step's climb). Returns the modes reset."""
    th_l, P_l, W_l = long[0], long[1], long[3]
    gap = th_l[iw] - theta[iw]
    if gain > 0.5 * opts.restart_gate ** 2:
        far = np.abs(gap) > opts.reset_gate * np.sqrt(np.diag(P_l)[iw] + np.diag(P)[iw])
        if z_score is not None:
            far |= (np.abs(z_score) > opts.reset_gate) & (z_score * gap < 0)
    else:
        far = np.zeros(iw.size, dtype=bool)
    modes = np.flatnonzero(far)
    for i in modes:
        j = np.array([iw[i], ia[i]])
        if z_score is None:
            _start_again(th_l, P_l, W_l, j, theta[j], P[np.ix_(j, j)])
        else:
            _start_again(th_l, P_l, W_l, j, (theta[iw[i]], 0.0), (P[iw[i], iw[i]], rate_var[i]))
    return modes


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
    trend = opts.frequency_model == "trend"
    ia = np.arange(3 * m + iz.size, 4 * m + iz.size) if trend else np.arange(0)
    p = m + iz.size + 2 * m + ia.size
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
    n_restarts = n_pulses = n_resets = 0
    reset_times: list[tuple[float, int]] = []      # (s, mode) of each reset of the whole-record recursion
    resolution = 2 * math.pi / (W_len * dt) if trend else 0.0
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
    theta = np.concatenate([w0, z0 if est_z else [], K0 / kscale, np.zeros(ia.size)])
    P = np.zeros((p, p))
    # the first window's peak is as uncertain as akf_ambient's start says: 1σ max(1 % ω, resolution/4), the
    # window's Fourier resolution 2π/T (a fifth of the slowest mode's ω at five of its periods)
    P[iw, iw] = np.maximum(0.01 * w0, START_RESOLUTION_SHARE * 2 * math.pi / (W_len * dt)) ** 2
    if est_z:
        P[iz, iz] = (0.5 * z0) ** 2
    P[ik, ik] = np.maximum(0.3 * np.abs(theta[ik]), 0.05) ** 2
    Qth = np.zeros(p)
    Qth[iz] = (0.1 * 0.5 * z0) ** 2 / W_len if est_z else 0.0
    Qth[ik] = np.diag(P)[ik] * 0.01 / W_len
    # the rate's prior spread is the stated rate; its walk lets it change by that much over the trend horizon
    rate_var = (opts.rate_rel_per_s * prior[:ia.size]) ** 2
    trend_h = opts.trend_horizon_s if opts.trend_horizon_s is not None else 10 * W_len * dt
    P[ia, ia] = rate_var
    Qth[ia] = rate_var * dt / trend_h
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
    q_fixed = np.where(np.arange(p) >= m, Qth, 0.0)     # Q_θ's diagonal; the ω entries follow ω per sample
    const = np.concatenate([[dt, nu2, gam, opts.pulse_gate, opts.damping_ratio], kscale, q_fixed, lo_w,
                            np.minimum(hi_w, nyq)])
    two = opts.recursions == "two"
    cum = np.zeros(n + 1) if two else None   # Σ (ℓ_long − ℓ_window) up to each sample, ℓ = ½(ln S + e²/S)
    cum_s = np.zeros((n + 1, m)) if two else None     # the whole-record recursion's Σ ψᵢe/S and Σ ψᵢ²/S
    cum_i = np.zeros((n + 1, m)) if two else None
    since = np.full(m, W_len)                         # its modes' last reset (sample)
    tested = opts.rate_test in ("mode", "all")        # the rates tested (``"after_change"``: from a change on)
    if two:     # the whole-record memory: ω walks over one sample, the rate does not walk
        q_long = q_fixed.copy()
        q_long[ia] = 0.0
        const_long = const.copy()
        const_long[1] = opts.rate_rel_per_s ** 2 * dt
        const_long[5 + 2 * m:5 + 2 * m + p] = q_long
        long = [theta.copy(), P.copy(), x.copy(), Wm.copy(), lam]
    j0 = 2 * m + iz.size        # the step's output rows of the ω scores Σ ψᵢe/S, then of their information
    k0 = W_len
    while k0 < n:
        # the samples up to the next look (k + 1 − W a multiple of the hop), one mapaccum call
        k1 = min(n, k0 + (W_len - 1 - k0) % hop + 1)
        theta, P, x, Wm, lam, out = _advance(m, est_z, trend, (theta, P, x, Wm, lam), y[k0:k1], const)
        freq[k0:k1], var[k0:k1] = out[iw].T, out[m + iw].T
        if two:     # the whole-record recursion over the same samples; it is the one reported
            ell_win = out[-2]
            *long, out = _advance(m, est_z, trend, long, y[k0:k1], const_long)
            cum[k0 + 1:k1 + 1] = cum[k0] + np.cumsum(out[-2] - ell_win)
            cum_s[k0 + 1:k1 + 1] = cum_s[k0] + np.cumsum(out[j0:j0 + m].T, axis=0)
            cum_i[k0 + 1:k1 + 1] = cum_i[k0] + np.cumsum(out[j0 + m:j0 + 2 * m].T, axis=0)
            ks = np.arange(k0 + 1, k1 + 1)
            odds = cum[ks] - cum[np.maximum(ks - W_len, W_len)]          # over the last window
            w_l, v_l = out[iw].T, out[m + iw].T
            if tested:
                j1 = j0 + 2 * m
                blocks = out[j1 + m:j1 + m + 2 * m * m].T.reshape(-1, 2, m, m).swapaxes(-1, -2)   # column-major
                w_l, v_l = _zero_rate_average(w_l, v_l, out[j1:j1 + m].T, blocks[:, 0], blocks[:, 1], rate_var,
                                              opts.rate_test == "all")
            var[k0:k1] = _variance_two(w_l, v_l, freq[k0:k1], var[k0:k1], odds)
            freq[k0:k1] = w_l
        damp[k0:k1] = out[2 * m + iw].T if est_z else opts.damping_ratio
        n_pulses += int(np.sum(out[-1]))
        started[k0:k1] = True
        seen[k0:k1] = seen_now
        k = k1 - 1
        k0 = k1
        # every hop: the periodogram's peaks against ω̂ (restarts, as akf_ambient)
        if (k + 1 - W_len) % hop == 0:
            # the predictor at the look's θ (before restarts) must be stable, else K starts again
            unstable = _unstable(unpack(theta), dt)
            ref = theta[iw].copy()
            peak, r_f, v_f, _ = _ambient.periodogram_look(y[k + 1 - W_len:k + 1], dt, ref, opts.band,
                                                          opts.damping_ratio, pair_edges=opts.pair_peaks)
            seen_now = np.isfinite(peak) & _ambient.visible(v_f, r_f, ref, opts.band, dt)
            # the peak is the window's frequency, about its middle: with a rate in θ, ω̂ is carried back there
            # (ω̂ − ω̇ (W − 1)Δt/2), so that a drift it follows is no disagreement
            at_mid = theta[iw] - theta[ia] * (W_len - 1) * dt / 2 if trend else theta[iw]
            d = np.log(peak / at_mid)
            todo = _ambient.modes_to_restart(np.flatnonzero(np.isfinite(d)), peak - at_mid, at_mid,
                                             resolution, d, strikes, hist_d, opts)
            for i, s_i in todo:
                sd = s_i * peak[i]      # 1σ: the running robust scale of the mode's agreeing disagreements
                v = sd * sd
                if trend:                  # its rate starts again at 0 ± the stated rate
                    _start_again(theta, P, Wm, (iw[i], ia[i]), (peak[i], 0.0), (v, rate_var[i]))
                else:
                    _start_again(theta, P, Wm, iw[i], peak[i], v)
                n_restarts += 1
            if unstable:
                theta[ik] = K0 / kscale
                Wm[:] = 0.0
            if two:
                gain = float(odds[-1])      # the gate: the last window's likelihood ratio
                z_score = None
                if opts.score_reset:    # each ω's score over the last window (since its last reset), in σ
                    a = np.maximum(since, k + 1 - W_len)
                    info = cum_i[k + 1] - cum_i[a, iw]
                    s_sum = cum_s[k + 1] - cum_s[a, iw]
                    z_score = s_sum / np.sqrt(np.where(info > 0, info, np.inf))
                nr = _reset_from_window(long, theta, P, iw, ia, gain, opts, z_score, rate_var)
                since[nr] = k + 1
                n_resets += nr.size
                reset_times += [(k * dt, int(i)) for i in nr]
                if _unstable(unpack(long[0]), dt):
                    long[0][ik] = K0 / kscale
                    long[3][:] = 0.0
            seen[k] = seen_now
            freq[k], var[k] = theta[iw], np.diag(P)[iw]
            if two:
                w_l, v_l = long[0][iw], np.diag(long[1])[iw]
                if opts.rate_test == "after_change" and gain > 0.5 * opts.restart_gate ** 2:
                    tested = True       # from this look on
                if tested:
                    w_l, v_l = _zero_rate_average(w_l, v_l, long[0][ia], long[1][np.ix_(iw, ia)],
                                                  long[1][np.ix_(ia, ia)], rate_var, opts.rate_test == "all")
                var[k] = _variance_two(w_l, v_l, freq[k], var[k], gain)
                freq[k] = w_l
            th_out = long[0] if two else theta
            damp[k] = th_out[iz] if est_z else opts.damping_ratio
    return _Run(freq, var, started, n_restarts, n_pulses, seen, damping=damp, n_resets=n_resets,
                reset_times_s=tuple(reset_times))


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    opts = make_options(Options, options, name)
    out = rpem_filter(y, dt, prior, opts)
    k = np.flatnonzero(out.started)
    std = np.sqrt(np.clip(out.var[k], 0.0, None))
    return Track(k * dt, out.freq[k], std, out.seen[k] & (std <= _ambient.DETERMINED_REL_STD * out.freq[k]),
                 message=f"{name}: {out.n_restarts} restarts, {out.n_resets} resets, {out.n_pulses} pulse samples",
                 extra={"n_restarts": out.n_restarts, "n_resets": out.n_resets, "reset_times_s": out.reset_times_s,
                        "n_pulses": out.n_pulses, "damping": out.damping[k]})
