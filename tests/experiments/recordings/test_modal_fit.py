"""experiments.recordings.modal_fit: the modes' amplitudes, and on a clipped record those after the clip."""

from __future__ import annotations

import numpy as np

from experiments.recordings.modal_fit import fit_modes


def test_amplitudes_after_the_clip_are_the_unclipped_ones():
    dt, n = 0.02, 512
    t = dt * np.arange(n)
    clean = 0.3 + 3.0 * np.exp(-0.1 * t) * np.cos(20.0 * np.sqrt(1 - 0.005 ** 2) * t + 0.7)
    clipped = np.clip(clean, -1.5, 1.5)
    start = int(np.flatnonzero(np.abs(clipped) >= 1.5).max()) + 1
    fit = fit_modes(clipped, dt, [20.0], [0.005], start)
    np.testing.assert_allclose(fit.amplitude[0], 3.0, rtol=1e-9)
    np.testing.assert_allclose(fit.offset, 0.3, rtol=1e-9)
    np.testing.assert_allclose(fit.model, clean, atol=1e-9)         # the model covers the clipped part too
    whole = fit_modes(clipped, dt, [20.0], [0.005])
    assert abs(whole.amplitude[0] - 3.0) > 0.1                        # fitted through the clip: too small
