"""The time-varying truth: the closed-form transition, the modal model, and an independent integration."""

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import solve_ivp

from experiments.simulate.plant import build_plant
from experiments.simulate.timevarying import modal_model, oscillator_transition, simulate

DT = 0.02


def test_closed_form_transition_matches_scipy_expm_and_van_loan():
    w, z = 20.24, 0.005
    phi, gamma = oscillator_transition(w, z, DT)
    A = np.array([[0.0, 1.0], [-w**2, -2 * z * w]])
    aug = np.zeros((3, 3))
    aug[:2, :2], aug[1, 2] = A, 1.0                       # Van Loan: [[A, B], [0, 0]] for a unit modal force
    e = scipy.linalg.expm(aug * DT)
    np.testing.assert_allclose(phi, scipy.linalg.expm(A * DT), atol=1e-13)
    np.testing.assert_allclose(gamma[:, 1], e[:2, 2], rtol=1e-9, atol=1e-15)


def test_constant_schedule_release_matches_the_20_state_plant():
    # The modal model drops the small non-classical part of the damping (ζ = 0.005): agreement to 1e-3 of
    # the peak; a wrong gain, shape or sign would be off by order one.
    plant = build_plant()
    model = modal_model(plant)
    n = 1500
    y, _ = simulate(model, np.tile(model.freq_rad_s, (n, 1)), DT, xi0=model.xi0)
    ref = plant.tip_acceleration(n, DT)
    assert np.max(np.abs(y[0] - ref)) < 1e-3 * np.max(np.abs(ref))


def test_held_inputs_match_solve_ivp_of_the_20_state_plant():
    # Torque pulses and a tip force, zero-order held, frozen plant: integrate M η̈ = F − Kη − Dη̇ directly.
    plant = build_plant()
    model = modal_model(plant)
    n = 150
    rng = np.random.default_rng(1)
    u = np.zeros((1, n, 3))
    u[0, 10:12, 0] = 100.0
    u[0, :, 1] = 0.5 * rng.standard_normal(n)
    u[0, :, 2] = 20.0 * rng.standard_normal(n)
    y, _ = simulate(model, np.tile(model.freq_rad_s, (n, 1)), DT, u)
    nq = plant.M.shape[0]
    g = np.zeros((nq, 3))
    g[2, 0], g[:, 1], g[4, 2] = 1.0, plant.c_tip, 1.0
    x = np.zeros(2 * nq)
    ref = np.empty(n)
    for k in range(n):
        force = np.concatenate([np.zeros(nq), np.linalg.solve(plant.M, g @ u[0, k])])
        ref[k] = plant.C_acc @ x + plant.c_tip @ np.linalg.solve(plant.M, g @ u[0, k])
        sol = solve_ivp(lambda t, s, f=force: plant.A @ s + f, (0, DT), x, method="DOP853", rtol=1e-11,
                        atol=1e-14)
        x = sol.y[:, -1]
    assert np.max(np.abs(y[0] - ref)) < 2e-3 * np.max(np.abs(ref))


def test_time_varying_frequencies_match_solve_ivp():
    # The frozen-per-sample system (ω held at ω(t_k) over [t_k, t_k+1)) against an adaptive integration of
    # the same modal ODEs: the closed form and the recursion, not the modal reduction, are tested here.
    model = modal_model(build_plant())
    n = 400
    t = np.arange(n) * DT
    w = model.freq_rad_s * (1 + 0.2 * t / t[-1])[:, None] * (1 + 0.03 * np.sin(2 * np.pi * 0.5 * t))[:, None]
    u = np.zeros((1, n, 3))
    u[0, 5, 0], u[0, 200, 1], u[0, 300, 2] = 80.0, 3.0, 50.0
    y, x = simulate(model, w, DT, u, xi0=0.1 * model.xi0)
    m = w.shape[1]
    s = np.concatenate([np.stack([0.1 * model.xi0, np.zeros(m)], axis=1).reshape(-1)])
    ref = np.empty((n, m, 2))
    for k in range(n):
        ref[k] = s.reshape(m, 2)
        f = model.input_gain @ u[0, k]

        def rhs(_t, z, wk=w[k], f=f):
            z = z.reshape(m, 2)
            return np.stack([z[:, 1], f - wk**2 * z[:, 0] - 2 * model.damping * wk * z[:, 1]], axis=1).reshape(-1)

        s = solve_ivp(rhs, (0, DT), s, method="DOP853", rtol=1e-12, atol=1e-15).y[:, -1]
    acc = -(w**2) * ref[..., 0] - 2 * model.damping * w * ref[..., 1]
    y_ref = acc @ model.tip_gain + u[0] @ model.feedthrough
    np.testing.assert_allclose(x[0], ref, atol=1e-8 * np.abs(ref).max())
    assert np.max(np.abs(y[0] - y_ref)) < 1e-7 * np.max(np.abs(y_ref))


@pytest.mark.parametrize("w", [3.23, 56.67])
def test_free_decay_frequency_is_the_schedule(w):
    # One constant mode released from rest: the zero crossings of ξ are spaced π/ω_d.
    phi, _ = oscillator_transition(w, 0.0, 0.001)
    s = np.array([1.0, 0.0])
    xs = []
    for _ in range(20000):
        xs.append(s[0])
        s = phi @ s
    xs = np.array(xs)
    crossings = np.flatnonzero(np.sign(xs[1:]) != np.sign(xs[:-1]))
    period = 2 * np.mean(np.diff(crossings)) * 0.001
    assert period == pytest.approx(2 * np.pi / w, rel=2e-3)
