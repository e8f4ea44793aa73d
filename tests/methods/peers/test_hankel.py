"""The peers' Hankel row count (methods/peers/_hankel.py): from the model order, the prior and Δt, not N.

Checked: the time the rows span is the prior's longest time scale (slowest period, or the beat period of
the closest pair) times ``rows_periods``, whatever the sample interval; the order's floor; the old fraction
of N as the cap (so a short record keeps its count); the adapters use it; bad options are refused.
"""

import math

import numpy as np
import pytest
from _signals import DT

import methods
from methods.peers import _hankel

PRIOR = np.array([3.80, 16.00, 26.00, 46.00])       # Table 3 (configs/method/<peer>.yaml)


@pytest.mark.parametrize("dt", [0.02, 0.005, 0.04])
def test_rows_span_two_of_the_prior_s_longest_periods_at_any_sample_rate(dt):
    # slowest entry 3.8 rad/s: period 1.653 s, longer than the closest pair's beat (2π/10 = 0.628 s)
    rows = _hankel.hankel_rows(10**6, 12, PRIOR, dt, per_order=3.0, periods=2.0)
    assert rows == max(36, math.ceil(2 * 2 * math.pi / 3.8 / dt))
    assert rows * dt == pytest.approx(2 * 2 * math.pi / 3.8, abs=dt)


def test_a_close_pair_in_the_prior_asks_for_its_beat_period():
    prior = np.array([2.65, 16.73, 17.32, 52.91])     # Table 4: 0.59 rad/s between modes 2 and 3
    assert _hankel.prior_span_s(prior, DT) == pytest.approx(2 * math.pi / 0.59)
    assert _hankel.hankel_rows(10**6, 12, prior, DT, 3.0, 2.0) == math.ceil(2 * 2 * math.pi / 0.59 / DT)


def test_the_order_floor_the_cap_and_the_fraction_alone():
    assert _hankel.hankel_rows(10**6, 60, PRIOR, DT, 3.0, 2.0) == 180            # 3 × order beats 166
    assert _hankel.hankel_rows(100, 12, PRIOR, DT, 3.0, 2.0) == 100              # the old count caps it
    assert _hankel.hankel_rows(1000, 12, PRIOR, DT, 3.0, None) == 1000           # null periods: the cap


@pytest.mark.parametrize(("name", "key"), [("era", "hankel_rows"), ("hdmd", "delays"), ("bopdmd", "delays"),
                                           ("n4sid", "block_rows"), ("ssi_cov", "block_rows"),
                                           ("ssi_data", "block_rows")])
def test_adapters_stop_growing_the_rows_on_a_long_record(name, key):
    # 1024 samples: the fraction asks for N/2 (ERA, DMD) or N/4 (N4SID, SSI); two periods of 3.8 rad/s are 166.
    # ERA and Hankel DMD keep the square matrix by default (the cap cost them accuracy on long records)
    t = DT * np.arange(1024)
    y = sum(np.exp(-0.02 * w * t) * np.cos(w * t) for w in (3.2, 20.2, 22.0, 56.7))
    y = y + 1e-3 * np.random.default_rng(0).standard_normal(t.size)
    square = name in ("era", "hdmd")
    # 300 samples: the fraction's count is below 166, kept (ERA: half of N − 1 = 299, rounded to even)
    assert methods.get(name)(y[:300], DT, PRIOR).extra[key] == (150 if name in ("era", "hdmd", "bopdmd") else 75)
    est = methods.get(name)(y, DT, PRIOR, **({"rows_periods": 2.0} if square else {}))
    assert est.extra[key] == 166
    old = methods.get(name)(y, DT, PRIOR, rows_periods=None)
    assert old.extra[key] > 166
    # within 0.5 % (SSI-cov, which assumes a stationary response, is biased by the decay: 0.12 % here)
    np.testing.assert_allclose(est.frequencies, [3.2, 20.2, 22.0, 56.7], rtol=5e-3)


@pytest.mark.parametrize("name", ["era", "hdmd", "n4sid", "ssi_cov"])
def test_bad_row_options_are_refused_before_any_record(name):
    with pytest.raises(ValueError, match="rows_periods = 0"):
        methods.check_options(name, [5.0], DT, {"rows_periods": 0.0})
    with pytest.raises(ValueError, match="rows_per_order = 0.5"):
        methods.check_options(name, [5.0], DT, {"rows_per_order": 0.5})
