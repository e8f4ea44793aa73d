"""The unknown-force bound against independent computations of the Fisher information of one mode at a
constant frequency, driven by a white force (stationary), seen by an accelerometer with a direct term:
Whittle's asymptotic information of the sampled spectrum (large N) and the exact Gaussian-likelihood
information of the whole record (small N). Both are built here from scipy.signal's zero-order-hold
discretisation of the continuous oscillator, not from the simulator's closed form."""

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from experiments.simulate.pcrb import cell_pcrb, matched_walk_q
from experiments.simulate.pcrb_force import force_noise, unknown_force_pcrb
from experiments.simulate.timevarying import INPUTS, ModalModel, simulate

DT = 0.02
W0, ZETA, TIP, GAIN = 20.0, 0.05, 0.9, 0.004
DIRECT = 1.5 * TIP * GAIN          # the modal part c·b plus a rigid-body share
FORCE = 5.0                        # N per sample
BODY = INPUTS.index("force_body_y")


def one_mode():
    b = np.zeros((1, 3))
    b[0, BODY] = GAIN
    d = np.zeros(3)
    d[BODY] = DIRECT
    return ModalModel(freq_rad_s=np.array([W0]), damping=np.array([ZETA]), tip_gain=np.array([TIP]),
                      input_gain=b, feedthrough=d, xi0=np.zeros(1))


def discrete(w, zeta):
    """ZOH discretisation (scipy.signal.cont2discrete) of force → tip acceleration."""
    a = np.array([[0.0, 1.0], [-w**2, -2 * zeta * w]])
    b = np.array([[0.0], [GAIN]])
    c = TIP * np.array([[-w**2, -2 * zeta * w]])
    ad, bd, cd, dd, _ = scipy.signal.cont2discrete((a, b, c, np.array([[DIRECT]])), DT, method="zoh")
    return ad, bd, cd, dd


def log_spectrum(theta, lam, sigma):
    ad, bd, cd, dd = discrete(*theta)
    _, g = scipy.signal.dfreqresp(scipy.signal.dlti(ad, bd, cd, dd, dt=DT), w=lam)
    return np.log(FORCE**2 * np.abs(np.ravel(g)) ** 2 + sigma**2)


def whittle_information(n, sigma):
    """N/(4π)∫_{−π}^{π} ∂_a log S ∂_b log S dλ over θ = (ω, ζ), derivatives by central differences."""
    lam = np.linspace(1e-6, np.pi, 200_001)
    theta = np.array([W0, ZETA])
    grads = []
    for i in range(2):
        h = np.zeros(2)
        h[i] = 1e-6 * theta[i]
        grads.append((log_spectrum(theta + h, lam, sigma) - log_spectrum(theta - h, lam, sigma)) / (2 * h[i]))
    info = np.array([[np.trapezoid(ga * gb, lam) for gb in grads] for ga in grads]) / (2 * np.pi)
    return n * info


def record_covariance(theta, n, sigma):
    """The covariance of y_0…y_{N−1}: stationary initial state, white force, white noise."""
    ad, bd, cd, dd = discrete(*theta)
    p_st = scipy.linalg.solve_discrete_lyapunov(ad, FORCE**2 * bd @ bd.T)
    obs = np.empty((n, 2))
    impulse = np.empty(n)
    impulse[0] = dd[0, 0]
    a_pow = np.eye(2)
    for k in range(n):
        obs[k] = (cd @ a_pow)[0]            # C A^k
        if k + 1 < n:
            impulse[k + 1] = obs[k] @ bd[:, 0]     # C A^k B
        a_pow = a_pow @ ad
    lower = scipy.linalg.toeplitz(impulse, np.zeros(n))
    return obs @ p_st @ obs.T + FORCE**2 * lower @ lower.T + sigma**2 * np.eye(n)


def batch_information(n, sigma):
    """I_ab = ½ tr(C⁻¹ ∂_a C C⁻¹ ∂_b C), the exact Fisher information of the Gaussian record."""
    theta = np.array([W0, ZETA])
    c_inv = np.linalg.inv(record_covariance(theta, n, sigma))
    dc = []
    for i in range(2):
        h = np.zeros(2)
        h[i] = 1e-6 * theta[i]
        dc.append((record_covariance(theta + h, n, sigma) - record_covariance(theta - h, n, sigma)) / (2 * h[i]))
    return np.array([[0.5 * np.trace(c_inv @ a @ c_inv @ b) for b in dc] for a in dc])


