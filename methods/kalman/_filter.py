"""The identification model of eq. (8) and the extended Kalman filter shared by ``akf`` and ``wkf``.

State of the augmented model (eqs. 8, 21), for m modes::

    x = [q_1..q_m, q̇_1..q̇_m, ω_1..ω_m, drift..., x_f...]

* modal states: q̈_n = −ω_n² q_n − 2ζ ω_n q̇_n (eq. 7; the printed eq. (8) has +ω², a typo). The tip
  mode-shape values W_n(L) of eqs. (9)–(10) are unknown to a method that never sees the truth, so the
  measurement has unit gains and q_n is the *tip* displacement of mode n (W_n(L) absorbed into q_n).
* frequency states: random walks ω(k+1) = ω(k) + w₂(k) (eq. 21).
* drift states, position measurement only: [c, v, b], the integration constants and the accelerometer
  bias that the double integration turns into c + v·t + b·t²/2 (b alone for acceleration).
* weighting-filter states x_f (``wkf`` only): x_f(k+1) = φ_f x_f(k) + Δ_f h(x(k)) (eqs. 26–27).

The linear modal part is discretised exactly, Φ_n = expm(A_n Δt), and the Jacobian of the transition
with respect to ω_n uses the exact derivative ∂Φ_n/∂ω_n (the Fréchet derivative of expm in the
direction ∂A_n/∂ω_n), both in closed form for the 2×2 oscillator block (checked against
``scipy.linalg.expm`` / ``expm_frechet`` in the tests). The filter is filterpy's
``ExtendedKalmanFilter``, whose update is in Joseph form; the covariance is re-symmetrised each step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.signal
from filterpy.kalman import ExtendedKalmanFilter

from methods.estimate import Estimate, check_inputs, failed, flat_record, relative_option

MEASUREMENTS = ("position", "acceleration")

# Relative 1σ of a prior frequency when ``p0_frequency_var`` is None: P0 = (0.27·ω̄_n)². §4.1 assumes the
# frequencies "known with an uncertainty of approximately 30 %"; its P0 = 1, 20, 40, 200 (rad/s)² for the
# priors 3.8, 16, 26, 46 rad/s are σ/ω̄ = 0.263, 0.280, 0.243, 0.307, whose geometric mean is 0.272. The rule
# gives 1.05, 18.7, 49.3, 154 (rad/s)² for those priors (σ within −12 %…+11 % of the paper's).
P0_FREQUENCY_REL_STD = 0.27


def modal_transition(omega, zeta: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact transition of the damped oscillators and its exact derivative with respect to ω.

    For A(ω) = [[0, 1], [−ω², −2ζω]] (eq. 7), Φ = expm(A Δt) and ∂Φ/∂ω (the Fréchet derivative of
    expm at A Δt in the direction Δt ∂A/∂ω), in closed form for 0 ≤ ζ < 1.

    Parameters
    ----------
    omega : array_like, shape (m,)
        Undamped natural frequencies in rad/s (positive).
    zeta : float or array_like, shape (m,)
        Damping ratio, 0 ≤ ζ < 1, one for all modes or one per mode (complex values are carried through,
        for a complex-step derivative in ζ).
    dt : float
        Sample interval in s.

    Returns
    -------
    phi, dphi : ndarray, shape (m, 2, 2)
        Φ_n and ∂Φ_n/∂ω_n for each mode n.
    """
    w = np.asarray(omega, dtype=float)
    zeta = np.asarray(zeta)          # one ζ, or one per mode (complex: a complex-step derivative in ζ)
    r = np.sqrt(1.0 - zeta * zeta)
    e = np.exp(-zeta * w * dt)
    c = np.cos(w * r * dt)
    s = np.sin(w * r * dt)
    zr = zeta / r
    phi = np.empty(np.broadcast_shapes(w.shape, zeta.shape) + (2, 2), dtype=np.result_type(w, zeta))
    phi[..., 0, 0] = e * (c + zr * s)
    phi[..., 0, 1] = e * s / (w * r)
    phi[..., 1, 0] = -e * w * s / r
    phi[..., 1, 1] = e * (c - zr * s)
    # d/dω of e = −ζΔt·e, of c = −rΔt·s, of s = rΔt·c
    dphi = -zeta[..., None, None] * dt * phi
    dphi[..., 0, 0] += e * dt * (zeta * c - r * s)
    dphi[..., 0, 1] += e * (dt * c / w - s / (w * w * r))
    dphi[..., 1, 0] -= e * (s / r + w * dt * c)
    dphi[..., 1, 1] -= e * dt * (r * s + zeta * c)
    return phi, dphi


