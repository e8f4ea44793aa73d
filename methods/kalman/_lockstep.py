"""The augmented EKF of :mod:`methods.kalman._filter` run over R records in lock-step, with stacked arrays.

The pipeline identifies the R replicates of a cell in one job; run one at a time, a filter step is ~40
small numpy/filterpy calls on a 15–17-state model, and their overhead, not the arithmetic, is the cost
(10 ms per 256-sample replicate, 78 ms at 2048). Here every step is the same calls on (R, n) states and
(R, n, n) covariances, so the overhead is paid once per step for all replicates.

The model, the initial state and covariance, Q, R, F's constant blocks and H come from the reference
:func:`~methods.kalman._filter.prepare` per record (filterpy's ``ExtendedKalmanFilter`` built as the
single-record run builds it), h(x) from the reference's measurement row on the stack, and the result of
each record from the same :func:`~methods.kalman._filter.finished`. The step is the reference's, written for a stack:

* predict: f(x) with the exact modal transition, F = ∂f/∂x with the exact ∂Φ/∂ω, P ← F P Fᵀ + Q;
* update (one scalar measurement): PHᵀ, S = H P Hᵀ + R, K = PHᵀ/S, x ← x + K (z − h(x)), and filterpy's
  Joseph form (I − KH) P (I − KH)ᵀ + K R Kᵀ expanded for a rank-one H: P − K aᵀ − a Kᵀ + S K Kᵀ with
  a = P Hᵀ (the same matrix in exact arithmetic; the expansion needs no (n × n) products);
* P re-symmetrised, the divergence test of the reference (its reasons, word for word), and a record that
  diverges leaves the stack.

Written by hand because no kept library steps many filters at once: filterpy's filters hold one state.
filterpy stays the reference; the tests check that every record's frequencies, standard deviations,
history and messages equal those of :func:`~methods.kalman._filter.run_filter` (tests/methods/
test_kalman_batch.py).
"""

from __future__ import annotations

import math

import numpy as np

from methods.estimate import Estimate, check_inputs, failed, flat_record
from methods.kalman._filter import FilterSettings, _divergence, _measurement_row, finished, prepare


def identify_each(y, dt, priors, settings_for) -> list[Estimate]:
    """The batch face of ``akf``/``wkf``: each row of ``y`` (R × n) checked as ``identify`` checks one
    record (a bad one raises ``ValueError`` naming its row), a flat record failed as ``identify`` fails
    it, and the others run in lock-step by :func:`run_filters`. ``priors``: one prior for all rows or one
    row per record; ``settings_for(prior, dt)``: the method's checked :class:`FilterSettings` for a prior
    (made once per distinct prior: a cell's records usually share one)."""
    y = np.asarray(y, dtype=float) if not isinstance(y, np.ndarray) else y
    if y.ndim != 2:
        raise ValueError(f"records must be a 2-D array (R records × n samples), got shape {np.shape(y)}")
    priors = np.asarray(priors, dtype=float)
    priors = np.broadcast_to(priors, (len(y), priors.shape[-1])) if priors.ndim else priors
    out: list[Estimate | None] = [None] * len(y)
    todo, recs, pri, sets = [], [], [], []
    made: dict[bytes, FilterSettings] = {}
    for r in range(len(y)):
        try:
            rec, dt_s, prior = check_inputs(y[r], dt, priors[r])
        except ValueError as exc:
            raise ValueError(f"record {r}: {exc}") from None
        flat = flat_record(rec)
        if flat:
            out[r] = failed(prior, flat)
            continue
        todo.append(r)
        recs.append(rec)
        pri.append(prior)
        key = prior.tobytes()
        if key not in made:
            made[key] = settings_for(prior, dt_s)
        sets.append(made[key])
    if todo:
        for r, est in zip(todo, run_filters(np.array(recs), dt_s, np.array(pri), sets), strict=True):
            out[r] = est
    return out


