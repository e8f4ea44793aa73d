"""What the samples allow where ``rpem_ambient:two`` errs most: batch prediction-error fits of the ambient model
before and after a step and on the first window, and refits of the recursion by the likelihood of its own model —
a development table, not a test (pytest does not collect it).

    python tests/methods/tracking/dev/_ml_oracle_dev.py SEED [--set ambient|unseen] [--replicates R]
        [--cells "step"] [--cache DIR] [--first-window | --after-step [--kalman-grid] | --refit | --line-refit]

The modal model under any stationary white excitation (one force or several, a direct term, white measurement
noise) is an ARMA(2m, 2m) process whose autoregressive part is fixed by the modes, A(z) = Πᵢ(z² − 2e^(−ζᵢωᵢΔt)
cos(ωᵢ√(1 − ζᵢ²)Δt) z + e^(−2ζᵢωᵢΔt)), and whose monic moving-average part B(z) is free (minimum phase): the
innovation form with a free gain, as ``rpem_ambient`` models it. Its prediction errors are e = (A/B) y
(``scipy.signal.lfilter``), less the filter's free response to an unknown initial state (2m columns, projected
out by least squares); ``scipy.optimize.least_squares`` minimises Σe² over (ω, ζ, B): the prediction-error
(asymptotically maximum-likelihood) estimate of a stationary stretch, which a recursion approaches only once its
start is forgotten.

* Default: on the white-force step records whose label holds one of ``--cells``, per replicate, the fit of
  [0, step) — started at the truth with the truth's B (a genie: the steady Kalman predictor of the simulated
  model), and blind from the tracker's estimate just before the step (B from the modes' poles pulled in, ω held
  while ζ and B settle, then all free) — beside the tracker's estimate there.
* ``--after-step``: on the same records, the fits of [step, step + T) for T = 5, 10, 15, 20 s — the genie's, blind
  from the tracker's estimate at step + T, the modes of a least-squares AR(30) and a grid over the closest prior
  pair with B held at the truth's before the step — beside the tracker there and its re-convergence. With
  ``--kalman-grid`` also the same grid scored by the likelihood of a steady Kalman predictor whose noise model moves
  with each hypothesis of the pair (the modes not in the pair at the tracker's before the step): the genie's model,
  and a blind one, one white force (gains per mode, a direct term, the sensor noise; ζ = 1 %) fitted by its
  likelihood to the 30 s before the step at the tracker's ω there.
* ``--refit``: on the same records, at the whole-record recursion's last look before the step, the ω of every mode
  refitted over every sample so far by the likelihood of the steady Kalman predictor whose noise model is the
  recursion's own innovation form (its ζ and gain K held), beside the recursion's, and the likelihood it gains.
* ``--line-refit``: on the white-force drift records, at the looks nearest 60 s and 100 s, the recursion's line
  (every mode's ω and rate) refitted over the samples since its first window by the same likelihood with the
  frequencies moving along the line (a predictor in segments), and the likelihood it gains.
* ``--first-window``: on every white-force record (drifts too), the blind fit of the first window (the one the
  tracker starts from, five periods of the slowest prior mode), from the prior and from that window's Hann peaks
  (the lower Σe² kept), beside the peaks and the tracker at the window's end; tallied as ``_pair_window_dev.py``
  does on the closest prior pair (better / worse by 0.5 % of ω, or alike).
"""

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402
import scipy.optimize  # noqa: E402
import scipy.signal  # noqa: E402
from _cells import VARIANT_TWO as TWO  # noqa: E402
from _cells import reconvergence_s, step_parser, white_cells, white_step_cells  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.simulate.pcrb_force import force_noise  # noqa: E402
from experiments.simulate.plant import build_plant  # noqa: E402
from experiments.simulate.timevarying import modal_model, oscillator_transition  # noqa: E402
from methods.kalman import modal_transition  # noqa: E402
from methods.tracking import _ambient  # noqa: E402

MARGIN = 0.5    # % of ω