def double_integrate(y: np.ndarray, dt: float) -> np.ndarray:
    """Tip position from the accelerometer by two trapezoidal integrations, starting at 0 and 0.

    The trapezoidal integrator is linear and time-invariant, so each damped sinusoid of ``y`` comes out
    as a damped sinusoid with the *same* frequency and damping (only its amplitude and phase change) plus
    the homogeneous part of the two integrators, c + v·k: the unknown initial position and velocity.
    A constant bias b in ``y`` becomes exactly b·(kΔt)²/2. The filter estimates c, v and b as states.
    """
    v = np.concatenate(([0.0], np.cumsum(0.5 * dt * (y[1:] + y[:-1]))))
    return np.concatenate(([0.0], np.cumsum(0.5 * dt * (v[1:] + v[:-1]))))


def drift_transition(n_drift: int, dt: float) -> np.ndarray:
    """Transition of the drift states [c, v, b] (or a leading subset): a triple integrator."""
    full = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    return full[:n_drift, :n_drift]


@dataclass(frozen=True)
class Weighting:
    """A discrete SISO weighting filter, eq. (26): x_f⁺ = φ_f x_f + Δ_f u, y_f = C_f x_f."""

    phi_f: np.ndarray
    delta_f: np.ndarray
    c_f: np.ndarray

    def apply(self, u: np.ndarray) -> np.ndarray:
        """Filter the record ``u`` from a zero initial state (the same start as the filter's x_f), as
        the equivalent difference equation (same input-output map as eq. 26 from x_f(0) = 0)."""
        num, den = scipy.signal.ss2tf(self.phi_f, self.delta_f[:, None], self.c_f[None, :], np.zeros((1, 1)))
        return scipy.signal.lfilter(num[0], den, u)


@dataclass(frozen=True)
class FilterSettings:
    """Numbers of one filter run (plain values, already checked)."""

    measurement: str
    zeta: float
    qd_modal: float
    qd_frequency: float
    rd: float
    p0_frequency_var: np.ndarray
    p0_modal_scale: float
    estimate_bias: bool
    max_variance_growth: float
    weighting: Weighting | None = None
    r_f: float = 0.0


def settings_from(opts, prior: np.ndarray, method: str, *, dt: float | None = None, **more) -> FilterSettings:
    """Check the options shared by ``akf`` and ``wkf`` and turn them into plain filter settings (Δt = ``dt``
    s turns ``qd_frequency_rel`` into ``qd_frequency``)."""
    if opts.measurement not in MEASUREMENTS:
        raise ValueError(f"{method}: measurement must be one of {MEASUREMENTS}, got '{opts.measurement}'")
    if not 0.0 <= opts.damping_ratio < 1.0:
        raise ValueError(f"{method}: damping_ratio = {opts.damping_ratio} must be in [0, 1)")
    for name in ("qd_modal", "qd_frequency", "rd", "p0_modal_scale"):
        val = getattr(opts, name)
        if not (np.isfinite(val) and val >= 0):
            raise ValueError(f"{method}: {name} = {val} must be a non-negative number")
    qd_frequency = float(opts.qd_frequency)
    rel = getattr(opts, "qd_frequency_rel", None)
    if rel is not None and dt is not None:  # eq. (21)'s walk in units of the prior: per period of ω_min
        rel = relative_option(method, "qd_frequency_rel", rel, "qd_frequency", opts.qd_frequency,
                              type(opts).qd_frequency, allow_zero=True)
        w_min = float(np.min(prior))
        qd_frequency = rel * w_min**2 * dt / (2.0 * np.pi / w_min)
    if not opts.max_variance_growth > 1:
        raise ValueError(f"{method}: max_variance_growth = {opts.max_variance_growth} must exceed 1")
    prior_std = getattr(opts, "prior_std_rad_s", None)
    if prior_std is not None:               # the prior as a distribution: P0 of the frequencies is its spread²
        if opts.p0_frequency_var is not None:
            raise ValueError(f"{method}: give prior_std_rad_s or p0_frequency_var, not both (P0 = std²)")
        std = np.asarray(list(prior_std) if hasattr(prior_std, "__len__") else prior_std, dtype=float)
        if std.ndim > 1 or std.size not in (1, prior.size) or not np.all(np.isfinite(std) & (std > 0)):
            raise ValueError(f"{method}: prior_std_rad_s = {prior_std!r} must be one positive std in rad/s "
                             f"or one per prior frequency ({prior.size})")
        p0 = np.square(std).reshape(-1)
    elif opts.p0_frequency_var is None:     # derived from the prior: σ = P0_FREQUENCY_REL_STD × prior
        p0 = np.square(P0_FREQUENCY_REL_STD * prior)
    else:
        p0 = np.asarray(opts.p0_frequency_var, dtype=float).reshape(-1)
    if p0.size == 1:
        p0 = np.full(prior.size, p0[0])
    if p0.size != prior.size or not np.all(np.isfinite(p0) & (p0 >= 0)):
        raise ValueError(f"{method}: p0_frequency_var = {list(opts.p0_frequency_var)} must be one "
                         f"non-negative variance or one per prior frequency ({prior.size})")
    return FilterSettings(measurement=opts.measurement, zeta=float(opts.damping_ratio),
                          qd_modal=float(opts.qd_modal), qd_frequency=qd_frequency,
                          rd=float(opts.rd), p0_frequency_var=p0, p0_modal_scale=float(opts.p0_modal_scale),
                          estimate_bias=bool(opts.estimate_bias),
                          max_variance_growth=float(opts.max_variance_growth), **more)


