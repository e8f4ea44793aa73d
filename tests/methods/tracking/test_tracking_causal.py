"""Every tracker is causal: the estimate at t_s[k] uses the samples up to t_s[k] only.

Checked on every name of ``methods.track_names()`` (a tracker added later is covered): the record is changed
after sample K; every estimate stamped at or before K Δt must stay exactly what it was (the trackers are
deterministic functions of the samples they have seen), and some later estimate must change (the check is
not vacuous). The windowed trackers' trend stage (``trend=True``) is checked on three of them.
"""

import numpy as np
import pytest
from _tracking_signals import DT, driven_modes, schedule

import methods

PRIOR = [3.8, 16.0, 26.0, 46.0]
N = 1000
K = 600                                   # samples after K are replaced
# small windows so that every windowed method runs a few windows in a few seconds
WINDOWED = {"window_samples": 200, "hop_samples": 125}
SLOW = {"bopdmd": {"window_samples": 100, "hop_samples": 250}}     # ~1 s per window (pydmd's BOP-DMD)


TREND = ["fft+trend", "pem+trend", "era+trend"]       # the trend stage: every windowed tracker's option
# the defaults from Δt and the prior (window 413 samples here), the change detector's window restarts and
# gated_pencil's kick test
DEFAULTS = ["gated_pencil+defaults", "next_era+defaults", "gated_pencil+memory", "gated_pencil+kicks",
            "gated_pencil+freeze", "gated_pencil+nowindow", "gated_pencil+own", "gated_pencil+nospan",
            "gated_pencil+ring"]
# akf_ambient's rate state, its shared modulation and its single-force fit with a memory of looks (the
# forgetting sum); rpem_ambient's rate in θ (its per-hop CasADi runs hand the state over between looks) and its
# two memories (and their close pair's peaks assigned together, the zero-rate average)
AMBIENT = {"akf_ambient+rate": {"frequency_model": "trend"},
           "akf_ambient+single": {"force_model": "single", "fit_memory_looks": 30},
           # the shared modulation, its band shortened so that its looks at the tracks' history run before K
           "akf_ambient+slosh": {"frequency_model": "slosh", "slosh_periods": (0.5, 3.0)},
           "rpem_ambient+rate": {"frequency_model": "trend"},
           "rpem_ambient+two": {"frequency_model": "trend", "recursions": "two"},
           "rpem_ambient+score": {"frequency_model": "trend", "recursions": "two", "score_reset": True},
           "rpem_ambient+pairs": {"frequency_model": "trend", "recursions": "two", "score_reset": True,
                                  "pair_peaks": True},
           # the reported ω averaged with its zero-rate conditional, per sample from the whole-record posterior
           "rpem_ambient+ratemode": {"frequency_model": "trend", "recursions": "two", "score_reset": True,
                                     "pair_peaks": True, "rate_test": "mode"},
           "rpem_ambient+rateall": {"frequency_model": "trend", "recursions": "two", "score_reset": True,
                                    "pair_peaks": True, "rate_test": "all"},
           "rpem_ambient+ratechange": {"frequency_model": "trend", "recursions": "two", "score_reset": True,
                                       "pair_peaks": True, "rate_test": "after_change"}}


def _options(name):
    if name in AMBIENT:
        return name.partition("+")[0], AMBIENT[name]
    name, _, extra = name.partition("+")
    if extra == "kicks":                  # the kick test: its flags and clean runs carried from window to window
        return name, {"split_kicks": True}
    if extra == "freeze":                 # the trend stage's rate restored from before a change, held over it
        return name, {"trend_restart_rate": "freeze"}
    if extra == "nospan":                 # the defaults but a change of span is no new level of the trend
        return name, {"trend_span_relevel": False}
    if extra == "nowindow":               # the defaults but every window's length from the prior alone
        return name, {"window_from_estimates": False}
    if extra == "own":                    # each fast mode also on its own short window ending at the present
        return name, {"own_windows": True}
    if extra == "ring":                   # a fast mode from the window's newest ring (after its last pulse)
        return name, {"ring_start": True}
    if extra in ("defaults", "memory"):
        return name, ({"memory": True, "change_threshold": 2.0} if extra == "memory" else {})
    fields = {f for f in methods.track_options_class(name).__dataclass_fields__}
    opts = SLOW.get(name) or {k: v for k, v in WINDOWED.items() if k in fields}
    return name, opts | ({"trend": True} if extra == "trend" else {})


@pytest.fixture(scope="module")
def records():
    y = driven_modes(schedule(N, step_at=400, step=-0.05), noise_ug=300.0, seed=3)
    changed = y.copy()
    changed[K + 1:] = driven_modes(schedule(N - K - 1, drift=0.2), noise_ug=300.0, seed=4)
    return y, changed


@pytest.mark.parametrize("name", methods.track_names() + TREND + DEFAULTS + list(AMBIENT))
def test_changing_later_samples_leaves_earlier_estimates_unchanged(name, records):
    y, changed = records
    name, opts = _options(name)
    a = methods.track(name, y, DT, PRIOR, **opts)
    b = methods.track(name, changed, DT, PRIOR, **opts)
    assert a.frequencies.shape == (a.t_s.size, len(PRIOR)) and a.converged.dtype == bool
    assert np.all(np.diff(a.t_s) > 0) and a.runtime_s > 0
    np.testing.assert_array_equal(a.t_s, b.t_s)
    early = a.t_s <= K * DT + 1e-9
    assert early.any() and (~early).any(), name
    np.testing.assert_array_equal(a.frequencies[early], b.frequencies[early])
    np.testing.assert_array_equal(a.std[early], b.std[early])
    np.testing.assert_array_equal(a.converged[early], b.converged[early])
    later_a, later_b = a.frequencies[~early], b.frequencies[~early]
    assert not np.array_equal(later_a, later_b, equal_nan=True), f"{name}: later samples changed nothing"
    if opts.get("memory"):                       # the change detector did restart the window in this record
        assert a.extra["memory_restart_samples"].size > 0, a.message