def ar_poly(w, z, dt):
    """A(z) of the modes, highest power first (2m + 1 coefficients)."""
    a = np.array([1.0])
    for wi, zi in zip(w, z, strict=True):
        r = np.exp(-zi * wi * dt)
        a = np.convolve(a, [1.0, -2 * r * np.cos(wi * np.sqrt(1 - zi * zi) * dt), r * r])
    return a


def residuals(theta, y, dt, m):
    """Prediction errors of (ω, ζ, b), the initial state projected out; large where B is not minimum phase."""
    w, z, b = theta[:m], theta[m:2 * m], theta[2 * m:]
    B = np.concatenate(([1.0], b))
    if np.max(np.abs(np.roots(B))) >= 0.9995:
        return np.full(y.size, 1e3 * np.std(y))
    A = ar_poly(w, z, dt)
    e0 = scipy.signal.lfilter(A, B, y)
    n0 = 2 * m
    G = np.empty((y.size, n0))
    zeros = np.zeros(y.size)
    for j in range(n0):
        zi = np.zeros(n0)
        zi[j] = 1.0
        G[:, j] = scipy.signal.lfilter(A, B, zeros, zi=zi)[0]
    c, *_ = np.linalg.lstsq(G, e0, rcond=None)
    return e0 - G @ c


def genie_model(cfg, cell, w):
    """(Φ, C, Q, S, R) of the simulated model at frequencies ``w`` (a genie): the plant's modal model
    (``timevarying.modal_model``), its unknown white force as the bound models it (``pcrb_force.force_noise``:
    process noise, its covariance with the measurement and the direct term's share), the sensor noise."""
    dt = float(cell["dt_s"])
    model = modal_model(build_plant(cfg.plant))
    z = model.damping
    phi, _ = oscillator_transition(w, z, dt)
    F = scipy.linalg.block_diag(*phi)
    C = np.concatenate([g * np.array([-wi * wi, -2 * zi * wi]) for g, wi, zi in
                        zip(model.tip_gain, w, z, strict=True)])[None, :]
    force = "force_body_y" if cfg.excitation.disturbance_at == "body" else "force_tip"
    Q, S, direct_var = force_noise(model, w[None, :], dt, cfg.excitation.disturbance_force_n, force, damping=False)
    m2 = 2 * w.size
    R = np.array([[direct_var + float(cell["noise_std_m_s2"]) ** 2]])
    return F, C, Q[0, :m2, :m2], S[0, :m2, None], R


def predictor(F, C, Q, S, R):
    """The steady Kalman predictor of (Φ, C, Q, S, R) (``scipy.linalg.solve_discrete_are``): its gain K and
    innovation variance."""
    P = scipy.linalg.solve_discrete_are(F.T, C.T, Q, R, s=S)
    var = float((C @ P @ C.T + R)[0, 0])
    return (F @ P @ C.T + S) / var, var


def true_b(cfg, cell, k: int) -> np.ndarray:
    """The truth's B(z) at sample ``k`` (a genie): ``np.poly(Φ − K C)`` of the steady Kalman predictor of
    :func:`genie_model` at that sample's frequencies, without its leading 1."""
    F, C, *noise = genie_model(cfg, cell, cell["truth_freq_rad_s"][k])
    K, _ = predictor(F, C, *noise)
    return np.poly(F - K @ C)[1:]


def predictor_innovations(y, F, C, Q, S, R, skip: int):
    """The innovations of ``y`` (the first ``skip`` dropped) under the steady Kalman predictor of (Φ, C, Q, S, R):
    e = (A/B) y (``scipy.signal.lfilter``), A = det(zI − Φ), B = det(zI − Φ + K C); returns (e, their variance, B)."""
    K, var = predictor(F, C, Q, S, R)
    B = np.poly(F - K @ C)
    return scipy.signal.lfilter(np.poly(F), B, y)[skip:], var, B


