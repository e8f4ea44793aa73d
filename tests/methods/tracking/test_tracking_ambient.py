"""``akf_ambient`` and ``rpem_ambient``: the model's pieces against independent computations, refusals, and the
late estimate on a stationary white-force record against the batch innovation-form ``pem``.

(Causality: test_tracking_causal.py covers both through ``methods.track_names()``, and ``akf_ambient``'s rate
state and accumulated single-force fit. The coverage of the reported 1σ on the grid's cells is measured by
``python -m experiments.benchmarks.tracking_ambient``; here it is checked on stationary records.)
"""

import numpy as np
import pytest
import scipy.signal
import scipy.stats
from _tracking_signals import DT, driven_modes, schedule

import methods
from methods.tracking import _ambient

PRIOR = [3.8, 16.0, 26.0, 46.0]
Y = np.cos(3.3 * DT * np.arange(1000)) + 0.5 * np.cos(20.3 * DT * np.arange(1000))

BAD = [
    ("akf_ambient", {"rate_rel_per_s": 0.0}, "rate_rel_per_s = 0.0"),
    ("akf_ambient", {"damping_ratio": 1.5}, "damping_ratio = 1.5"),
    ("akf_ambient", {"force_model": "several"}, "force_model = 'several'"),
    ("akf_ambient", {"window_s": 100.0}, "longer than the record"),
    ("akf_ambient", {"hop_s": 0.001}, "hop_s = 0.001"),
    ("akf_ambient", {"restart_after": 0}, "restart_after = 0"),
    ("akf_ambient", {"refit_looks": 1.5}, "refit_looks = 1.5"),
    ("akf_ambient", {"frequency_model": "spline"}, "frequency_model = 'spline'"),
    ("akf_ambient", {"trend_horizon_s": 0.0}, "trend_horizon_s = 0.0"),
    ("akf_ambient", {"fit_memory_looks": 0}, "fit_memory_looks = 0"),
    ("akf_ambient", {"slosh_periods": (20.0, 3.0)}, "slosh_periods = (20.0, 3.0)"),
    ("akf_ambient", {"slosh_damping": 0.0}, "slosh_damping = 0.0"),
    ("akf_ambient", {"slosh_gate": -1.0}, "slosh_gate = -1.0"),
    ("rpem_ambient", {"estimate_damping": "yes"}, "estimate_damping = 'yes'"),
    ("rpem_ambient", {"pulse_gate": -1.0}, "pulse_gate = -1.0"),
    ("rpem_ambient", {"colour": "red"}, "unknown option 'colour'"),
    ("rpem_ambient", {"frequency_model": "spline"}, "frequency_model = 'spline'"),
    ("rpem_ambient", {"trend_horizon_s": 0.0}, "trend_horizon_s = 0.0"),
    ("rpem_ambient", {"recursions": "three"}, "recursions = 'three'"),
    ("rpem_ambient", {"recursions": "two"}, "needs frequency_model = 'trend'"),
    ("rpem_ambient", {"frequency_model": "trend", "recursions": "two", "reset_gate": 0.0}, "reset_gate = 0.0"),
    ("rpem_ambient", {"frequency_model": "trend", "recursions": "two", "score_reset": "yes"}, "score_reset = 'yes'"),
    ("rpem_ambient", {"score_reset": True}, "score_reset = true needs recursions = 'two'"),
    ("rpem_ambient", {"pair_peaks": 1}, "pair_peaks = 1"),
    ("rpem_ambient", {"rate_test": "yes"}, "rate_test = 'yes'"),
    ("rpem_ambient", {"frequency_model": "trend", "recursions": "two", "rate_test": "all"},
     "rate_test = 'all' needs score_reset = true"),
    ("rpem_ambient", {"frequency_model": "trend", "recursions": "two", "rate_test": "after_change"},
     "rate_test = 'after_change' needs score_reset = true"),
]


@pytest.mark.parametrize("name, options, words", BAD, ids=[f"{n}-{next(iter(o))}" for n, o, _ in BAD])
def test_bad_options_are_one_line_naming_the_option(name, options, words):
    with pytest.raises(ValueError) as err:
        methods.track(name, Y, DT, PRIOR, **options)
    assert words in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(ValueError, match=words.split(" ")[0]):
        methods.check_track_options(name, PRIOR, DT, options, n_samples=Y.size)