def run_filters(y: np.ndarray, dt: float, priors: np.ndarray, settings: list[FilterSettings]) -> list[Estimate]:
    """Run the filter of :func:`methods.kalman._filter.run_filter` on every row of ``y`` (R × n), row r
    with prior ``priors[r]`` and settings ``settings[r]`` (the same but for the prior-derived P0), and
    return one Estimate per row, equal to ``run_filter(y[r], dt, priors[r], settings[r])``."""
    n_rec, n_samples = y.shape
    s = settings[0]
    wf = s.weighting
    parts = [prepare(y[r], dt, priors[r], settings[r]) for r in range(n_rec)]
    meas = np.array([p[0] for p in parts])
    lay = parts[0][1]
    x = np.array([p[2].x[:, 0] for p in parts])
    P = np.array([p[2].P for p in parts])
    Q = np.array([p[2].Q for p in parts])
    F = np.array([p[3] for p in parts])
    H = np.array([p[4][0] for p in parts])
    r_meas = float(parts[0][2].R[0, 0])
    m, nm = lay.m, lay.n_model
    q_, v_, w_, f_ = lay.q, lay.v, lay.w, lay.f
    nonlinear_h = s.measurement == "acceleration"
    zeta = s.zeta
    r = math.sqrt(1.0 - zeta * zeta)
    zr = zeta / r
    nyquist = np.pi / dt
    tiny = np.finfo(float).tiny
    p_limit = s.max_variance_growth * np.maximum(np.trace(P, axis1=1, axis2=2), tiny)
    alive = np.arange(n_rec)                     # the records still in the stack, by original index
    history = np.empty((n_rec, n_samples, m))
    var_history = np.empty((n_rec, n_samples, m))
    out: list[Estimate | None] = [None] * n_rec
    diag = np.arange(lay.n)
    buf = _Buffers(x.shape[0], lay.n)
    with np.errstate(all="ignore"):               # a diverging record is caught after its step
        for k in range(n_samples):
            if k > 0:
                # Φ and ∂Φ/∂ω: the expressions of the reference's _transition_flat on arrays, in the same
                # order (modal_transition's rounding moves the acceleration filter's history by ~1e-9)
                w = x[:, w_]
                e = np.exp(-zeta * dt * w)
                arg = r * dt * w
                ec, es = e * np.cos(arg), e * np.sin(arg)
                p00, p01, p10, p11 = ec + zr * es, es / (w * r), -w * es / r, ec - zr * es
                F[:, q_, q_], F[:, q_, v_], F[:, v_, q_], F[:, v_, v_] = p00, p01, p10, p11
                F[:, q_, w_] = 0.0
                F[:, v_, w_] = 0.0
                if wf is not None and nonlinear_h:
                    row = _measurement_row(x, lay, s)[1]
                    F[:, f_, :nm] = wf.delta_f[None, :, None] * row[:, None, :]
                    F[:, f_[:, None], w_] = 0.0
                xn = np.matmul(F, x[:, :, None])[:, :, 0]      # f(x): the ω columns are zero here
                q, v = x[:, q_], x[:, v_]
                g = -zeta * dt
                d00 = g * p00 + dt * (zeta * ec - r * es)
                d01 = g * p01 + dt * ec / w - es / (w * w * r)
                d10 = g * p10 - es / r - w * dt * ec
                d11 = g * p11 - dt * (r * es + zeta * ec)
                F[:, q_, w_] = d00 * q + d01 * v
                F[:, v_, w_] = d10 * q + d11 * v
                if wf is not None and nonlinear_h:
                    F[:, f_[:, None], w_] = wf.delta_f[None, :, None] * row[:, None, w_]
                x = xn
                # P ← F P Fᵀ + Q into preallocated stacks (matmul with a transposed view as operand, or
                # allocating its output, is 2-3x slower on these small matrices)
                np.matmul(F, P, out=buf.fp)
                np.copyto(buf.ft, F.transpose(0, 2, 1))
                np.matmul(buf.fp, buf.ft, out=P)
                P += Q
            if wf is None and nonlinear_h:
                h, H[:, :nm] = _measurement_row(x, lay, s)
            else:
                h = np.einsum("ri,ri->r", H, x)
            a = np.matmul(P, H[:, :, None])[:, :, 0]           # P Hᵀ
            S = np.einsum("ri,ri->r", H, a) + r_meas
            K = a / S[:, None]
            x = x + K * (meas[:, k] - h)[:, None]
            # Joseph form for a scalar measurement: P − K aᵀ − a Kᵀ + S K Kᵀ = P + [K a] [(S K − a)ᵀ; −Kᵀ]
            buf.u[:, :, 0] = K
            buf.u[:, :, 1] = a
            buf.v[:, 0, :] = S[:, None] * K - a
            np.negative(K, out=buf.v[:, 1, :])
            np.matmul(buf.u, buf.v, out=buf.fp)
            P += buf.fp
            np.add(P, P.transpose(0, 2, 1), out=buf.fp)
            np.multiply(buf.fp, 0.5, out=P)
            wk = x[:, w_]
            history[alive, k] = wk
            var_history[alive, k] = P[:, w_, w_]
            trace = np.trace(P, axis1=1, axis2=2)
            pdiag = P[:, diag, diag]
            bad = ~np.isfinite(trace + x.sum(axis=1))
            bad |= (wk.min(axis=1) <= 0.0) | (wk.max(axis=1) >= nyquist)
            bad |= trace > p_limit
            bad |= pdiag.min(axis=1) < -1e-9 * trace
            if bad.any():
                for i in np.flatnonzero(bad):
                    rec = alive[i]
                    reason = _divergence(x[i], P[i], wk[i], nyquist, p_limit[i])
                    out[rec] = failed(priors[rec], f"diverged at sample {k}: {reason}", iterations=k + 1,
                                      history=history[rec, : k + 1].copy())
                keep = ~bad
                alive, x, P, Q, F, H, meas, p_limit = (alive[keep], x[keep], P[keep], Q[keep], F[keep],
                                                        H[keep], meas[keep], p_limit[keep])
                if alive.size == 0:
                    break
                buf = _Buffers(alive.size, lay.n)
    for i, rec in enumerate(alive):
        out[rec] = finished(history[rec], var_history[rec], x[i].copy(), priors[rec], settings[rec])
    return out


class _Buffers:
    """Preallocated work stacks for R records of n states."""

    def __init__(self, n_rec: int, n: int):
        self.fp = np.empty((n_rec, n, n))
        self.ft = np.empty((n_rec, n, n))
        self.u = np.empty((n_rec, n, 2))
        self.v = np.empty((n_rec, 2, n))