def kalman_nll(y, F, C, Q, S, R, skip: int = 25) -> float:
    """The negative log-likelihood of ``y`` under the steady Kalman predictor of (Φ, C, Q, S, R)
    (:func:`predictor_innovations`)."""
    e, var, _ = predictor_innovations(y, F, C, Q, S, R, skip)
    return 0.5 * (e.size * np.log(var) + e @ e / var)


def innovation_model(w, z, K, dt):
    """(Φ, C, Q, S, R) of the innovation form x⁺ = Φx + K e, y = Cx + e at frequencies ``w`` (Q = KKᵀ, S = K, R = 1,
    Q and R regularised by 10⁻⁶ of their scale): the noise model ``rpem_ambient`` estimates, moved to other ω."""
    m = w.size
    phi, _ = modal_transition(w, z, dt)
    Q = np.outer(K, K)
    Q += 1e-6 * (np.trace(Q) / (2 * m) + 1e-300) * np.eye(2 * m)
    return (scipy.linalg.block_diag(*phi), np.column_stack([-w * w, -2 * z * w]).ravel()[None, :], Q, K[:, None],
            np.array([[1.0 + 1e-6]]))


def force_model(w, z, dt, theta):
    """A blind noise model: one white force, zero-order held, x⁺ = Φx + Γb f, y = Cx + d f + v, f ~ N(0, 1),
    C = [−ωᵢ², −2ζᵢωᵢ] per mode (tip units); ``theta`` = [b₁…bₘ, d, ln var v]."""
    m = w.size
    phi, gamma = oscillator_transition(w[None, :], z[None, :], dt)
    F = scipy.linalg.block_diag(*phi[0])
    g = (gamma[0, :, :, 1] * theta[:m, None]).reshape(2 * m)
    C = np.concatenate([np.array([-wi * wi, -2 * zi * wi]) for wi, zi in zip(w, z, strict=True)])[None, :]
    d = theta[m]
    return F, C, np.outer(g, g), (d * g)[:, None], np.array([[d * d + np.exp(theta[m + 1])]])


def fit_force_model(y, w, z, dt) -> np.ndarray:
    """:func:`force_model`'s θ of least :func:`kalman_nll` on ``y`` at (ω, ζ) held (``scipy.optimize.minimize``,
    Nelder–Mead from two starts)."""
    m, sd = w.size, float(np.std(y))
    best = None
    for x0 in (np.concatenate((np.full(m, sd), [0.1 * sd, np.log(0.01 * sd ** 2)])),
               np.concatenate((sd * w / w[0], [sd, np.log(0.1 * sd ** 2)]))):
        def cost(th):
            try:
                return kalman_nll(y, *force_model(w, z, dt, th))
            except (ValueError, np.linalg.LinAlgError):
                return 1e12
        res = scipy.optimize.minimize(cost, x0, method="Nelder-Mead",
                                      options={"maxfev": 3000, "xatol": 1e-6, "fatol": 1e-3})
        if best is None or res.fun < best.fun:
            best = res
    return best.x


def kalman_grid(y, w, pair, model, span: float = 0.12, n: int = 33) -> np.ndarray:
    """ω with the two modes of ``pair`` at the least :func:`kalman_nll` of an n × n grid ±``span`` about ``w``, the
    noise model ``model(ω)`` → (Φ, C, Q, S, R) moving with each hypothesis."""
    i, j = pair
    best, arg = np.inf, w
    for a in 1 + np.linspace(-span, span, n):
        for c in 1 + np.linspace(-span, span, n):
            ww = w.copy()
            ww[i], ww[j] = w[i] * a, w[j] * c
            if ww[j] <= 1.01 * ww[i]:
                continue
            v = kalman_nll(y, *model(ww))
            if v < best:
                best, arg = v, ww
    return arg