@pytest.mark.parametrize("zeta", [0.0, 0.005, 0.2])
def test_held_force_column_is_the_zero_order_hold_discretisation(zeta):
    """Γ = A⁻¹(Φ − I)B against scipy.signal.cont2discrete (zero-order hold) of each oscillator."""
    w = np.array([3.2, 20.0, 56.7, 140.0])
    phi, _ = _ambient.modal_transition(w, zeta, DT)
    g = _ambient._gamma(phi, w, zeta)
    for i, wi in enumerate(w):
        A = np.array([[0.0, 1.0], [-wi * wi, -2 * zeta * wi]])
        ad, bd, *_ = scipy.signal.cont2discrete((A, np.array([[0.0], [1.0]]), np.eye(2), np.zeros((2, 1))), DT)
        np.testing.assert_allclose(phi[i], ad, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(g[i], bd[:, 0], rtol=1e-9, atol=1e-15)


def test_modal_response_is_the_discrete_transfer_function():
    """G_i(e^{jθ}) = C_i(zI − Φ_i)⁻¹Γ_i (closed-form adjugate) against a linear solve at each frequency."""
    w, zeta = np.array([3.2, 22.0]), 0.01
    f = np.linspace(0.05, 20.0, 57)
    G = _ambient._modal_response(f, w, zeta, DT)
    phi, _ = _ambient.modal_transition(w, zeta, DT)
    g = _ambient._gamma(phi, w, zeta)
    z = np.exp(2j * np.pi * f * DT)
    for i in range(w.size):
        c = np.array([-w[i] ** 2, -2 * zeta * w[i]])
        ref = [c @ np.linalg.solve(zk * np.eye(2) - phi[i], g[i]) for zk in z]
        np.testing.assert_allclose(G[:, i], ref, rtol=1e-9)


def test_periodogram_floor_is_the_white_noise_variance():
    """r̂ of white noise alone is its variance: the median periodogram bin over ln 2 (a bin of white noise is
    its PSD times an exponential variable); no mode takes any variance above the floor worth a mode."""
    rng = np.random.default_rng(5)
    sigma = 0.01
    _, r, var, _ = _ambient.periodogram_look(sigma * rng.standard_normal(4096), DT, np.array(PRIOR), 0.3, 0.005)
    assert 0.9 * sigma**2 < r < 1.1 * sigma**2
    assert np.all(var < 0.2 * sigma**2 * 4096 * DT)


@pytest.mark.parametrize("true_pair, ref_pair", [((18.8, 20.3), (18.8, 22.2)), ((20.0, 21.6), (18.0, 21.6))])
def test_pair_peaks_assign_a_stepped_mode_beyond_the_midpoint(true_pair, ref_pair):
    """Two sinusoids of a close pair (2.3 Fourier bins apart in a 9.8 s window), one of them beyond the
    geometric midpoint of the estimates (the first: mode 3 stepped down under mode 2's band; the second:
    mode 2 stepped up into mode 3's): its band's maximum lies on the edge, so the plain look finds no peak;
    with ``pair_edges`` it finds the sinusoid's frequency within a quarter of the resolution 2π/T, and the
    other mode's peak is unchanged."""
    n = int(round(9.8 / DT))
    t = np.arange(n) * DT
    w2, w3 = true_pair
    y = 2.0 * np.sin(w2 * t) + np.sin(w3 * t + 0.7) if ref_pair[0] == w2 else np.sin(w2 * t) + 2.0 * np.sin(w3 * t)
    y = y + 0.01 * np.random.default_rng(3).standard_normal(n)
    ref = np.array([3.2, *ref_pair, 55.0])
    plain, *_ = _ambient.periodogram_look(y, DT, ref, 0.3, 0.005)
    paired, *_ = _ambient.periodogram_look(y, DT, ref, 0.3, 0.005, pair_edges=True)
    moved = 2 if ref_pair[0] == w2 else 1          # the mode whose new peak lies beyond the midpoint
    assert np.isnan(plain[moved])
    assert abs(paired[moved] - true_pair[moved - 1]) < 0.25 * 2 * np.pi / (n * DT)
    assert paired[3 - moved] == plain[3 - moved]
    assert abs(plain[3 - moved] - true_pair[2 - moved]) < 0.25 * 2 * np.pi / (n * DT)


def test_pair_peaks_act_only_on_an_edge_that_is_the_midpoint_to_a_neighbour():
    """A periodogram rising through mode 1's whole band (3.2 rad/s ± 30 %, its upper edge 4.16 rad/s, far below
    the midpoint 8 rad/s to mode 2) to a bump at 15 rad/s and mode 2's line at 20 rad/s: the band's maximum is
    on its own edge, no neighbour's, so mode 1 keeps no peak instead of taking the bump (+370 %). Mode 3's
    maximum on its lower edge, capped at the midpoint to mode 2, is paired: it takes the line at 20.7 rad/s
    beside mode 2's."""
    w = np.linspace(0.5, 80.0, 4000)
    p = (np.exp(-0.5 * (w - 15.0) ** 2) + 5.0 * np.exp(-2.0 * (w - 20.0) ** 2) + 1e-3 * w
         + 3.0 * np.exp(-0.5 * ((w - 20.7) / 0.1) ** 2))
    ref = np.array([3.2, 20.0, 22.0, 55.0])
    lo, hi = _ambient._bands(ref, 0.3)
    peak = np.array([np.nan, 20.0, np.nan, 55.0])
    sel = (w >= lo[0]) & (w <= hi[0])
    assert np.argmax(p[sel]) == sel.sum() - 1 and hi[0] < np.sqrt(ref[0] * ref[1])
    out = _ambient._pair_edge_peaks(w, w / (2 * np.pi), p, np.log(p), peak, lo, hi, ref)
    assert np.isnan(out[0])
    assert lo[2] == pytest.approx(np.sqrt(20.0 * 22.0)) and out[2] == pytest.approx(20.7, abs=0.02)


@pytest.fixture(scope="module")
def stationary():
    w = schedule(3000)
    return driven_modes(w, force=1.0, noise_ug=300.0, seed=11), w[0]


TWO = {"frequency_model": "trend", "recursions": "two"}


@pytest.mark.parametrize("name, options", [("akf_ambient", {}), ("rpem_ambient", {"frequency_model": "trend"}),
                                           ("rpem_ambient", TWO)],
                         ids=["akf_ambient", "rpem_ambient-trend", "rpem_ambient-two"])
def test_late_estimate_agrees_with_batch_innovation_form_pem(stationary, name, options):
    """On a stationary white-force record the tracker's mean estimate over its last 15 s and the batch
    innovation-form pem (``predictor="kalman"``, its own noise model) of the same 15 s agree within the scatter
    of the two: 4σ of the difference, σ² = the tracker's reported variance + pem's reported one. Compared on the
    modes pem reports determined (with the paper's fixed gain it determines mode 1 here and loses modes 2–4,
    which is pem's limit on a forced record, not the tracker's), at least one."""
    y, truth = stationary
    tr = methods.track(name, y, DT, truth * np.array([1.03, 0.97, 1.02, 1.04]), **options)   # a prior 2–4 % off
    last = tr.t_s >= tr.t_s[-1] - 15.0
    mine = tr.frequencies[last].mean(axis=0)
    my_std = np.median(tr.std[last], axis=0)
    est = methods.get("pem")(y[-750:], DT, mine, predictor="kalman")
    ok = est.converged_per_mode & np.isfinite(est.std)
    assert ok.any()
    tol = 4 * np.sqrt(my_std**2 + est.std**2)
    assert np.all(np.abs(mine - est.frequencies)[ok] <= tol[ok]), (mine, est.frequencies, tol, ok)
    assert np.all(np.abs(mine - truth) <= 4 * my_std + 0.01 * truth)


def test_whittle_fit_finds_the_sign_pattern_and_direct_term_of_one_force():
    """A spectrum built from one force behind four modes (gains of mixed signs, a direct term) and white
    noise: on the exact spectrum the least Whittle loss is at the true sign pattern, α = d²/r̂ and sign of d;
    on periodograms drawn from it (each bin the spectrum times an exponential variable, Whittle's model of a
    periodogram) the forgetting sum over 30 looks finds the same."""
    w, zeta = np.array([3.23, 20.24, 22.0, 56.67]), 0.005
    b_true, d_true, r_v = np.array([0.027, -0.015, -0.007, 0.009]), -0.0029, 0.0029**2 / 9
    f = np.arange(0, 4 * 256 + 1) / (4 * 512 * DT)               # periodogram_look's bins for a 512-sample window
    G = _ambient._modal_response(f, w, zeta, DT)
    M = 2 * DT * (np.abs(G @ b_true + d_true) ** 2 + r_v)
    var = w * DT * b_true**2 / (4 * zeta)       # each mode's acceleration variance (the gains are per sample)
    r_hat = d_true**2 + r_v                                       # the floor holds the direct term and the noise
    b, d, rv = _ambient.fit_single_force((f, M), w, zeta, DT, var, r_hat)
    np.testing.assert_array_equal(np.sign(b), np.sign(b_true))
    np.testing.assert_allclose(np.abs(b), np.abs(b_true), rtol=1e-9)
    assert np.sign(d) == np.sign(d_true) and abs(d * d - d_true**2) <= 0.1 * r_hat and rv <= 0.15 * r_hat
    rng = np.random.default_rng(3)
    acc = None
    for _ in range(30):
        loss = _ambient.whittle_losses((f, M * rng.exponential(size=f.size)), w, zeta, DT, var, r_hat)
        acc = loss if acc is None else (1 - 1 / 30) * acc + loss
    b, d, _ = _ambient.single_force_from_losses(acc, w, zeta, DT, var, r_hat)
    np.testing.assert_array_equal(np.sign(b), np.sign(b_true))
    assert np.sign(d) == np.sign(d_true)


def test_reported_std_covers_its_error_60_to_75_percent_on_stationary_records():
    """The filter's own 1σ covers |ω̂ − ω| in 60–75 % of (time, mode) after 30 s, pooled over three stationary
    white-force records (a Gaussian error within its true 1σ: 68 %). Only stationary records: on the grid's
    drift and step cells it covers 46–63 % (docs/measured/tracking_ambient.md), which this test does not claim."""
    inside = []
    for seed in (1, 2, 3):
        w = schedule(4500)
        y = driven_modes(w, force=1.0, noise_ug=300.0, seed=seed)
        tr = methods.track("akf_ambient", y, DT, w[0] * np.array([1.03, 0.97, 1.02, 1.04]))
        late = tr.t_s >= 30.0
        inside.append(np.abs(tr.frequencies[late] - w[0]) <= tr.std[late])
    share = float(np.mean(np.concatenate(inside)))
    assert 0.60 <= share <= 0.75, share


def _rpem_step_numpy(theta, P, x, W, lam, yk, m, est_z, dt, nu2, gam, gate, zeta0, kscale, q_fixed, lo, hi):
    """One sample of ``rpem_ambient`` written from its docstring's equations in numpy: Φ and ∂Φ/∂ω closed
    form (``modal_transition``), ∂Φ/∂ζ by complex step, ∂C/∂θ by hand."""
    nz = m if est_z else 0
    p = theta.size
    w = theta[:m]
    z = theta[m:2 * m] if est_z else np.full(m, zeta0)
    K = theta[m + nz:] * kscale
    phi, dphi = _ambient.modal_transition(w, z, dt)
    dphz = _ambient.modal_transition(w, z + 1e-20j, dt)[0].imag / 1e-20
    C = np.column_stack([-w * w, -2 * z * w]).ravel()
    xi = x.reshape(m, 2)
    e = yk - C @ x
    dC = np.zeros(p)
    dC[:m] = -2 * w * xi[:, 0] - 2 * z * xi[:, 1]
    if est_z:
        dC[m:2 * m] = -2 * w * xi[:, 1]
    psi = C @ W + dC
    Pm = P + np.diag(np.concatenate([nu2 * dt * w * w, q_fixed[m:]]))
    S = psi @ Pm @ psi + lam
    pulse = S > 0 and e * e > gate * S
    if S > 0 and not pulse:
        L = Pm @ psi / S
        theta_new = theta + L * e
        theta_new[:m] = np.clip(theta_new[:m], lo, hi)
        theta_new[m:m + nz] = np.clip(theta_new[m:m + nz], 1e-4, 0.2)
        P_new = Pm - np.outer(L, Pm @ psi)
        P_new = 0.5 * (P_new + P_new.T)
        lam_new = lam + gam * (e * e - lam)
    else:
        theta_new, P_new, lam_new = theta, Pm, lam
    Fb = scipy.linalg.block_diag(*phi)
    M = np.zeros((2 * m, p))
    for i in range(m):
        M[2 * i:2 * i + 2, i] = dphi[i] @ xi[i]
        if est_z:
            M[2 * i:2 * i + 2, m + i] = dphz[i] @ xi[i]
    M[np.arange(2 * m), m + nz + np.arange(2 * m)] = kscale * e
    W_new = (Fb - np.outer(K, C)) @ W + M - np.outer(K, dC)
    x_new = Fb @ x + K * e
    updated = S > 0 and not pulse
    score = psi[:m] * e / S if updated else np.zeros(m)
    info = psi[:m] ** 2 / S if updated else np.zeros(m)
    return theta_new, P_new, x_new, W_new, lam_new, pulse, score, info


@pytest.mark.parametrize("est_z", [True, False])
@pytest.mark.parametrize("yk", [0.3, 1e4], ids=["update", "pulse"])
def test_rpem_casadi_step_is_the_numpy_recursion(est_z, yk):
    """``rpem_ambient``'s per-sample step (a CasADi function, algorithmic derivatives) against the same
    equations in numpy at a random state, on an update and on a pulse (e²/S over the gate)."""
    from methods.tracking import _rpem

    rng = np.random.default_rng(7 + est_z)
    m = 3
    nz = m if est_z else 0
    p = 3 * m + nz
    w = np.array([3.1, 20.0, 47.0])
    theta = np.concatenate([w, np.full(nz, 0.01), 0.1 * rng.standard_normal(2 * m)])
    A = rng.standard_normal((p, p))
    P = 1e-3 * (A @ A.T + np.eye(p))
    x, W = 0.01 * rng.standard_normal(2 * m), 0.01 * rng.standard_normal((2 * m, p))
    lam = 0.04
    kscale = np.ravel(np.column_stack([1 / w**2, 1 / w]))
    q_fixed = np.concatenate([np.zeros(m), 1e-6 * rng.uniform(size=p - m)])
    consts = dict(dt=DT, nu2=1e-5, gam=0.002, gate=25.0, zeta0=0.005, kscale=kscale, q_fixed=q_fixed,
                  lo=w / 1.3, hi=w * 1.3)
    ref = _rpem_step_numpy(theta, P, x, W, lam, yk, m, est_z, **consts)
    const = np.concatenate([[DT, 1e-5, 0.002, 25.0, 0.005], kscale, q_fixed, w / 1.3, w * 1.3])
    state = np.concatenate([theta, P.ravel(), x, W.ravel(order="F"), [lam]])
    new, out = (np.asarray(v).ravel() for v in _rpem._step_function(m, est_z)(state, yk, const))
    got = (new[:p], new[p:p + p * p].reshape(p, p), new[p + p * p:p + p * p + 2 * m],
           new[p + p * p + 2 * m:-1].reshape((2 * m, p), order="F"), new[-1])
    for a, b in zip(got, ref[:5], strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    assert bool(out[-1]) == ref[5] == (yk > 1)
    np.testing.assert_allclose(out[:m], ref[0][:m], rtol=1e-12)
    # each frequency's score ψᵢe/S and information ψᵢ²/S (0 on a pulse), after ω̂, P_ωω and ζ̂
    j0 = 2 * m + nz
    np.testing.assert_allclose(out[j0:j0 + m], ref[6], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out[j0 + m:j0 + 2 * m], ref[7], rtol=1e-9, atol=1e-12)


def _two_memories(gap_sigmas):
    """A whole-record recursion [θ, P, x̂, W, Λ] and a window one (θ', P') of 3 modes, θ = [ω (3), ζ (3), K (6),
    ω̇ (3)], P and P' diagonal with ω's variance 1e-4 and 3e-4 (σ of the difference 0.02), ω' − ω =
    ``gap_sigmas`` × 0.02, and cross-covariances of ω with ω̇ in both."""
    p = 15
    iw, ia = np.arange(3), np.arange(12, 15)
    th = np.arange(1.0, p + 1.0)
    P = np.diag(np.full(p, 1e-4))
    P[0, 12] = P[12, 0] = 1e-6
    th_w = th.copy()
    th_w[iw] += 0.02 * np.asarray(gap_sigmas)
    th_w[ia] += 0.5
    P_w = np.diag(np.full(p, 3e-4))
    P_w[0, 12] = P_w[12, 0] = 2e-6
    P_w[1, 2] = P_w[2, 1] = 5e-5
    long = [th, P, np.zeros(6), np.ones((6, p)), 1.0]
    return long, th_w, P_w, iw, ia


def test_two_memories_reset_only_disagreeing_modes_after_the_likelihood_ratio():
    """``recursions="two"``'s interaction, by hand: below restart_gate²/2 (8 nats at 4σ) of likelihood ratio nothing
    moves; above it the modes whose ω differ by more than reset_gate (3) σ of the difference — modes 0 and 2 of
    gaps 10σ, 0.5σ, 3.5σ — take the window recursion's ω and rate and their covariance block (the cross terms to
    the rest 0), their sensitivity columns 0; mode 1 and every other entry stay."""
    from methods.estimate import make_options
    from methods.tracking import _rpem

    opts = make_options(_rpem.Options, TWO, "rpem_ambient")
    long, th_w, P_w, iw, ia = _two_memories([10.0, 0.5, 3.5])
    before = [np.copy(v) for v in long]
    assert _rpem._reset_from_window(long, th_w, P_w, iw, ia, 7.9, opts).size == 0
    for a, b in zip(long, before, strict=True):
        np.testing.assert_array_equal(a, b)
    assert list(_rpem._reset_from_window(long, th_w, P_w, iw, ia, 8.1, opts)) == [0, 2]
    th, P, _, W, _ = long
    reset = np.array([0, 2, 12, 14])
    np.testing.assert_array_equal(th[reset], th_w[reset])
    kept = np.setdiff1d(np.arange(15), reset)
    np.testing.assert_array_equal(th[kept], before[0][kept])
    np.testing.assert_array_equal(P[np.ix_(reset, reset)], [[3e-4, 0, 2e-6, 0], [0, 3e-4, 0, 0],
                                                          [2e-6, 0, 3e-4, 0], [0, 0, 0, 3e-4]])
    np.testing.assert_array_equal(P[np.ix_(kept, kept)], before[1][np.ix_(kept, kept)])
    assert not P[np.ix_(reset, kept)].any()
    assert not W[:, reset].any() and (W[:, kept] == 1).all()


def test_score_reset_also_resets_a_mode_whose_score_points_to_the_window_estimate():
    """``score_reset``, by hand: gaps of 0.5σ of the difference on all three modes (none beyond reset_gate 3σ),
    scores z = 4 toward the window recursion's ω̂' (mode 0), 4 away from it (mode 1), 2 toward it (mode 2):
    below the likelihood ratio's 8 nats nothing moves; above it only mode 0 is reset, taking the window's ω and
    its variance, its rate 0 ± the stated rate (``rate_var``), no cross-covariance, sensitivities 0."""
    from methods.estimate import make_options
    from methods.tracking import _rpem

    opts = make_options(_rpem.Options, TWO | {"score_reset": True}, "rpem_ambient")
    long, th_w, P_w, iw, ia = _two_memories([0.5, 0.5, 0.5])
    z = np.array([4.0, -4.0, 2.0])           # ω̂' > ω̂ on every mode: a positive score points toward it
    rate_var = np.array([1e-6, 2e-6, 3e-6])
    before = [np.copy(v) for v in long]
    assert _rpem._reset_from_window(long, th_w, P_w, iw, ia, 7.9, opts, z, rate_var).size == 0
    for a, b in zip(long, before, strict=True):
        np.testing.assert_array_equal(a, b)
    assert list(_rpem._reset_from_window(long, th_w, P_w, iw, ia, 8.1, opts, z, rate_var)) == [0]
    th, P, _, W, _ = long
    assert th[0] == th_w[0] and th[12] == 0.0
    np.testing.assert_array_equal(P[np.ix_([0, 12], [0, 12])], [[3e-4, 0.0], [0.0, 1e-6]])
    kept = np.setdiff1d(np.arange(15), [0, 12])
    np.testing.assert_array_equal(th[kept], before[0][kept])
    np.testing.assert_array_equal(P[np.ix_(kept, kept)], before[1][np.ix_(kept, kept)])
    assert not P[np.ix_([0, 12], kept)].any()
    assert not W[:, [0, 12]].any() and (W[:, kept] == 1).all()
    # without the scores (score_reset off) the same gaps reset nothing
    long, *_ = _two_memories([0.5, 0.5, 0.5])
    assert _rpem._reset_from_window(long, th_w, P_w, iw, ia, 8.1, opts).size == 0


def test_two_memories_variance_is_the_mixture_error_of_the_whole_record_estimate():
    """The reported variance against its formula evaluated by hand: odds 0 (μ = ½), ln 3 (μ = ¾), −50 (μ → 0)."""
    from methods.tracking import _rpem

    w, v, w2, v2 = np.array([10.0, 20.0]), np.array([0.01, 0.04]), np.array([10.2, 19.0]), np.array([0.02, 0.09])
    np.testing.assert_allclose(_rpem._variance_two(w, v, w2, v2, 0.0), [0.5 * 0.01 + 0.5 * (0.02 + 0.04),
                                                                        0.5 * 0.04 + 0.5 * (0.09 + 1.0)])
    np.testing.assert_allclose(_rpem._variance_two(w, v, w2, v2, np.log(3.0)),
                               [0.25 * 0.01 + 0.75 * 0.06, 0.25 * 0.04 + 0.75 * 1.09])
    np.testing.assert_allclose(_rpem._variance_two(w[None], v[None], w2[None], v2[None], np.array([-50.0])),
                               v[None], rtol=1e-12)


def _level_and_rate(rate, seed):
    """A level ω plus a rate a·t seen with white noise (σ 0.05, 400 samples over 40 s, t from the record's end),
    priors ω ~ N(3, 0.1²), a ~ N(0, 0.01²): the rate model's posterior (ω at the end, a) by least squares with
    the prior, and independently each nested model's evidence (the record's Gaussian density under it,
    ``scipy.stats.multivariate_normal``) and the level model's own posterior (ω̂₀, V₀)."""
    import scipy.stats

    n, sig, sw, sa = 400, 0.05, 0.1, 0.01
    t = np.linspace(-40.0, 0.0, n)
    y = 3.02 + rate * t + sig * np.random.default_rng(seed).standard_normal(n)
    X = np.column_stack([np.ones(n), t])
    S0 = np.diag([sw ** 2, sa ** 2])
    m0 = np.array([3.0, 0.0])
    P = np.linalg.inv(np.linalg.inv(S0) + X.T @ X / sig ** 2)
    mean = P @ (np.linalg.inv(S0) @ m0 + X.T @ y / sig ** 2)
    log_e1 = scipy.stats.multivariate_normal.logpdf(y, X @ m0, X @ S0 @ X.T + sig ** 2 * np.eye(n))
    log_e0 = scipy.stats.multivariate_normal.logpdf(y, np.full(n, 3.0), sw ** 2 + sig ** 2 * np.eye(n))
    v0 = 1.0 / (1 / sw ** 2 + n / sig ** 2)
    return mean, P, log_e1, log_e0, v0 * (3.0 / sw ** 2 + y.sum() / sig ** 2), v0, sa ** 2


@pytest.mark.parametrize("joint", [False, True], ids=["mode", "all"])
@pytest.mark.parametrize("rates, weights", [((0.0, 3e-4), ((0.55, 0.99), (0.05, 0.8))),
                                            ((0.0, 6e-3), ((0.55, 0.99), (0.0, 0.01)))], ids=["between", "drift"])
def test_zero_rate_average_is_the_average_of_the_two_batch_models(rates, weights, joint):
    """``rate_test``'s average against both nested models computed in batch (:func:`_level_and_rate`), two modes,
    each seen on its own record. Per mode (``"mode"``) μ₀ᵢ is the mode's own evidence ratio at equal prior
    odds; for every rate at once (``"all"``) one μ₀ from the summed log evidences of "no rate" and "every rate
    free". The average μ₀ω̂₀ + (1 − μ₀)ω̂ and its mixture variance must agree with ``_zero_rate_average`` fed
    the rate model's posterior alone. ``weights``: each record's μ₀ — no rate favours the level, 3e-4 per s
    (1.4σ of the record's rate) is undecided, 6e-3 (0.6σ of the rate's prior, 27σ of the record's) the rate's."""
    from methods.tracking import _rpem

    recs = [_level_and_rate(r, 31 + i) for i, r in enumerate(rates)]
    mean = np.array([r[0] for r in recs])
    P = [r[1] for r in recs]
    w_bar, v_bar = _rpem._zero_rate_average(mean[:, 0], np.array([p[0, 0] for p in P]), mean[:, 1],
                                            np.diag([p[0, 1] for p in P]), np.diag([p[1, 1] for p in P]),
                                            np.array([r[6] for r in recs]), joint)
    mu0 = np.array([1.0 / (1.0 + np.exp(r[2] - r[3])) for r in recs])
    for m, (lo, hi) in zip(mu0, weights, strict=True):
        assert lo <= m <= hi, mu0
    if joint:
        mu0 = np.full(2, 1.0 / (1.0 + np.exp(sum(r[2] - r[3] for r in recs))))
    w0, v0 = np.array([r[4] for r in recs]), np.array([r[5] for r in recs])
    w_ref = mu0 * w0 + (1 - mu0) * mean[:, 0]
    v_ref = mu0 * (v0 + (w0 - w_ref) ** 2) + (1 - mu0) * (np.array([p[0, 0] for p in P]) + (mean[:, 0] - w_ref) ** 2)
    np.testing.assert_allclose(w_bar, w_ref, rtol=1e-6)
    np.testing.assert_allclose(v_bar, v_ref, rtol=1e-6)
    assert np.all(np.abs(w0 - mean[:, 0]) > 10 * np.abs(w_bar - w_ref))     # the models differ: μ₀ is tested


@pytest.fixture(scope="module")
def grid_like():
    """One replicate of the six white-force cells of ``experiments.benchmarks.tracking_ambient`` (the grid's
    drift and step at 100 and 1000 µg, the issue's +12 % drift and −7 % step), seeds 3, 5 and 13 — never the
    design (7, 11) nor the scoring (20261121) seeds — without their bounds."""
    from experiments.benchmarks.tracking_ambient import CELLS, configs
    from experiments.simulate.tracking_data import make_cell

    labels = [label for label in CELLS if "white force" in label and "slosh" not in label]
    return {(seed, label): make_cell(configs(seed, 1)[label], bounds=False) for seed in (3, 5, 13)
            for label in labels}


def _track_cell(cell, **options):
    tr = methods.track("rpem_ambient", cell["accel_m_s2"][0], float(cell["dt_s"]), cell["prior_rad_s"][0],
                       **options)
    return tr, cell["truth_freq_rad_s"][np.round(tr.t_s / float(cell["dt_s"])).astype(int)]


def test_two_memories_std_covers_its_error_60_to_75_percent_on_grid_like_records(grid_like):
    """``recursions="two"``'s 1σ covers |ω̂ − ω| in 60–75 % of (time, mode) after 30 s, pooled over the six
    white-force cells × three seeds (a Gaussian error within its 1σ: 68 %; measured 0.67–0.75 per seed)."""
    inside = []
    for cell in grid_like.values():
        tr, truth = _track_cell(cell, **TWO)
        late = tr.t_s >= 30.0
        inside.append(np.abs(tr.frequencies - truth)[late] <= tr.std[late])
    share = float(np.mean(np.concatenate(inside)))
    assert 0.60 <= share <= 0.75, share


def test_two_memories_follow_a_step_the_whole_record_alone_does_not_leave(grid_like):
    """The issue's −7 % step of modes 2–4 at 80 s (seed 3): with the resets every mode is within 1 % of the truth
    over the last 20 s (median over time); the same whole-record recursion with the resets switched off
    (``restart_gate`` 10⁶: no likelihood ratio reaches it) still has a mode beyond 1 %; on the three drift
    records of the same seed no reset fires."""
    cell = grid_like[(3, "issue: −7 % step of modes 2–4 at 80 s, white force, 100 µg")]
    late = {}
    for key, opts in (("two", TWO), ("alone", TWO | {"restart_gate": 1e6})):
        tr, truth = _track_cell(cell, **opts)
        end = tr.t_s >= tr.t_s[-1] - 20.0
        late[key] = np.median(np.abs(tr.frequencies / truth - 1)[end], axis=0)
        if key == "two":
            assert tr.extra["n_resets"] >= 1
    assert np.all(late["two"] < 0.01), late
    assert np.any(late["alone"] > 0.01), late
    for (seed, label), cell in grid_like.items():
        if seed == 3 and "drift" in label:
            assert _track_cell(cell, **TWO)[0].extra["n_resets"] == 0, label


def test_slosh_look_finds_a_known_modulation_and_none_in_a_walk():
    """Block means of two log-tracks carrying the same a = 3 % sin(2π·0.07 t) on a drift and a step, with a walk
    of their own: the differenced spectrum's line is at 0.07 Hz (± a tenth of the 80 s record's resolution
    1/80 Hz) and a²/2 within 25 % (the Hann main lobe and the median floor); the walks and the step alone,
    no modulation, pass no gate."""
    rng = np.random.default_rng(2)
    dt_block = 0.5
    t = dt_block * np.arange(160)[:, None]
    walk = np.cumsum(0.001 * rng.standard_normal((t.size, 2)), axis=0)
    base = np.log([3.2, 22.0]) + 0.0005 * t + 0.05 * (t > 40) + walk
    f, v = _ambient.slosh_look(base + 0.03 * np.sin(2 * np.pi * 0.07 * t), np.array([1.0, 3.0]), dt_block,
                               (0.026, 0.17), 10.0)
    assert abs(f - 0.07) < 0.1 / 80 and abs(v / (0.03**2 / 2) - 1) < 0.25, (f, v)
    f, v = _ambient.slosh_look(base, np.array([1.0, 3.0]), dt_block, (0.026, 0.17), 10.0)
    assert np.isnan(f) and v == 0.0


def test_slosh_model_follows_a_modulation_the_walk_lags():
    """Three modes (3.23, 20.24, 56.67 rad/s) modulated by one wave, ωᵢ(t) = ωᵢ(1 + a sin 2π·0.07 t), a = 3 %
    (the grid's slosh amplitude at the issue's rate), white force, 100 µg, 100 s; (time, mode) after 60 s of
    seeds 1–3 pooled. The walk does not follow the wave: its median error is the wave's own rms a/√2 = 2.1 %
    (measured 2.2 %). The shared modulation's is below 0.8 × a/√2 (an independent number: the error of a
    tracker that does not follow the wave) and below 0.8 × the walk's (measured 1.4 %: 0.65 × and 0.64 ×; per
    seed 0.86 × the walk where restarts misfire and the line found is false). On the same records without a
    modulation the shared model costs at most 20 % over the walk (measured 0.628 % against 0.629 %)."""
    n, a = 5000, 0.03
    t = DT * np.arange(n)[:, None]
    flat = schedule(n, freq=[3.23, 20.24, 56.67])
    prior = flat[0] * np.array([1.03, 0.97, 1.04])
    err = {}
    for label, w in (("slosh", flat * (1 + a * np.sin(2 * np.pi * 0.07 * t))), ("flat", flat)):
        for model in ("walk", "slosh"):
            e = []
            for seed in (1, 2, 3):
                y = driven_modes(w, force=1.0, noise_ug=100.0, seed=seed, gain=[4.0, 1.0, 1.0])
                tr = methods.track("akf_ambient", y, DT, prior, frequency_model=model)
                k = np.round(tr.t_s / DT).astype(int)
                late = tr.t_s >= 60.0
                e.append(np.abs(tr.frequencies[late] / w[k[late]] - 1).ravel())
            err[label, model] = float(np.median(np.concatenate(e)))
    assert err["slosh", "slosh"] < 0.8 * a / np.sqrt(2), err
    assert err["slosh", "slosh"] < 0.8 * err["slosh", "walk"], err
    assert err["flat", "slosh"] <= 1.2 * err["flat", "walk"], err


def test_score_reset_resets_a_stepped_mode_within_a_window_and_never_on_a_drift(grid_like):
    """``score_reset`` on the grid's step (+6 % mode 3, −4 % mode 4 at 60 s, 100 and 1000 µg) and the issue's
    −7 % step of modes 2–4, seeds 3, 5, 13: a stepped mode of the whole-record recursion is first reset within
    one window (five periods of the slowest prior mode, 9.8 s) of the step, and on the grid's steps both stepped
    modes hold within 1 % of the truth for 2 s from at most 20 s after the step (measured 3–16 s); on the nine
    drift records (grid 100/1000 µg, the issue's +12 %) no reset fires."""
    opts = TWO | {"score_reset": True}
    for (seed, label), cell in grid_like.items():
        tr, truth = _track_cell(cell, **opts)
        resets = tr.extra["reset_times_s"]
        if "drift" in label:
            assert resets == (), (seed, label, resets)
            continue
        t_step = float(cell["step_time_s"])
        stepped = np.flatnonzero(truth[-1] != truth[0])
        window = 5 * 2 * np.pi / float(cell["prior_rad_s"][0][0])
        first = min(t for t, i in resets if i in stepped and t >= t_step)
        assert first - t_step <= window, (seed, label, resets)
        if "grid" in label:
            inside = np.abs(tr.frequencies / truth - 1) < 0.01
            hold = int(round(2.0 / (tr.t_s[1] - tr.t_s[0])))
            for i in stepped:
                k = np.flatnonzero(tr.t_s >= t_step)
                ok = [j for j in k[:-hold] if inside[j:j + hold, i].all()]
                assert ok and tr.t_s[ok[0]] - t_step <= 20.0, (seed, label, i)


def test_rpem_start_std_is_sized_to_the_first_windows_resolution():
    """The first window's periodogram peak of a slow mode is as uncertain as the window's resolution allows
    (five periods resolve a fifth of ω): on 20 one-mode white-force records (3.2 rad/s, ζ 0.005, the prior 3 %
    off, simulated here by ``scipy.signal``'s zero-order hold), ``rpem_ambient``'s first estimates are 0.2–24 %
    off, and within 3 of their stated σ on 17 (a 1σ of 1 % ω, the start before 2026-11-27: on 7)."""
    w, z, dt = 3.2, 0.005, 0.02
    a = np.array([[0.0, 1.0], [-w * w, -2 * z * w]])
    sysd = scipy.signal.cont2discrete((a, np.array([[0.0], [1.0]]), a[1:], np.array([[1.0]])), dt, method="zoh")
    within = 0
    for seed in range(20):
        rng = np.random.default_rng(seed)
        n = int(15 / dt)
        _, y, _ = scipy.signal.dlsim(sysd, rng.standard_normal(n))
        y = y[:, 0] + 0.05 * np.std(y) * rng.standard_normal(n)
        tr = methods.track("rpem_ambient", y, dt, np.array([1.03 * w]))
        within += abs(tr.frequencies[0, 0] - w) <= 3 * tr.std[0, 0]
    assert within >= 16