class _AugmentedEKF(ExtendedKalmanFilter):
    """filterpy's EKF with the nonlinear state prediction f(x) of the augmented model."""

    x_next: np.ndarray

    def predict_x(self, u=0):
        self.x = self.x_next


class _Layout:
    """Index sets of the augmented state."""

    def __init__(self, m: int, n_drift: int, n_f: int):
        self.m = m
        self.q = np.arange(m)
        self.v = np.arange(m, 2 * m)
        self.w = np.arange(2 * m, 3 * m)
        self.d = np.arange(3 * m, 3 * m + n_drift)
        self.f = np.arange(3 * m + n_drift, 3 * m + n_drift + n_f)
        self.n = 3 * m + n_drift + n_f
        self.n_model = 3 * m + n_drift          # everything but the weighting states


def _measurement_row(x: np.ndarray, lay: _Layout, s: FilterSettings):
    """h(x) of eq. (9) or eq. (10) with unit tip gains, and its Jacobian row over the model states: for one
    state ``x`` (n,), or for a stack of them (R × n, the lock-step run), h and the rows stacked alike."""
    row = np.zeros(x.shape[:-1] + (lay.n_model,))
    q, v = x[..., lay.q], x[..., lay.v]
    if s.measurement == "position":          # eq. (9): Σ q_n + c
        row[..., lay.q] = 1.0
        h = q.sum(axis=-1)
    else:                                     # eq. (10): Σ (−ω² q − 2ζω q̇) + b
        w = x[..., lay.w]
        row[..., lay.q] = -w * w
        row[..., lay.v] = -2.0 * s.zeta * w
        row[..., lay.w] = -2.0 * w * q - 2.0 * s.zeta * v
        h = (row[..., lay.q] * q).sum(axis=-1) + (row[..., lay.v] * v).sum(axis=-1)
    if lay.d.size:
        row[..., lay.d[0]] = 1.0
        h = h + x[..., lay.d[0]]
    return h, row