def fit(y, dt, w0, z0, b0):
    """(ω, ζ, b) of least Σe² from (ω₀, ζ₀, b₀); ω bounded to ±15 % of its start, ζ to [1e-4, 0.3]."""
    m = w0.size
    x0 = np.concatenate((w0, z0, b0))
    lo = np.concatenate((0.85 * w0, np.full(m, 1e-4), np.full(2 * m, -np.inf)))
    hi = np.concatenate((1.15 * w0, np.full(m, 0.3), np.full(2 * m, np.inf)))
    x0 = np.clip(x0, lo + 1e-12, hi - 1e-12)
    res = scipy.optimize.least_squares(residuals, x0, bounds=(lo, hi), args=(y, dt, m), x_scale="jac",
                                       diff_step=1e-7, max_nfev=400)
    return res.x[:m], res.x[m:2 * m], res.x[2 * m:]


def blind_fit(y, dt, w0):
    """A fit from ω₀ alone: ζ = 1 %, B(z) = A(z/ρ) for ρ = 0.5, 0.8, 0.95, each with ω held while ζ and B settle;
    the least Σe² of the three is then fitted with ω free. Returns (ω, Σe²)."""
    m = w0.size
    z0 = np.full(m, 0.01)
    lo = np.concatenate((np.full(m, 1e-4), np.full(2 * m, -np.inf)))
    hi = np.concatenate((np.full(m, 0.3), np.full(2 * m, np.inf)))
    best = None
    for rho in (0.5, 0.8, 0.95):
        b = ar_poly(w0, z0, dt)[1:] * rho ** np.arange(1, 2 * m + 1)
        res = scipy.optimize.least_squares(lambda x: residuals(np.concatenate((w0, x)), y, dt, m),
                                           np.concatenate((z0, b)), bounds=(lo, hi), x_scale="jac",
                                           diff_step=1e-7, max_nfev=200)
        if best is None or res.cost < best.cost:
            best = res
    w, z, b = fit(y, dt, w0, best.x[:m], best.x[m:])
    return w, float(np.sum(residuals(np.concatenate((w, z, b)), y, dt, m) ** 2))


def innovation_sse(y: np.ndarray, w: np.ndarray, z: np.ndarray, K: np.ndarray, dt: float, skip: int) -> float:
    """Σe² (the first ``skip`` dropped) of the steady Kalman predictor of :func:`innovation_model` at frequencies
    ``w`` (:func:`predictor_innovations`). The innovations' scale drops out of the concentrated likelihood,
    N/2 ln Σe² (so the noise model's scale is free). inf where the Riccati equation has no stabilising solution."""
    try:
        e, _, B = predictor_innovations(y, *innovation_model(w, z, K, dt), skip)
    except (ValueError, np.linalg.LinAlgError):
        return np.inf
    return np.inf if np.max(np.abs(np.roots(B))) >= 1.0 else float(e @ e)


def pct(w, truth) -> str:
    return "/".join(f"{x:+.2f}" for x in 100 * (np.asarray(w) / truth - 1))


def before_the_step(args, name, opts) -> None:
    for label, cfg, cell in white_step_cells(args):
        st = float(cell["step_time_s"])
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        zeta = np.asarray(cell["truth_damping"], float)
        k0 = int(round(st / dt))
        print(label, flush=True)
        for r in range(cell["accel_m_s2"].shape[0]):
            y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
            tr = methods.track(name, y, dt, prior, **opts)
            w_trk = tr.frequencies[np.searchsorted(tr.t_s, st - dt / 2) - 1]
            w_genie, _, _ = fit(y[:k0], dt, truth[k0 - 1], zeta, true_b(cfg, cell, 0))
            w_blind, _ = blind_fit(y[:k0], dt, w_trk)
            print(f"  r{r} e % at the step: genie ML {pct(w_genie, truth[k0 - 1])} | blind ML from the tracker "
                  f"{pct(w_blind, truth[k0 - 1])} | tracker {pct(w_trk, truth[k0 - 1])}", flush=True)