def stationary_records(n, replicates, seed):
    """Modal states of white-force records started in the stationary distribution (a 60 s burn-in)."""
    model = one_mode()
    burn = int(60 / DT)
    u = np.zeros((replicates, burn + n, 3))
    u[:, :, BODY] = FORCE * np.random.default_rng(seed).standard_normal((replicates, burn + n))
    _, x = simulate(model, np.full((burn + n, 1), W0), DT, u)
    return model, x[:, burn:], u[:, burn:]


def bound_information(n, replicates, sigma, seed):
    """The bound's information on ω at the last sample, averaged over replicates, and the prior's."""
    model, x, u = stationary_records(n, replicates, seed)
    ad, bd, _, _ = discrete(W0, ZETA)
    prior_var = np.array([(0.1 * W0) ** 2, (0.5 * ZETA) ** 2])
    p0 = scipy.linalg.block_diag(scipy.linalg.solve_discrete_lyapunov(ad, FORCE**2 * bd @ bd.T), np.diag(prior_var))
    std = unknown_force_pcrb(model, np.full((n, 1), W0), x, DT, sigma, np.array([W0]), force_std_n=FORCE, u=u,
                             rw_q=np.zeros(1), P0=p0)
    return np.mean(1.0 / std[:, -1, 0] ** 2), np.diag(1.0 / prior_var)


@pytest.mark.parametrize("sigma", [1e-4, 1e-3])
def test_bound_approaches_whittle_information_at_large_n(sigma):
    # 120 s, 120 correlation times 1/(ζω) of the mode, 12 replicates (0.997–1.006 of Whittle on seeds 3, 4)
    n = 6000
    got, prior_info = bound_information(n, 12, sigma, seed=3)
    ref = 1.0 / np.linalg.inv(whittle_information(n, sigma) + prior_info)[0, 0]
    assert got == pytest.approx(ref, rel=0.05)


def test_with_strong_noise_the_bound_is_looser_than_whittle():
    # σ = 0.1 m/s², 3× the record's rms (0.037 m/s²): the information along the
    # true trajectory is (1/2π)∫σ_f²|∂G/∂ω|²/S, above Whittle's (2.6× here): still below the true CRB's std
    n = 6000
    got, prior_info = bound_information(n, 4, 0.1, seed=3)
    ref = 1.0 / np.linalg.inv(whittle_information(n, 0.1) + prior_info)[0, 0]
    assert got > 1.5 * ref


def test_bound_equals_exact_fisher_information_of_a_short_record():
    # 2.4 s, 2.4 correlation times: the exact information of the Gaussian record (C is 120 × 120); the mean
    # over 400 replicates: 1.04 and 0.99 of it on seeds 5 and 6
    n = 120
    got, prior_info = bound_information(n, 400, 1e-4, seed=5)
    ref = 1.0 / np.linalg.inv(batch_information(n, 1e-4) + prior_info)[0, 0]
    assert got == pytest.approx(ref, rel=0.08)


def test_whittle_and_exact_information_agree_at_large_n():
    # the two independent references agree with each other (N = 600, 12 correlation times: Whittle is
    # asymptotic)
    n = 600
    ratio = whittle_information(n, 1e-4)[0, 0] / batch_information(n, 1e-4)[0, 0]
    assert ratio == pytest.approx(1.0, rel=0.03)          # 1.014


def test_unknown_force_bound_is_far_above_the_genie_and_vanishing_force_is_the_genie():
    n = 1500
    model, x, u = stationary_records(n, 2, seed=1)
    w = np.full((n, 1), W0)
    prior = np.array([[W0 * 1.02]] * 2)
    genie = cell_pcrb(model, w, x, DT, 1e-3, prior, u=u)
    unknown = unknown_force_pcrb(model, w, x, DT, 1e-3, prior, force_std_n=FORCE, u=u)
    vanishing = unknown_force_pcrb(model, w, x, DT, 1e-3, prior, force_std_n=0.0, u=u)
    np.testing.assert_allclose(vanishing, genie, rtol=1e-6)
    # knowing the force, ω is read off response/force ratio: orders of magnitude below
    assert np.all(unknown[:, -1] > 30 * genie[:, -1])