def _initial_covariance(z: np.ndarray, y: np.ndarray, prior: np.ndarray, lay: _Layout,
                        s: FilterSettings, scale: tuple[float, float] | None = None) -> np.ndarray:
    """P0: the frequency variances (§4.1's, or (0.27·prior)² by default: ``P0_FREQUENCY_REL_STD``); zero
    for the weighting states (§4.2); and for the modal and drift states, whose initial values are unknown
    and set to zero, broad variances scaled by the largest magnitude of the record: any one mode could
    carry the whole signal. (The paper's zeros for the modal states presume the initial displacement
    known.) The largest magnitude, not the RMS, so that P0 does not change with the record length once
    the first peaks are in. ``scale`` = (max |y|, max |z|) given by the caller (a tracker, which may use
    only the samples it has seen) replaces the record's."""
    p0 = np.zeros(lay.n)
    y_max, z_max = (float(np.max(np.abs(y))), float(np.max(np.abs(z)))) if scale is None else scale
    if s.measurement == "position":
        p0[lay.q] = (s.p0_modal_scale * z_max) ** 2
        p0[lay.v] = (s.p0_modal_scale * z_max * prior) ** 2
        scales = [z_max, z_max * prior.max(), y_max]          # c, v, bias b
    else:
        p0[lay.q] = (s.p0_modal_scale * y_max / prior**2) ** 2
        p0[lay.v] = (s.p0_modal_scale * y_max / prior) ** 2
        scales = [y_max]                                      # bias b
    p0[lay.d] = np.square(scales[: lay.d.size])
    p0[lay.w] = s.p0_frequency_var
    return np.diag(p0)


def prepare(y: np.ndarray, dt: float, prior: np.ndarray, s: FilterSettings,
            scale: tuple[float, float] | None = None):
    """What a filter run on ``y`` starts from: the sequence the filter measures (the record, integrated
    twice for position, weighted for ``wkf``), the state layout, filterpy's EKF with x0, P0, Q and R, the
    transition F with its constant blocks and the measurement row H (shared with the lock-step run).
    ``scale``: (max |y|, max |z|) for P0 instead of the whole record's (see ``_initial_covariance``)."""
    if s.measurement == "position":
        z = double_integrate(y, dt)
        n_drift = 3 if s.estimate_bias else 2
    else:
        z = y
        n_drift = 1 if s.estimate_bias else 0
    wf = s.weighting
    lay = _Layout(prior.size, n_drift, 0 if wf is None else wf.phi_f.shape[0])
    meas = z if wf is None else wf.apply(z)   # the weighted filter sees y_f, eq. (26)
    ekf, F, H = _build_filter(z, y, dt, prior, lay, s, scale)
    return meas, lay, ekf, F, H


def identify_record(y, dt, prior, settings_for) -> Estimate:
    """The face of ``akf``/``wkf`` on one record: the inputs checked, the method's checked settings for the
    prior (``settings_for(prior, dt)``), a flat record failed, else :func:`run_filter`."""
    y, dt, prior = check_inputs(y, dt, prior)
    settings = settings_for(prior, dt)
    flat = flat_record(y)
    if flat:
        return failed(prior, flat)
    return run_filter(y, dt, prior, settings)


def run_filter(y: np.ndarray, dt: float, prior: np.ndarray, s: FilterSettings, *,
               observer=None, scale: tuple[float, float] | None = None) -> Estimate:
    """Run the augmented (optionally frequency-weighted) EKF over the record ``y`` (tip acceleration).

    Returns an Estimate whose history holds the frequency states after every measurement update (and
    ``extra["std_history"]`` their filter standard deviations), or a failed Estimate with the history up
    to the failure when the filter diverges. ``observer(k, x, P)``, if given, sees every posterior (tests).
    ``scale``: (max |y|, max |z|) for P0 (the online tracker's, from the samples it has seen); None: the
    record's.
    """
    meas, lay, ekf, F, H = prepare(y, dt, prior, s, scale)
    wf = s.weighting

    n, nm = lay.n, lay.n_model
    # flat positions in F of the modal blocks Φ_n and of the columns ∂(Φ_n x_n)/∂ω_n
    idx_phi = np.concatenate([lay.q * n + lay.q, lay.q * n + lay.v, lay.v * n + lay.q, lay.v * n + lay.v])
    idx_dw = np.concatenate([lay.q * n + lay.w, lay.v * n + lay.w])
    nonlinear_h = s.measurement == "acceleration"      # eq. (10) depends on ω
    h_now = np.zeros((1, 1))

    def hjac(xc):           # filterpy calls HJacobian, then Hx, at the same predicted state
        if wf is None and nonlinear_h:
            h_now[0, 0], H[0, :nm] = _measurement_row(xc[:, 0], lay, s)
        return H

    def hx(xc):
        return h_now if (wf is None and nonlinear_h) else H @ xc

    nyquist = np.pi / dt
    p_limit = s.max_variance_growth * max(float(np.trace(ekf.P)), np.finfo(float).tiny)
    history = np.empty((y.size, lay.m))
    std_history = np.empty((y.size, lay.m))
    diag_w = lay.w * (n + 1)
    for k in range(y.size):
        if k > 0:                   # predict, eqs. (13)-(14) with φ(k) of eq. (24)
            xo = ekf.x[:, 0]
            phi, dphi = _transition_flat(xo[lay.w], s.zeta, dt)
            F.flat[idx_phi] = phi
            F.flat[idx_dw] = 0.0
            if wf is not None and nonlinear_h:
                row = _measurement_row(xo, lay, s)[1]
                F[lay.f, :nm] = np.outer(wf.delta_f, row)
                F[lay.f[:, None], lay.w] = 0.0
            xn = F @ xo                 # f(x): linear in everything but ω, whose columns are zeroed
            q, v = xo[lay.q], xo[lay.v]
            F.flat[idx_dw] = np.concatenate([dphi[0] * q + dphi[1] * v, dphi[2] * q + dphi[3] * v])
            if wf is not None and nonlinear_h:
                F[lay.f[:, None], lay.w] = np.outer(wf.delta_f, row[lay.w])
            ekf.x_next = xn.reshape(-1, 1)
            ekf.predict()
        ekf.update(np.array([[meas[k]]]), hjac, hx)    # eqs. (15)-(17), Joseph form
        P = 0.5 * (ekf.P + ekf.P.T)
        ekf.P = P
        xk = ekf.x[:, 0]
        history[k] = xk[lay.w]
        std_history[k] = P.flat[diag_w]
        if observer is not None:
            observer(k, xk, P)
        reason = _divergence(xk, P, history[k], nyquist, p_limit)
        if reason:
            return failed(prior, f"diverged at sample {k}: {reason}", iterations=k + 1,
                          history=history[: k + 1])
    return finished(history, std_history, ekf.x[:, 0].copy(), prior, s)


