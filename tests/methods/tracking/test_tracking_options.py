"""Bad tracking options are refused with one line naming the option, before any work; the registry's face."""

import dataclasses

import numpy as np
import pytest

import methods

PRIOR = [3.8, 16.0, 26.0, 46.0]
DT = 0.02
Y = np.cos(3.3 * DT * np.arange(1000)) + 0.5 * np.cos(20.3 * DT * np.arange(1000))

BAD = [
    ("pem", {"window_samples": 2000}, "window_samples = 2000 is longer than the record"),
    ("fft", {"hop_samples": 0}, "hop_samples = 0"),
    ("era", {"hop_samples": -5}, "hop_samples = -5"),
    ("n4sid", {"window_samples": 4}, "window_samples = 4"),
    ("pem", {"window_samples": 100.5}, "window_samples = 100.5"),
    ("pem", {"predictor": "psychic"}, "predictor"),
    ("next_era", {"window_samples": 2000}, "window_samples = 2000 is longer than the record"),
    ("next_era", {"hop_samples": 0}, "hop_samples = 0"),
    ("akf", {"qd_frequency": -1.0}, "qd_frequency = -1.0"),
    ("akf", {"warmup_s": 100.0}, "warmup_s = 100.0 s is longer than the record"),
    ("wkf", {"max_restarts": -1}, "max_restarts = -1"),
    ("pll", {"remove_mean": True}, "remove_mean"),
    ("pll", {"loop_bandwidth_rad_s": [1.0, 2.0]}, "loop_bandwidth_rad_s"),
    ("rls_ar", {"forgetting": 1.5}, "forgetting = 1.5"),
    ("rls_ar", {"extra_order": -1}, "extra_order = -1"),
    ("rls_ar", {"colour": "red"}, "unknown option 'colour'"),
    ("ssi_cov", {"colour": "red"}, "unknown option 'colour'"),
]


@pytest.mark.parametrize("name, options, words", BAD, ids=[f"{n}-{next(iter(o))}" for n, o, _ in BAD])
def test_bad_options_are_one_line_naming_the_option(name, options, words):
    with pytest.raises(ValueError) as err:
        methods.track(name, Y, DT, PRIOR, **options)
    assert words in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(ValueError, match=words.split(" ")[0]):     # the same check without a record
        methods.check_track_options(name, PRIOR, DT, options, n_samples=Y.size)


def test_a_record_shorter_than_one_window_is_refused_without_a_record():
    with pytest.raises(ValueError, match="longer than the record"):
        methods.check_track_options("pem", PRIOR, DT, {"window_samples": 512}, n_samples=300)
    assert methods.check_track_options("pem", PRIOR, DT, {"window_samples": 512}).window_samples == 512


def test_unknown_tracker_is_named():
    with pytest.raises(ValueError, match="unknown tracker 'crystal_ball'"):
        methods.track("crystal_ball", Y, DT, PRIOR)


@pytest.mark.parametrize("name", methods.track_names())
def test_every_tracker_has_an_options_dataclass_with_defaults(name):
    cls = methods.track_options_class(name)
    opts = methods.check_track_options(name, PRIOR, DT, {})
    assert isinstance(opts, cls) and dataclasses.is_dataclass(cls)


def test_every_batch_method_is_a_tracker_and_windowed_ones_take_window_and_hop():
    names = methods.track_names()
    assert set(methods.names()) <= set(names) and {"rls_ar", "next_era"} <= set(names)
    for name in set(methods.names()) - {"akf", "wkf", "pll"}:
        fields = {f.name for f in dataclasses.fields(methods.track_options_class(name))}
        assert {"window_samples", "hop_samples", "warm_start"} <= fields


@pytest.mark.parametrize("name", methods.track_names())
def test_an_all_zero_record_is_never_tracked_as_converged(name):
    fields = methods.track_options_class(name).__dataclass_fields__
    opts = {"window_samples": 256, "hop_samples": 200} if "window_samples" in fields else {}
    tr = methods.track(name, np.zeros(700), DT, PRIOR, **opts)
    assert not tr.converged.any(), f"{name}: {tr.message}"
    assert not np.any(tr.std == 0.0)


@pytest.mark.parametrize("name", ["akf", "wkf", "pll", "rls_ar", "akf_ambient", "rpem_ambient"])
def test_white_noise_is_never_tracked_as_converged_by_the_recursive_trackers(name):
    y = 0.01 * np.random.default_rng(11).standard_normal(1500)          # ≈ 1000 µg, no mode
    assert not methods.track(name, y, DT, PRIOR).converged.any()