def test_force_noise_is_rank_one_and_refuses_an_unknown_input():
    model = one_mode()
    Q, S, direct_var = force_noise(model, np.full((10, 1), W0), DT, FORCE)
    assert Q.shape == (10, 4, 4) and np.linalg.matrix_rank(Q[3]) == 1
    np.testing.assert_allclose(S[3], DIRECT * np.sqrt(np.diag(Q[3])) * np.sign(S[3]) * FORCE, rtol=1e-12)
    assert direct_var == pytest.approx((DIRECT * FORCE) ** 2)
    with pytest.raises(ValueError, match="force_input = 'force_x'"):
        force_noise(model, np.full((10, 1), W0), DT, FORCE, "force_x")


def test_matched_walk_moves_at_the_schedules_rate_and_jumps_only_at_a_step():
    n = 100
    ramp = np.linspace(20.0, 21.0, n)[:, None]
    step = np.where(np.arange(n) < 40, 20.0, 21.2)[:, None]
    np.testing.assert_allclose(matched_walk_q(ramp)[:, 0], (1.0 / (n - 1)) ** 2, rtol=1e-9)
    q = matched_walk_q(step)[:, 0]
    # elsewhere the floor, a walk of 1e-4·ω over the record
    assert q[39] == pytest.approx(1.2**2) and np.allclose(q[np.arange(n) != 39], (1e-4 * 20.0) ** 2 / n)


def test_a_cell_under_a_white_force_has_both_bounds_and_the_genie_is_the_lower():
    from experiments.simulate.tracking_data import TrackingCellConfig, make_cell

    cfg = TrackingCellConfig(schedule={"drift": 0.05}, excitation={"disturbance_force_n": 5.0}, noise_ug=300.0,
                             duration_s=10.0, replicates=2)
    cell = make_cell(cfg)
    genie, unknown = cell["pcrb_std_rad_s"], cell["pcrb_unknown_force_std_rad_s"]
    assert genie.shape == unknown.shape == (2, 500, 4)
    assert np.all(unknown >= genie * (1 - 1e-9))
    assert np.median(unknown[:, -100:] / genie[:, -100:]) > 4          # 8.9 on this 10 s cell


def test_pulses_are_known_to_both_bounds_so_a_pulse_cell_has_one_bound():
    from experiments.simulate.tracking_data import TrackingCellConfig, make_cell

    cfg = TrackingCellConfig(schedule={"step": [0.0, 0.0, 0.05, 0.0], "step_time_s": 5.0},
                             excitation={"thruster_torque_n_m": 100.0, "thruster_rate_hz": 0.5}, noise_ug=1000.0,
                             duration_s=10.0, replicates=2)
    cell = make_cell(cfg)
    np.testing.assert_allclose(cell["pcrb_unknown_force_std_rad_s"], cell["pcrb_std_rad_s"], rtol=1e-9)


def line_record_covariance(theta, n, sigma, p_x0):
    """The covariance of y_0…y_{N−1} when the frequency is a line, ω_k = ω₀ + kΔt·ω̇ (the system frozen at
    ω_k over sample k, each sample's matrices from scipy's zero-order hold), x_0 ~ N(0, p_x0) fixed."""
    w0, zeta, rate = theta
    mats = [discrete(w0 + k * DT * rate, zeta) for k in range(n)]
    obs, lower = np.empty((n, 2)), np.zeros((n, n))
    to_k = np.eye(2)                                   # A_{k−1}⋯A_0
    for k in range(n):
        _, _, cd, dd = mats[k]
        obs[k] = (cd @ to_k)[0]
        lower[k, k] = dd[0, 0]
        after = cd.copy()                              # C_k A_{k−1}⋯A_{j+1}
        for j in range(k - 1, -1, -1):
            lower[k, j] = (after @ mats[j][1])[0, 0]
            after = after @ mats[j][0]
        to_k = mats[k][0] @ to_k
    return obs @ p_x0 @ obs.T + FORCE**2 * lower @ lower.T + sigma**2 * np.eye(n)


