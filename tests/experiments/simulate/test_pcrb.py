"""The tracking yardstick: the PCRB recursion against the batch Fisher information inverted directly, and
the sliding-window bound against crlb.py's free-decay bound."""

import numpy as np
import pytest

from experiments.simulate.crlb import crlb_std
from experiments.simulate.pcrb import (
    cell_pcrb,
    jacobians,
    pcrb_covariance,
    tichavsky_recursion,
    transition_derivatives,
    window_bound,
)
from experiments.simulate.plant import build_plant
from experiments.simulate.timevarying import ModalModel, modal_model, oscillator_transition, simulate

DT = 0.02


def one_mode(w=20.0, zeta=0.01):
    return ModalModel(freq_rad_s=np.array([w]), damping=np.array([zeta]), tip_gain=np.array([0.9]),
                      input_gain=np.zeros((1, 3)), feedthrough=np.zeros(3), xi0=np.array([0.01]))


def test_complex_step_derivative_matches_central_difference():
    _, _, pw, gw, pz, _ = transition_derivatives(20.0, 0.01, DT)
    h = 1e-6
    fd = (oscillator_transition(20.0 + h, 0.01, DT)[0] - oscillator_transition(20.0 - h, 0.01, DT)[0]) / (2 * h)
    np.testing.assert_allclose(pw, fd, rtol=1e-6, atol=1e-10)
    fz = (oscillator_transition(20.0, 0.01 + h, DT)[0] - oscillator_transition(20.0, 0.01 - h, DT)[0]) / (2 * h)
    np.testing.assert_allclose(pz, fz, rtol=1e-6, atol=1e-10)


def _batch_fim_last_omega_var(F, H, Q, noise_var, P0):
    """[J⁻¹]ωω of the last sample from the Fisher information of the whole trajectory z_0…z_{N-1}: the
    prior, every measurement and every transition, assembled as one matrix and inverted directly."""
    n, d = H.shape
    J = np.zeros((n * d, n * d))
    J[:d, :d] += np.linalg.inv(P0)
    qi = np.linalg.inv(Q)
    for k in range(n):
        b = slice(k * d, (k + 1) * d)
        J[b, b] += np.outer(H[k], H[k]) / noise_var
        if k + 1 < n:
            g = np.zeros((d, n * d))
            g[:, b] = -F[k]
            g[:, (k + 1) * d:(k + 2) * d] = np.eye(d)
            J += g.T @ qi @ g
    return np.linalg.inv(J)[(n - 1) * d + 2, (n - 1) * d + 2]


def test_pcrb_recursion_equals_inverse_of_batch_fisher_information_one_mode():
    model = one_mode()
    n = 40
    w = np.full((n, 1), 20.0) * (1 + 0.05 * np.arange(n) / n)[:, None]
    _, x = simulate(model, w, DT, xi0=model.xi0)
    F, H = jacobians(model, w, x, DT, damping=False)
    Q = np.diag([1e-9, 1e-7, 1e-4])
    P0 = np.diag([1e-4, 1e-2, 0.5])
    noise_var = 1e-4
    p = pcrb_covariance(F, H, Q, noise_var, P0)[0]
    J = tichavsky_recursion(F, H, Q, noise_var, np.linalg.inv(P0))
    for k in (5, 20, n - 1):
        batch = _batch_fim_last_omega_var(F[0, :k + 1], H[0, :k + 1], Q, noise_var, P0)
        assert p[k, 2] == pytest.approx(batch, rel=1e-6)
        assert np.linalg.inv(J[k])[2, 2] == pytest.approx(batch, rel=1e-6)
    # the data teach something: the bound falls well below the prior's 0.5 rad²/s²
    assert p[-1, 2] < 0.01 * P0[2, 2]


def test_window_bound_of_a_free_decay_is_the_crlb_of_crlb_py():
    # Constant frequencies, the paper's release: the window's model (oscillator states, ω, ζ) is crlb.py's
    # damped-sinusoid model (a, φ, ω, ζ) in other coordinates, so the ω bound must be the same number.
    plant = build_plant()
    model = modal_model(plant)
    n = 256
    w = np.tile(model.freq_rad_s, (n, 1))
    y, x = simulate(model, w, DT, xi0=model.xi0)
    t = np.arange(n) * DT
    amp, ph = [], []
    for i in range(4):
        acc = -(w[:, i] ** 2) * x[0, :, i, 0] - 2 * model.damping[i] * w[:, i] * x[0, :, i, 1]
        acc = acc * model.tip_gain[i]
        e = np.exp(-model.damping[i] * w[0, i] * t)
        wd = w[0, i] * np.sqrt(1 - model.damping[i] ** 2)
        (a, b), *_ = np.linalg.lstsq(np.column_stack([e * np.cos(wd * t), e * np.sin(wd * t)]), acc, rcond=None)
        amp.append(np.hypot(a, b))
        ph.append(np.arctan2(-b, a))
    sigma = 1000 * 9.80665e-6
    ref = crlb_std(model.freq_rad_s, model.damping, amp, ph, n, DT, sigma)
    _, got = window_bound(model, w, x[0], DT, sigma, ends=[n - 1], widths=[n])
    np.testing.assert_allclose(got[0], ref, rtol=1e-4)


def test_window_bound_includes_the_bias_of_a_drift():
    model = modal_model(build_plant())
    n = 2048
    w = np.tile(model.freq_rad_s, (n, 1)) * (1 + 0.2 * np.arange(n) / n)[:, None]
    _, x = simulate(model, w, DT, xi0=model.xi0)
    _, fixed = window_bound(model, w, x[0], DT, 1e-5, ends=[n - 1], widths=[1024])
    # at 10 µg the variance is negligible: the bound is the lag of a 1024-sample window, ω·0.2·(1023/2)/n
    np.testing.assert_allclose(fixed[0], model.freq_rad_s * 0.2 * 511.5 / n, rtol=1e-3)


def test_cell_pcrb_falls_with_the_noise():
    model = modal_model(build_plant())
    n = 500
    w = np.tile(model.freq_rad_s, (n, 1))
    _, x = simulate(model, w, DT, xi0=model.xi0)
    prior = model.freq_rad_s[None] * 1.03
    lo = cell_pcrb(model, w, x, DT, 1e-4, prior)
    hi = cell_pcrb(model, w, x, DT, 1e-2, prior)
    assert lo.shape == (1, n, 4)
    # a random-walk model forgets: the bound falls slower than the noise (∝ √σ at steady state)
    assert np.all(lo[0, -1] < 0.5 * hi[0, -1])
    # at the start only the prior: 5 %/√3 of ω
    np.testing.assert_allclose(hi[0, 0], 0.05 / np.sqrt(3) * model.freq_rad_s, rtol=0.05)