def finished(history: np.ndarray, var_history: np.ndarray, final_state: np.ndarray, prior: np.ndarray,
             s: FilterSettings) -> Estimate:
    """The Estimate of a filter run that did not diverge: the frequency states and variances after every
    sample (n × m each), the last state, the prior and the settings (shared with the lock-step run)."""
    n = history.shape[0]
    determined, share = _determined(var_history[-1], n, s)
    std_history = np.sqrt(np.clip(var_history, 0.0, None))
    std = std_history[-1].copy()
    std[~determined & (std == 0.0)] = np.nan     # a frequency held fixed (P0 = Qd = 0) has no 1σ to give
    message = f"{n} samples filtered ({s.measurement} measurement)"
    if not determined.all():
        message += "; not determined by the record (frequency variance still above half of the prior's): " + \
            ", ".join(f"mode {i + 1} ({prior[i]:g} rad/s, {share[i]:.2f})" for i in np.flatnonzero(~determined))
    return Estimate(history[-1].copy(), std, history=history, converged=True,
                    iterations=n, message=message, converged_per_mode=determined,
                    extra={"std_history": std_history, "final_state": final_state, "variance_share": share})


# A frequency counts as determined by the record when its final filter variance is at most this share of the
# variance it would have with no measurement at all, P0 + (n − 1)·Qd (the prior's, grown by the random walk of
# eq. 21). For a Gaussian update, posterior/prior variance = 1/(1 + I·P0): at 1/2 the record carries as much
# information I on that frequency as the prior did. Below it the estimate is the prior's, not the record's.
DETERMINED_VARIANCE_SHARE = 0.5


def _determined(var_w: np.ndarray, n: int, s: FilterSettings) -> tuple[np.ndarray, np.ndarray]:
    """Per mode: whether the record determined the frequency, and the share of its no-information variance
    left (``DETERMINED_VARIANCE_SHARE``). ``run_filter`` reports the overall ``converged`` as "did not
    diverge" and this per mode, in ``Estimate.converged_per_mode``."""
    no_info = s.p0_frequency_var + (n - 1) * s.qd_frequency
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(no_info > 0, var_w / no_info, np.nan)
    return share <= DETERMINED_VARIANCE_SHARE, share