@pytest.mark.parametrize("rate_std", [0.3, 3.0])
def test_unknown_rate_bound_equals_exact_fisher_information_of_a_line(rate_std):
    # θ = (ω₀, ζ, ω̇), the truth ω̇ = 0; the level at the last sample, ω₀ + (N−1)Δt ω̇, has the variance
    # gᵀ(I + I_prior)⁻¹g. 2.4 s, 400 replicates: 0.99 and 0.98 of it (seed 5); without the rate the bound's
    # information is 1.4× and 4.4× higher, so the check sees the rate
    n, sigma = 120, 1e-4
    model, x, u = stationary_records(n, 400, seed=5)
    ad, bd, _, _ = discrete(W0, ZETA)
    p_x0 = scipy.linalg.solve_discrete_lyapunov(ad, FORCE**2 * bd @ bd.T)
    prior_var = np.array([(0.1 * W0) ** 2, (0.5 * ZETA) ** 2, rate_std**2])
    std = unknown_force_pcrb(model, np.full((n, 1), W0), x, DT, sigma, np.array([W0]), force_std_n=FORCE, u=u,
                             rw_q=np.zeros(1), P0=scipy.linalg.block_diag(p_x0, np.diag(prior_var)),
                             rate_std=rate_std)
    theta, scale = np.array([W0, ZETA, 0.0]), np.array([W0, ZETA, 1.0])
    c_inv = np.linalg.inv(line_record_covariance(theta, n, sigma, p_x0))
    dc = []
    for i in range(3):
        h = np.zeros(3)
        h[i] = 1e-6 * scale[i]
        dc.append((line_record_covariance(theta + h, n, sigma, p_x0)
                   - line_record_covariance(theta - h, n, sigma, p_x0)) / (2 * h[i]))
    info = np.array([[0.5 * np.trace(c_inv @ a @ c_inv @ b) for b in dc] for a in dc]) + np.diag(1 / prior_var)
    g = np.array([1.0, 0.0, (n - 1) * DT])
    assert np.mean(1.0 / std[:, -1, 0] ** 2) == pytest.approx(1.0 / (g @ np.linalg.solve(info, g)), rel=0.08)


def test_unknown_rate_bound_is_about_twice_the_constants_on_a_long_record_and_refuses_a_bad_rate():
    # a diffuse rate over 60 s (60 correlation times): a line's end point from N equally informative samples
    # has (4N − 2)/(N + 1) ≈ 4 times a constant's variance; 1.84–2.25 in std here, median 1.95
    n = 3000
    model, x, u = stationary_records(n, 4, seed=3)
    w, prior = np.full((n, 1), W0), np.array([W0])
    const = unknown_force_pcrb(model, w, x, DT, 1e-4, prior, force_std_n=FORCE, u=u, rw_q=np.zeros(1))
    line = unknown_force_pcrb(model, w, x, DT, 1e-4, prior, force_std_n=FORCE, u=u, rw_q=np.zeros(1),
                              rate_std=10.0)
    assert np.median(line[:, -1, 0] / const[:, -1, 0]) == pytest.approx(2.0, rel=0.08)
    with pytest.raises(ValueError, match=r"rate_std = \[-1.0\] must be finite numbers > 0"):
        unknown_force_pcrb(model, w, x, DT, 1e-4, prior, force_std_n=FORCE, u=u, rate_std=-1.0)


def test_a_drift_over_the_whole_record_carries_the_unknown_rate_bound_and_a_step_does_not():
    from experiments.simulate.tracking_data import TrackingCellConfig, is_line, make_cell

    drift = make_cell(TrackingCellConfig(schedule={"drift": 0.05}, excitation={"disturbance_force_n": 5.0},
                                         noise_ug=300.0, duration_s=20.0, replicates=2))
    line, walk = drift["pcrb_unknown_rate_std_rad_s"], drift["pcrb_unknown_force_std_rad_s"]
    assert line.shape == walk.shape == (2, 1000, 4)
    # not told the rate, the level is less certain than with the schedule's walk, which knows it
    assert np.median(line[:, 500:] / walk[:, 500:]) > 1.2           # 1.37 on this 20 s cell
    step = make_cell(TrackingCellConfig(schedule={"step": [0.0, 0.0, 0.05, 0.0], "step_time_s": 10.0},
                                        excitation={"disturbance_force_n": 5.0}, noise_ug=300.0, duration_s=20.0,
                                        replicates=1))
    assert "pcrb_unknown_rate_std_rad_s" not in step
    t = np.arange(100.0)[:, None]
    assert is_line(20.0 + 0.01 * t) and is_line(np.full((100, 2), 3.0))
    assert not is_line(20.0 + 0.01 * np.minimum(t, 50.0)) and not is_line(20.0 * (1 + 0.02 * np.sin(0.1 * t)))
