"""The measurement figure's display decimation keeps what a line plot shows at its pixel columns."""

import numpy as np
import pytest

from experiments.report.measurement_figure import envelope


@pytest.mark.parametrize("n, columns", [(100_000, 1500), (10_007, 1000), (4_543, 1500)])
def test_envelope_keeps_every_columns_extremes_in_time_order(n, columns):
    rng = np.random.default_rng(n)
    t = 0.5 + np.arange(n) * 1e-3
    y = np.cumsum(rng.standard_normal(n)) + 5.0 * (rng.random(n) < 1e-3)      # a walk with rare spikes
    te, ye = envelope(t, y, columns)
    assert np.all(np.diff(te) > 0)                                            # samples of y, in order
    assert set(np.round(te, 9)) <= set(np.round(t, 9))
    assert ye == pytest.approx(np.interp(te, t, y))
    if n // columns < 4:
        assert te.size == n                                                  # sparse enough: as it is
        return
    assert te.size <= 2 * columns + n // columns
    # every stretch of a few pixel columns spans the same range of y as with every sample
    per = n // columns
    for i in range(0, n // per * per - 3 * per + 1, 3 * per):
        full = y[i:i + 3 * per]
        kept = ye[(te >= t[i]) & (te <= t[i + 3 * per - 1])]
        assert (kept.min(), kept.max()) == (full.min(), full.max())
    assert ye.max() == y.max() and ye.min() == y.min()                       # every peak is drawn