def _build_filter(z, y, dt, prior, lay: _Layout, s: FilterSettings, scale=None):
    """filterpy's EKF with x0, P0, Q, R of the augmented model; the transition F with its constant
    blocks filled in (updated in place every step); the measurement row H."""
    ekf = _AugmentedEKF(lay.n, 1)
    x0 = np.zeros(lay.n)
    x0[lay.w] = prior
    ekf.x = x0.reshape(-1, 1)
    ekf.P = _initial_covariance(z, y, prior, lay, s, scale)
    qdiag = np.zeros(lay.n)
    if s.measurement == "position":
        qdiag[lay.q] = qdiag[lay.v] = s.qd_modal
    else:   # Qd in measurement units: q̈ ≈ ω²q, so the acceleration-equivalent variance is qd_modal
        qdiag[lay.q] = s.qd_modal / prior**4
        qdiag[lay.v] = s.qd_modal / prior**2
    qdiag[lay.w] = s.qd_frequency                     # random walks, eq. (21)
    ekf.Q = np.diag(qdiag)
    F = np.zeros((lay.n, lay.n))
    F[lay.w, lay.w] = 1.0
    F[np.ix_(lay.d, lay.d)] = drift_transition(lay.d.size, dt)
    ekf.F = F
    H = np.zeros((1, lay.n))
    h_const = _measurement_row(x0, lay, s)[1] if s.measurement == "position" else None   # eq. (9)
    wf = s.weighting
    if wf is None:
        ekf.R = np.array([[s.rd]])
        if h_const is not None:
            H[0, : lay.n_model] = h_const
    else:
        F[np.ix_(lay.f, lay.f)] = wf.phi_f
        ekf.Q[np.ix_(lay.f, lay.f)] = s.rd * np.outer(wf.delta_f, wf.delta_f)   # eq. (28)
        ekf.R = np.array([[s.r_f]])                                             # eq. (29)
        H[0, lay.f] = wf.c_f                                                    # C_i = [0 C_f]
        if h_const is not None:
            F[lay.f, : lay.n_model] = np.outer(wf.delta_f, h_const)             # Δ_f C, eq. (27)
    return ekf, F, H


def _transition_flat(w: np.ndarray, zeta: float, dt: float) -> tuple[list[float], list[np.ndarray]]:
    """The entries of :func:`modal_transition` for the inner loop, with scalar math (a few modes are
    cheaper as Python floats than as tiny arrays): Φ entries ordered (φ00…, φ01…, φ10…, φ11…) over the
    modes, and [∂φ00, ∂φ01, ∂φ10, ∂φ11] per mode."""
    r = math.sqrt(1.0 - zeta * zeta)
    zr = zeta / r
    p00, p01, p10, p11 = [], [], [], []
    d00, d01, d10, d11 = [], [], [], []
    for wi in w.tolist():
        e = math.exp(-zeta * wi * dt)
        ec = e * math.cos(wi * r * dt)
        es = e * math.sin(wi * r * dt)
        a, b, c, d = ec + zr * es, es / (wi * r), -wi * es / r, ec - zr * es
        p00.append(a)
        p01.append(b)
        p10.append(c)
        p11.append(d)
        g = -zeta * dt
        d00.append(g * a + dt * (zeta * ec - r * es))
        d01.append(g * b + dt * ec / wi - es / (wi * wi * r))
        d10.append(g * c - es / r - wi * dt * ec)
        d11.append(g * d - dt * (r * es + zeta * ec))
    return p00 + p01 + p10 + p11, [np.array(d00), np.array(d01), np.array(d10), np.array(d11)]


def _divergence(x: np.ndarray, P: np.ndarray, w: np.ndarray, nyquist: float, p_limit: float) -> str:
    """Why the filter is judged diverged, or '' when it is not (cheap: called every sample)."""
    trace = float(np.trace(P))
    if not np.isfinite(trace + float(x.sum())):
        return "non-finite state or covariance"
    lo, hi = float(w.min()), float(w.max())
    if lo <= 0.0 or hi >= nyquist:
        i = int(np.argmin(w)) if lo <= 0.0 else int(np.argmax(w))
        return f"frequency {i + 1} = {w[i]:.4g} rad/s left (0, Nyquist {nyquist:.4g} rad/s)"
    if trace > p_limit:
        return f"covariance blow-up (trace {trace:.3g} > {p_limit:.3g})"
    dmin = float(P.diagonal().min())
    if dmin < -1e-9 * trace:
        return f"covariance lost positive semi-definiteness (variance {dmin:.3g})"
    return ""