def ar_modes(y, dt, p: int, ref) -> np.ndarray:
    """The modes of a least-squares AR(``p``) fit of ``y`` (``scipy.linalg.lstsq``): per reference frequency the
    nearest pole frequency (ζ < 0.2) within the geometric midpoints to its neighbours (NaN: none)."""
    Y = scipy.linalg.hankel(y[:y.size - p], y[y.size - p - 1:])
    a, *_ = scipy.linalg.lstsq(Y[:, :p][:, ::-1], Y[:, p])
    s = np.log(np.roots(np.concatenate(([1.0], -a))).astype(complex)) / dt
    w = np.abs(s)[(s.imag > 0) & (-s.real < 0.2 * np.abs(s))]
    out = np.full(ref.size, np.nan)
    for i, wr in enumerate(ref):
        lo = np.sqrt(ref[i - 1] * wr) if i else 0.7 * wr
        hi = np.sqrt(ref[i + 1] * wr) if i + 1 < ref.size else 1.3 * wr
        c = w[(w > lo) & (w < hi)]
        if c.size:
            out[i] = c[np.argmin(np.abs(c - wr))]
    return out


def grid_pair(y, dt, w, z, b, pair, span: float = 0.12, n: int = 49, skip: int = 25) -> np.ndarray:
    """ω with the two modes of ``pair`` at the least Σe² (B held at ``b``, the first ``skip`` errors dropped) of an
    n × n grid ±``span`` about ``w``."""
    i, j = pair
    best, arg = np.inf, w
    B = np.concatenate(([1.0], b))
    for a in w[i] * (1 + np.linspace(-span, span, n)):
        for c in w[j] * (1 + np.linspace(-span, span, n)):
            if c <= 1.01 * a:
                continue
            ww = w.copy()
            ww[i], ww[j] = a, c
            e = scipy.signal.lfilter(ar_poly(ww, z, dt), B, y)[skip:]
            if e @ e < best:
                best, arg = e @ e, ww
    return arg


def after_the_step(args, name, opts) -> None:
    """The fits of [step, step + T) for T = 5, 10, 15, 20 s beside the tracker at step + T and its re-convergence:
    the genie (truth after the step, its B), blind from the tracker's estimate, a least-squares AR(30), and a grid over
    the closest prior pair (the other modes at the tracker's, B the truth's before the step, a genie) refitted."""
    for label, cfg, cell in white_step_cells(args):
        st = float(cell["step_time_s"])
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        zeta = np.asarray(cell["truth_damping"], float)
        k0 = int(round(st / dt))
        b_true, b_pre = true_b(cfg, cell, k0 + 1), true_b(cfg, cell, k0 - 1)
        print(label, flush=True)
        for r in range(cell["accel_m_s2"].shape[0]):
            y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
            tr = methods.track(name, y, dt, prior, **opts)
            rc = reconvergence_s(tr.t_s, tr.frequencies, truth, dt, st)
            print(f"  r{r} tracker back in {rc:.1f} s", flush=True)
            for T in (5.0, 10.0, 15.0, 20.0):
                k1 = k0 + int(round(T / dt))
                if k1 > y.size:
                    break
                w_trk = tr.frequencies[np.searchsorted(tr.t_s, st + T - dt / 2) - 1]
                w_genie, _, _ = fit(y[k0:k1], dt, truth[k1 - 1], zeta, b_true)
                w_blind, _ = blind_fit(y[k0:k1], dt, w_trk)
                w_ar = ar_modes(y[k0:k1], dt, 30, w_trk)
                i = int(np.argmin(np.diff(prior)))
                w_grid = grid_pair(y[k0:k1], dt, w_trk, zeta, b_pre, (i, i + 1))
                w_grid, _, _ = fit(y[k0:k1], dt, w_grid, zeta, b_pre)
                line = (f"    T {T:4.1f} s e %: genie ML {pct(w_genie, truth[k1 - 1])} | blind ML from the tracker "
                        f"{pct(w_blind, truth[k1 - 1])} | AR(30) {pct(w_ar, truth[k1 - 1])} | pair grid "
                        f"{pct(w_grid, truth[k1 - 1])}")
                if args.kalman_grid:
                    pre = tr.frequencies[np.searchsorted(tr.t_s, st - dt / 2) - 1]
                    z1 = np.full(pre.size, 0.01)
                    if T == 5.0:
                        theta = fit_force_model(y[k0 - int(round(30 / dt)):k0], pre, z1, dt)
                    w_kg = kalman_grid(y[k0:k1], pre, (i, i + 1), lambda w, c=cfg, cl=cell: genie_model(c, cl, w))
                    w_kb = kalman_grid(y[k0:k1], pre, (i, i + 1),
                                       lambda w, th=theta, z=z1, d=dt: force_model(w, z, d, th))
                    line += (f" | Kalman grid, genie noise {pct(w_kg, truth[k1 - 1])} | Kalman grid, blind noise "
                             f"{pct(w_kb, truth[k1 - 1])}")
                print(line + f" | tracker {pct(w_trk, truth[k1 - 1])}", flush=True)


