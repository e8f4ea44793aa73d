"""The automatic memory (methods/tracking/_memory.py): a CUSUM on the trend filter's normalised innovations
restarts ``gated_pencil``'s window after a jump, and not on a drift.

Against independent numbers: the CUSUM recursion on hand-made innovations (its alarm time and restart point
follow from the sums by hand); end to end on records built here (tests/methods/_tracking_signals.py): a
record that steps after dwells of 15 periods of the slowest mode, and one that drifts by 30 % with the same
ringing blows, no step.
"""

import numpy as np
import pytest
from _tracking_signals import modal_response, ringing_force, score_steps, stepped_schedule

import methods
from methods.tracking import _memory

DT = 0.025


def test_the_cusum_alarms_on_a_shift_and_restarts_after_the_last_clean_window():
    c = _memory.Cusum(2, threshold=5.0, drift=0.5)
    rng = np.random.default_rng(2)
    for j in range(300):                                   # no change: N(0, 1) innovations, h = 5, κ = 0.5
        assert not c.update(rng.standard_normal(2) * np.array([1.0, 0.3]), 10 * j).any() or j > 0
    c.reset(2990)
    for j in range(300, 320):
        assert not c.update(np.array([0.0, 0.2]), 10 * j).any()          # within κ: the sums stay at 0
    alarms = [c.update(np.array([2.5, 0.0]), 10 * j) for j in range(320, 326)]
    # g⁺ = 2, 4, 6 > 5: the third window after the shift, mode 0 only
    assert [a[0] for a in alarms[:3]] == [False, False, True] and not any(a[1] for a in alarms)
    assert c.restart_sample(np.array([True, False])) == 10 * 319 + 1


def test_the_cusum_false_alarm_rate_on_white_innovations_is_small():
    c = _memory.Cusum(1, threshold=5.0, drift=0.5)
    rng = np.random.default_rng(3)
    alarms = 0
    for j, x in enumerate(rng.standard_normal(5000)):
        if c.update(np.array([x]), j).any():
            alarms += 1
            c.reset(j)
    assert alarms <= 12                                    # two-sided ARL₀ ≈ 470 windows at h = 5, κ = 0.5


def _record(w, seed):
    rng = np.random.default_rng(seed)
    u = ringing_force(w.shape[0], [], rng, DT, 2 * np.pi / w[0].min(), pulses_per_period=0.3)
    y = modal_response(w, u, zeta=0.005, gain=np.ones(w.shape[1]), dt=DT)
    return y + 0.01 * np.percentile(np.abs(y), 99) * rng.standard_normal(y.size)


@pytest.fixture(scope="module")
def short_dwells():
    """Two modes (8 and 19 rad/s, 31 samples per period of the slower) stepping ±5–20 % after dwells of 15–16
    periods, every step ringing them, blows between; 1 % noise."""
    rng = np.random.default_rng(21)
    freq = np.array([8.0, 19.0])
    n = int(round(110 * 2 * np.pi / freq[0] / DT))
    w, steps = stepped_schedule(n, DT, freq, rng, dwell_periods=(15.0, 16.0), first_dwell_periods=20.0)
    rng2 = np.random.default_rng(22)
    u = ringing_force(n, steps, rng2, DT, 2 * np.pi / freq[0], pulses_per_period=0.3)
    y = modal_response(w, u, zeta=0.005, gain=np.ones(2), dt=DT)
    return y + 0.01 * np.percentile(np.abs(y), 99) * rng2.standard_normal(n), w, steps, freq * np.array([1.03, 0.98])


def test_dwells_of_15_periods_are_tracked_and_reconverged_within_10_periods(short_dwells):
    y, w, steps, prior = short_dwells
    sc = score_steps(*(lambda t: (t.t_s, t.frequencies))(methods.track("gated_pencil", y, DT, prior)), w, DT, steps)
    assert steps.size >= 5 and sc["reconv_worst"] <= 10.0 and sc["error"] < 0.003 and sc["within"] > 0.95, sc


def test_the_change_detector_restarts_the_window_after_every_step_at_its_ring(short_dwells):
    y, w, steps, prior = short_dwells
    # the detector on its own: with the kick test (on by default) the window's fit splits at a step's ring and
    # follows the step by itself, and after one step of the six here the innovations stay under the detector's
    # threshold (the re-convergence holds: the test below)
    tr = methods.track("gated_pencil", y, DT, prior, memory=True, split_kicks=False)
    restarts = tr.extra["memory_restart_samples"]
    period_n = 2 * np.pi / w.min(axis=1) / DT
    for k in steps:        # within 5 periods of the step, and not before it: after the ring the detector flagged
        near = restarts[(restarts >= k) & (restarts <= k + 5 * period_n[k])]
        assert near.size >= 1, (k, restarts)
    assert np.unique(restarts).size <= steps.size + 3, restarts        # a few spurious restarts at most
    sc = score_steps(tr.t_s, tr.frequencies, w, DT, steps)
    assert sc["reconv_worst"] <= 10.0 and sc["error"] < 0.003, sc


def test_with_the_kick_test_the_detector_still_reconverges_within_10_periods(short_dwells):
    y, w, steps, prior = short_dwells
    tr = methods.track("gated_pencil", y, DT, prior, memory=True)
    assert np.unique(tr.extra["memory_restart_samples"]).size <= steps.size + 3
    sc = score_steps(tr.t_s, tr.frequencies, w, DT, steps)
    assert sc["reconv_worst"] <= 10.0 and sc["error"] < 0.003, sc


def test_a_drift_is_followed_without_a_restart():
    n = int(round(120 * 2 * np.pi / 8.0 / DT))
    ramp = np.linspace(0.0, 0.3, n)[:, None]
    w = np.array([8.0, 19.0])[None, :] * (1 + ramp * np.array([1.0, 0.5]))      # +30 % and +15 %
    y = _record(w, seed=31)
    tr = methods.track("gated_pencil", y, DT, [8.1, 18.8], memory=True)
    assert tr.extra["memory_restart_samples"].size == 0, tr.message
    late = tr.t_s > 20 * 2 * np.pi / 8.0
    err = np.abs(tr.frequencies[late] / w[np.round(tr.t_s[late] / DT).astype(int)] - 1)
    assert np.median(err) < 0.002 and np.all(err < 0.01)
