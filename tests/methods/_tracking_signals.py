"""Records for the tracking tests: modal oscillators whose frequencies move, driven by white force.

Each mode n is q̈ = −ω_n(t)² q − 2ζω_n(t) q̇ + b_n u(t); the tip acceleration is Σ q̈_n + white noise. The frozen
system's exact zero-order-hold transition (scipy.signal.cont2discrete) is applied while the frequencies stay
put: the truth simulator of the tracking track is the experiments' business, this is a small helper.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import cont2discrete, dlsim

DT = 0.02
UG = 9.80665e-6
FREQ = np.array([3.23, 20.24, 22.0, 56.67])      # Table 3, rad/s
GAIN = np.array([4.0, 1.0, 1.0, 1.0])            # force-to-mode gains (mode 1 raised: a white force excites it least)


def schedule(n: int, *, drift: float = 0.0, step_at: int | None = None, step: float = 0.0,
             freq=FREQ) -> np.ndarray:
    """(n, m) frequencies: a linear relative drift over the record, and a relative step at sample step_at."""
    k = np.arange(n)[:, None]
    w = np.asarray(freq, float)[None, :] * (1.0 + drift * k / max(n - 1, 1))
    if step_at is not None:
        w = w * np.where(k >= step_at, 1.0 + step, 1.0)
    return w


def driven_modes(w: np.ndarray, *, zeta: float = 0.005, force: float = 1.0, noise_ug: float = 100.0,
                 seed: int = 1, gain=GAIN, dt: float = DT) -> np.ndarray:
    """Tip acceleration of the modes with frequencies ``w`` (n × m, per sample), white force of 1σ ``force``:
    each run of equal rows of ``w`` is one frozen linear system (scipy.signal.dlsim), its final state the
    next run's initial state."""
    n, m = w.shape
    rng = np.random.default_rng(seed)
    u = force * rng.standard_normal(n)
    return modal_response(w, u, zeta=zeta, gain=np.asarray(gain, float)[:m], dt=dt) \
        + noise_ug * UG * rng.standard_normal(n)


def modal_response(w: np.ndarray, u: np.ndarray, *, zeta, gain, dt: float) -> np.ndarray:
    """Noise-free tip acceleration of the modes with frequencies ``w`` (n × m, per sample) under the force
    ``u`` (n,), zero-order held: each run of equal rows of ``w`` one frozen system (scipy.signal.dlsim)."""
    n, m = w.shape
    gain = np.broadcast_to(np.asarray(gain, float), (m,))
    change = np.flatnonzero(np.any(np.diff(w, axis=0) != 0, axis=1)) + 1
    bounds = np.concatenate(([0], change, [n]))
    x = np.zeros(2 * m)
    y = np.empty(n)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        A, B, C, D = _modes_ss(w[a], zeta, gain)
        phi, gam, _, _, _ = cont2discrete((A, B, C, D), dt)
        _, out, states = dlsim((phi, gam, C, D, dt), u[a:b], x0=x)
        y[a:b] = out[:, 0]
        x = phi @ states[-1] + gam[:, 0] * u[b - 1]
    return y


def _modes_ss(w, zeta, gain):
    """Continuous state space of the driven modes, output the summed accelerations (with feedthrough)."""
    m = w.size
    A = np.zeros((2 * m, 2 * m))
    A[np.arange(m), np.arange(m, 2 * m)] = 1.0
    A[np.arange(m, 2 * m), np.arange(m)] = -w * w
    A[np.arange(m, 2 * m), np.arange(m, 2 * m)] = -2 * zeta * w
    B = np.concatenate((np.zeros(m), gain))[:, None]
    C = np.concatenate((-w * w, -2 * zeta * w))[None, :]
    return A, B, C, np.array([[gain.sum()]])


# ---------------------------------------------------------------------------------------------------------
# Records unlike the grid's: any Δt, 1–6 modes, steps with short dwells, each step ringing the structure.