def recursion_looks(name, opts, y, dt, prior):
    """``rpem_ambient`` (``recursions="two"``) on ``y``, read where the tracker hands its whole-record recursion to the
    reset step: (the track, the window's samples, the hop, each look's sample, per look the last window's likelihood
    ratio Λ_W and the whole-record recursion's θ)."""
    from methods.tracking import _rpem
    looks: list = []
    orig = _rpem._reset_from_window

    def keep(long, theta, P, iw, ia, gain, *a, **kw):
        looks.append((gain, long[0].copy()))
        return orig(long, theta, P, iw, ia, gain, *a, **kw)

    _rpem._reset_from_window = keep
    try:
        tr = methods.track(name, y, dt, prior, **opts)
    finally:
        _rpem._reset_from_window = orig
    W_len, hop = _rpem._ambient._window_samples(_rpem.Options(), dt, prior)
    return tr, W_len, hop, W_len - 1 + hop * (1 + np.arange(len(looks))), looks


def recursion_lines(name, opts, y, dt, prior):
    """The whole-record recursion at each look (:func:`recursion_looks`): (the window's samples, each look's sample,
    per look ω, ζ, gain K and rate)."""
    _, W_len, _, at, looks = recursion_looks(name, opts, y, dt, prior)
    m = prior.size
    kscale = np.empty(2 * m)
    kscale[0::2], kscale[1::2] = 1 / prior ** 2, 1 / prior
    return W_len, at, [(th[:m], th[m:2 * m], th[2 * m:4 * m] * kscale, th[4 * m:5 * m]) for _, th in looks]


def refit(args, name, opts) -> None:
    """At the whole-record recursion's last look before the step, the ω (every mode, ζ and K held at the
    recursion's) of least concentrated likelihood N/2 ln Σe² of :func:`innovation_sse` over every sample so far
    (Nelder–Mead from the recursion's ω), beside the recursion's; the likelihood gained, in nats, and a tally of
    the closest prior pair's larger error where the gain passes ``restart_gate``²/2 and where it does not."""
    from methods.tracking import _rpem
    gate = 0.5 * _rpem.Options().restart_gate ** 2
    tally = {True: [], False: []}
    for label, _, cell in white_step_cells(args):
        st = float(cell["step_time_s"])
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        print(label, flush=True)
        for r in range(cell["accel_m_s2"].shape[0]):
            y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
            _, at, lines = recursion_lines(name, opts, y, dt, prior)
            j = np.flatnonzero(at < int(round(st / dt)))[-1]
            m, kl = prior.size, at[j]
            w0, z0, K0, _ = lines[j]
            seg = y[:kl + 1]
            skip = int(round(2 * 2 * np.pi / w0.min() / dt))

            def cost(x, seg=seg, w0=w0, z0=z0, K0=K0, skip=skip, dt=dt):
                return 0.5 * (seg.size - skip) * np.log(max(innovation_sse(seg, w0 * np.exp(x), z0, K0, dt, skip),
                                                            1e-300))

            c0 = time.process_time()
            res = scipy.optimize.minimize(cost, np.zeros(m), method="Nelder-Mead",
                                          options={"xatol": 1e-5, "fatol": 0.01, "maxfev": 400})
            cpu = time.process_time() - c0
            w1, gain = w0 * np.exp(res.x), cost(np.zeros(m)) - res.fun
            i = int(np.argmin(np.diff(prior)))
            e0, e1 = (float(np.max(np.abs(100 * (w[[i, i + 1]] / truth[kl, [i, i + 1]] - 1)))) for w in (w0, w1))
            tally[bool(gain > gate)].append((e0, e1))
            print(f"  r{r} at {kl * dt:.1f} s e %: recursion {pct(w0, truth[kl])} | refit {pct(w1, truth[kl])} | "
                  f"gain {gain:.1f} nats | {res.nfev} evaluations, {cpu:.2f} s CPU", flush=True)
    for passed, pairs in tally.items():
        if pairs:
            e = np.array(pairs)
            print(f"gain {'>' if passed else '≤'} {gate:g} nats: {len(pairs)} replicates, the pair's larger error "
                  f"recursion → refit: median {np.median(e[:, 0]):.2f} → {np.median(e[:, 1]):.2f} %, better on "
                  f"{int(np.sum(e[:, 1] < e[:, 0] - MARGIN))}, worse on {int(np.sum(e[:, 1] > e[:, 0] + MARGIN))}")


