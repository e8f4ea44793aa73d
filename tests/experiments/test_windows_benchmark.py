"""The softening cantilever of experiments/benchmarks/windows.py: its backbones, and its one-line refusals."""

import numpy as np
import pytest

from experiments.benchmarks import windows


@pytest.mark.parametrize("backbone", ["cubic", "quadratic"])
def test_the_oscillator_at_unit_amplitude_has_the_stated_shift(backbone):
    """Undamped, started at amplitude 1 (ẋ(0) = ω): the period of its first oscillations is 2π/((1 + shift)ω)
    to first order in the shift (harmonic balance: 3εA²/4 and 8εA/(3π) are the first-order terms)."""
    w, shift = 20.0, -0.02
    t = np.arange(40_000) * 1e-4
    x = windows.softening_modes(t, [w], [0.0], [1.0], shift, backbone)
    up = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    period = np.mean(np.diff(t[up]))
    assert abs(np.max(np.abs(x)) - 1.0) < 0.05
    np.testing.assert_allclose(2 * np.pi / period, (1 + shift) * w, rtol=2e-3)


def test_bad_values_are_one_error_line(capsys):
    with pytest.raises(SystemExit) as exc:
        windows.main(["--records", "0"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --records = 0") and err.count("\n") == 1
