"""Records for the tracking tests: modal oscillators whose frequencies move, driven by white force.

Each mode n is q̈ = −ω_n(t)² q − 2ζω_n(t) q̇ + b_n u(t); the tip acceleration is Σ (q̈_n) + white noise. Per
sample the frozen oscillator's exact zero-order-hold transition (scipy.signal.cont2discrete) is applied: the
truth simulator of the tracking track is the experiments' business, this is only a small independent helper.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import cont2discrete

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
    """Tip acceleration of the modes with frequencies ``w`` (n × m, per sample), white force of 1σ ``force``."""
    n, m = w.shape
    rng = np.random.default_rng(seed)
    u = force * rng.standard_normal(n)
    gain = np.asarray(gain, float)[:m]
    x = np.zeros((m, 2))
    y = np.empty(n)
    cache: dict[bytes, tuple] = {}
    for k in range(n):
        key = w[k].tobytes()
        if key not in cache:
            mats = []
            for wn in w[k]:
                a = np.array([[0.0, 1.0], [-wn * wn, -2 * zeta * wn]])
                phi, gam, _, _, _ = cont2discrete((a, np.array([[0.0], [1.0]]), np.eye(2), np.zeros((2, 1))), dt)
                mats.append((phi, gam[:, 0]))
            cache[key] = (np.array([p for p, _ in mats]), np.array([g for _, g in mats]))
        phi, gam = cache[key]
        acc = -(w[k] ** 2) * x[:, 0] - 2 * zeta * w[k] * x[:, 1] + gain * u[k]
        y[k] = acc.sum()
        x = np.einsum("nij,nj->ni", phi, x) + gam * (gain * u[k])[:, None]
    return y + noise_ug * UG * rng.standard_normal(n)