def line_innovations(y, dt, w_end, rate, z, K, n_seg: int, skip: int):
    """The innovations (the first ``skip`` dropped) of the predictor of :func:`innovation_sse`'s noise model when
    every frequency is a line ending at ``w_end`` with slope ``rate`` (rad/s²): ``n_seg`` segments, each at its
    middle's frequencies (its own Riccati gain), the state carried across them; a loop over the samples (slow:
    a diagnosis, about 1 s per fit of 50–100 s). None where a segment's frequencies cross or its Riccati equation
    has no stabilising solution."""
    m, n = w_end.size, y.size
    edges = np.linspace(0, n, n_seg + 1).astype(int)
    x, e = np.zeros(2 * m), np.empty(n)
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        w = w_end + rate * ((a + b) / 2 - (n - 1)) * dt
        if np.any(np.diff(w) <= 0) or np.any(w <= 0):
            return None
        F, C, *noise = innovation_model(w, z, K, dt)
        try:
            gain, _ = predictor(F, C, *noise)
        except (ValueError, np.linalg.LinAlgError):
            return None
        C, gain = C.ravel(), gain.ravel()
        for k in range(a, b):
            e[k] = y[k] - C @ x
            x = F @ x + gain * e[k]
    return e[skip:]


def line_refit(args, name, opts) -> None:
    """On the white-force drift records, at the looks nearest 60 s and 100 s, the whole-record recursion's line
    (every mode's ω and rate, ζ and K held) refitted over the samples since its first window by the likelihood of
    :func:`line_innovations` (``scipy.optimize.least_squares``), beside the recursion's, and the nats it gains."""
    from _cells import white_force_drift

    from methods.tracking import _rpem
    gate = 0.5 * _rpem.Options().restart_gate ** 2
    rows = []
    for label, _, cell in white_cells(args.set, args.seed, args.replicates, args.cache,
                                      lambda _, cfg: white_force_drift(cfg)):
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        print(label, flush=True)
        for r in range(cell["accel_m_s2"].shape[0]):
            y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
            W_len, at, lines = recursion_lines(name, opts, y, dt, prior)
            m = prior.size
            for T in (60.0, 100.0):
                j = np.flatnonzero(at * dt <= T)[-1]
                kl = at[j]
                w0, z0, K0, r0 = lines[j]
                seg = y[W_len:kl + 1]
                skip = int(round(2 * 2 * np.pi / w0.min() / dt))

                def resid(x, seg=seg, w0=w0, z0=z0, K0=K0, r0=r0, skip=skip, dt=dt, m=m):
                    e = line_innovations(seg, dt, w0 * np.exp(x[:m]), r0 + x[m:] * w0, z0, K0, 8, skip)
                    return np.full(seg.size - skip, 1e3 * np.std(seg)) if e is None else e

                e0 = resid(np.zeros(2 * m))
                res = scipy.optimize.least_squares(resid, np.zeros(2 * m), diff_step=1e-6, max_nfev=60,
                                                   x_scale=np.concatenate((np.full(m, 0.01), np.full(m, 1e-4))))
                gain = 0.5 * e0.size * np.log((e0 @ e0) / (res.fun @ res.fun))
                w1 = w0 * np.exp(res.x[:m])
                rows.append((gain, np.abs(w0 / truth[kl] - 1), np.abs(w1 / truth[kl] - 1)))
                print(f"  r{r} at {kl * dt:5.1f} s e %: recursion {pct(w0, truth[kl])} | line refit "
                      f"{pct(w1, truth[kl])} | gain {gain:.1f} nats", flush=True)
    g = np.array([x[0] for x in rows])
    for sel, what in ((g > gate, f"> {gate:g}"), (g <= gate, f"≤ {gate:g}")):
        if sel.any():
            a, b = (np.median(np.array([x[i] for x in rows])[sel], axis=0) for i in (1, 2))
            print(f"gain {what} nats: {int(sel.sum())} refits, median |e| % per mode recursion "
                  f"{'/'.join(f'{100 * v:.2f}' for v in a)} → refit {'/'.join(f'{100 * v:.2f}' for v in b)}")