def stepped_schedule(n: int, dt: float, freq, rng, *, dwell_periods=(15.0, 60.0), step=(0.05, 0.2),
                     first_dwell_periods: float = 40.0, bounds=(0.6, 1.6)):
    """(n, m) piecewise-constant frequencies and the step samples: dwells drawn uniformly in
    ``dwell_periods`` periods of the slowest mode (the first one ``first_dwell_periods``), each step every mode
    × (1 ± U(step)) with its own sign, redrawn while the modes would cross, meet (< 3 %), leave
    ``bounds`` × their start or reach 0.9 × Nyquist."""
    freq = np.asarray(freq, float)
    period = 2 * np.pi / freq.min()
    w = np.empty((n, freq.size))
    steps = []
    cur, k = freq.copy(), 0
    dwell = first_dwell_periods
    while k < n:
        stop = min(n, k + max(2, int(round(dwell * period / dt))))
        w[k:stop] = cur
        k = stop
        if k >= n:
            break
        steps.append(k)
        for _ in range(200):
            new = cur * (1 + rng.choice([-1.0, 1.0], freq.size) * rng.uniform(*step, freq.size))
            if (np.all(np.diff(new) > 0.03 * new[:-1]) and np.all(new > bounds[0] * freq)
                    and np.all(new < bounds[1] * freq) and new.max() < 0.9 * np.pi / dt):
                cur = new
                break
        dwell = rng.uniform(*dwell_periods)
    return w, np.asarray(steps, dtype=int)


def ringing_force(n: int, steps, rng, dt: float, period_s: float, *, pulses_per_period: float = 0.2,
                  white: float = 0.02):
    """A force that rings the structure at the start and at every step (a one-sample blow of random sign and
    size 0.5–1.5, an impulse of 0.01–0.03 N·s), at random blows between (``pulses_per_period`` per period of
    the slowest mode), and a weak white force of per-sample std ``white``·0.02/√(Δt·T), T the slowest period:
    a record time-scaled by a (Δt and T × a) keeps the same mix of blows and white force."""
    u = white * 0.02 / np.sqrt(dt * period_s) * rng.standard_normal(n)
    blows = {0} | set(np.asarray(steps, int).tolist())
    n_extra = rng.poisson(pulses_per_period * n * dt / period_s)
    blows |= set(rng.integers(0, n, n_extra).tolist())
    for k in blows:
        u[k] += rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 1.5) / dt * 0.02
    return u


def anyrate_record(dt: float, m: int, seed: int, *, duration_periods: float = 400.0, noise_rel: float = 0.01,
                   zeta: float = 0.005, parts: bool = False):
    """A record at sample interval ``dt`` with ``m`` modes: frequencies log-uniform with ωΔt in [0.08, 1.2]
    rad per sample (5–80 samples per period) at least 8 % apart, stepping ±5–20 % after dwells of 15–60 periods
    of the slowest mode, every step ringing the modes, blows between, white noise of ``noise_rel`` × the
    99th percentile of |y| (the rings' level).
    Returns (y, truth (n, m), step samples, prior = the start frequencies × (1 ± 5 %), sorted); with ``parts``
    also (the force u (n,), the noise's std, ζ), what a bound of the record needs."""
    rng = np.random.default_rng([seed, m, int(round(1e6 * dt))])
    for _ in range(1000):
        wdt = np.sort(np.exp(rng.uniform(np.log(0.08), np.log(1.2), m)))
        if m == 1 or np.all(np.diff(wdt) > 0.08 * wdt[:-1]):
            break
    freq = wdt / dt
    period = 2 * np.pi / freq.min()
    n = int(round(duration_periods * period / dt))
    w, steps = stepped_schedule(n, dt, freq, rng)
    u = ringing_force(n, steps, rng, dt, period)
    y = modal_response(w, u, zeta=zeta, gain=np.ones(m), dt=dt)
    noise_std = noise_rel * np.percentile(np.abs(y), 99)
    y = y + noise_std * rng.standard_normal(n)
    prior = np.sort(freq * (1 + 0.05 * rng.uniform(-1, 1, m)))
    return (y, w, steps, prior, u, noise_std, zeta) if parts else (y, w, steps, prior)


