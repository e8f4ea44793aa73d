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
    gain = np.asarray(gain, float)[:m]
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
    return y + noise_ug * UG * rng.standard_normal(n)


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