def first_window(args, name, opts) -> None:
    tally = [0, 0, 0]
    for label, _, cell in white_cells(args.set, args.seed, args.replicates, args.cache):
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        for r in range(cell["accel_m_s2"].shape[0]):
            y, prior = cell["accel_m_s2"][r], cell["prior_rad_s"][r]
            n = int(round(5 * 2 * np.pi / prior[0] / dt))
            peak, *_ = _ambient.periodogram_look(y[:n], dt, prior, 0.1, 0.005, pair_edges=True)
            fits = [blind_fit(y[:n], dt, w0) for w0 in (prior, np.where(np.isfinite(peak), peak, prior))]
            w_ml = min(fits, key=lambda f: f[1])[0]
            tr = methods.track(name, y, dt, prior, **opts)
            w_trk = tr.frequencies[min(np.searchsorted(tr.t_s, n * dt), tr.t_s.size - 1)]
            i = int(np.argmin(np.diff(prior)))
            pair = [i, i + 1]
            a = np.max(np.abs(100 * (w_trk[pair] / truth[n - 1, pair] - 1)))
            b = np.max(np.abs(100 * (w_ml[pair] / truth[n - 1, pair] - 1)))
            tally[0 if b < a - MARGIN else 1 if b > a + MARGIN else 2] += 1
            print(f"{label[:40]:40s} r{r} {n * dt:4.1f} s e %: peaks {pct(peak, truth[n - 1])} | blind ML "
                  f"{pct(w_ml, truth[n - 1])} | tracker {pct(w_trk, truth[n - 1])}", flush=True)
    print(f"the first window's ML places the closest prior pair better on {tally[0]}, worse on {tally[1]}, "
          f"alike on {tally[2]}")


def main() -> None:
    ap = step_parser(__doc__, cells="step")
    ap.add_argument("--cache", default=None)
    ap.add_argument("--first-window", action="store_true")
    ap.add_argument("--after-step", action="store_true")
    ap.add_argument("--kalman-grid", action="store_true")
    ap.add_argument("--refit", action="store_true")
    ap.add_argument("--line-refit", action="store_true")
    args = ap.parse_args()
    name, opts = parse_row(TWO)
    run = (first_window if args.first_window else after_the_step if args.after_step else refit if args.refit
           else line_refit if args.line_refit else before_the_step)
    run(args, name, opts)


if __name__ == "__main__":
    main()