def lab_record(seed: int, *, n_modes: int = 1, duration_s: float = 12.0, fs_hz: float = 5000.0,
               decimate_by: int = 20):
    """A laboratory-like record: one or two modes at 20–60 Hz stepping ±5–20 % after dwells of 0.4–2 s (the
    first 1 s), every step ringing the beam, read by a 5 kHz accelerometer (10 V/g, ±10 V, 12 bits, an offset
    of 0.02–0.1 g, 1 mg RMS of analogue noise), decimated by ``decimate_by`` with scipy.signal.decimate (FIR).
    Returns (y in m/s², dt, truth (n, m) at the decimated samples, step samples there, prior)."""
    import scipy.signal  # only this record is decimated

    rng = np.random.default_rng([seed, n_modes, 30])
    f_hz = np.array([rng.uniform(22, 32)]) if n_modes == 1 else np.array([rng.uniform(20, 28), rng.uniform(42, 55)])
    freq = 2 * np.pi * f_hz
    dt_fast = 1.0 / fs_hz
    n = int(round(duration_s * fs_hz))
    period = 2 * np.pi / freq.min()
    w, steps = stepped_schedule(n, dt_fast, freq, rng, dwell_periods=(0.4 / period, 2.0 / period),
                                first_dwell_periods=1.0 / period, bounds=(0.75, 1.5))
    u = ringing_force(n, steps, rng, dt_fast, period, pulses_per_period=0.0, white=0.002)
    y = modal_response(w, u, zeta=rng.uniform(0.003, 0.01), gain=np.ones(n_modes), dt=dt_fast)
    g = 9.80665
    # the rings' level (the 99th percentile of |y|: a blow's one-sample feed-through saturates) at 0.3 g
    volts = 10.0 * (y / g * (0.3 / np.percentile(np.abs(y), 99)) + rng.uniform(0.02, 0.1)
                    + 1e-3 * rng.standard_normal(n))
    lsb = 20.0 / 2 ** 12
    volts = np.clip(np.round(volts / lsb) * lsb, -10.0, 10.0 - lsb)
    acc = scipy.signal.decimate(volts / 10.0 * g, decimate_by, ftype="fir")
    keep = np.arange(0, n, decimate_by)
    prior = np.sort(freq * (1 + 0.1 * rng.uniform(-1, 1, n_modes)))
    return acc, dt_fast * decimate_by, w[keep], np.unique(steps // decimate_by), prior


def score_steps(t_s, est, truth, dt: float, steps, *, settle_periods: float = 10.0, tol: float = 0.01):
    """Scores of a track on a stepped record (truth (n, m) per sample, ``steps`` the step samples).

    error: median over times and modes of |ω̂ − ω|/ω (a missing estimate counts as 100 %) from
    ``settle_periods`` periods of the slowest mode after the record's first window-free start and after each
    step to the end of its dwell; within: the share of those times with every mode within ``tol``;
    reconverge: per dwell after a step, the time from the step until every mode stays within ``tol`` to the
    dwell's end, in periods of the slowest mode (inf: never) — the median and the worst over the steps, and
    the share of steps re-converged within ``settle_periods``."""
    k = np.clip(np.round(np.asarray(t_s) / dt).astype(int), 0, truth.shape[0] - 1)
    tr = truth[k]
    err = np.abs(est / tr - 1)
    err = np.where(np.isfinite(err), err, 1.0)
    bounds = np.concatenate(([0], np.asarray(steps, int), [truth.shape[0]]))
    scored = np.zeros(k.size, dtype=bool)
    recon = []
    for i in range(bounds.size - 1):
        a, b = bounds[i], bounds[i + 1]
        period_n = 2 * np.pi / truth[a].min() / dt
        inside = (k >= a) & (k < b)
        first = max(a + settle_periods * period_n, k[0] if i == 0 else a)
        scored |= inside & (k >= first)
        if i == 0:
            continue
        ok = np.all(err <= tol, axis=1) & inside
        idx = np.flatnonzero(inside)
        if idx.size == 0:
            continue
        bad = idx[~ok[idx]]
        if bad.size == 0:
            recon.append((k[idx[0]] - a) / period_n)
        elif bad[-1] == idx[-1]:
            recon.append(np.inf)
        else:
            recon.append((k[bad[-1] + 1] - a) / period_n)
    recon = np.asarray(recon)
    return {"error": float(np.median(err[scored])) if scored.any() else np.nan,
            "within": float(np.mean(np.all(err[scored] <= tol, axis=1))) if scored.any() else np.nan,
            "reconv_median": float(np.median(recon)) if recon.size else np.nan,
            "reconv_worst": float(np.max(recon)) if recon.size else np.nan,
            "reconv_share": float(np.mean(recon <= settle_periods)) if recon.size else np.nan}
