"""Synthetic tip signals for the method tests: sums of damped cosines, bias and white noise."""

from __future__ import annotations

import numpy as np

DT = 0.02
UG = 9.80665e-6         # 1 µg in m/s²


def damped_modes(freq, amp, n, *, zeta=0.005, noise_ug=0.0, seed=1, phase=None, dt=DT, bias=0.0):
    """Sum of damped cosines (the shape of the tip signal) plus a constant bias and white noise of
    noise_ug (1σ)."""
    t = np.arange(n) * dt
    phase = np.zeros(len(freq)) if phase is None else phase
    y = sum(a * np.exp(-zeta * w * t) * np.cos(w * np.sqrt(1 - zeta**2) * t + p)
            for w, a, p in zip(freq, amp, phase, strict=True))
    return y + bias + noise_ug * UG * np.random.default_rng(seed).standard_normal(n)


# Plants the paper never saw: 1, 2, 3 and 5 modes (frequencies rad/s, amplitudes m/s², phases drawn once).
# With the default position measurement the lowest mode is the well-excited one: after two integrations
# its amplitude a/ω² = 0.08–0.16 m is of the order of √Rd = 0.1 m; the higher modes' are 0.002–0.03 m.
OTHER_PLANTS = {
    1: ([5.0], [2.0]),
    2: ([2.5, 12.0], [1.0, 3.0]),
    3: ([4.0, 15.0, 35.0], [1.5, 3.0, 5.0]),
    5: ([3.0, 9.0, 20.0, 33.0, 50.0], [1.0, 2.0, 3.0, 4.0, 5.0]),
}


def other_plant(m, n, *, dt=DT, **kwargs):
    freq, amp = OTHER_PLANTS[m]
    phase = np.random.default_rng(10 + m).uniform(-np.pi, np.pi, m)
    return np.array(freq), damped_modes(freq, amp, n, phase=phase, dt=dt, **kwargs)
