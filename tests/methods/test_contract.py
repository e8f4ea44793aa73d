"""The contract every registered method keeps (methods/__init__.py), checked on every name in
``methods.names()`` — a method added later is covered without editing this file.

* No information, no convergence: a record that carries nothing about a mode (all zero, a constant bias,
  pure white noise) must not be reported converged for that mode, and its 1σ is NaN or finite and positive,
  never 0 (a zero std on a guess is a claim of certainty).
* Bad arguments are ``ValueError`` naming the argument, raised before any work, for every method.
* Options are checked without a record (``check_options``), so the jobs can reject them up front.
"""

import numpy as np
import pytest

import methods

DT = 0.02
PRIOR = [3.8, 16.0, 26.0, 46.0]          # Table 3's a-priori frequencies
N = 1024                                  # 20 s: longer than every default PLL's acquisition time (15 s)
SIGNALS = {
    "zero": lambda: np.zeros(N),
    "constant": lambda: np.full(N, 0.3),                                         # a pure sensor bias
    "noise": lambda: 0.01 * np.random.default_rng(11).standard_normal(N),       # ≈ 1000 µg white noise
}


def _cases():
    for name in methods.names():
        for signal in SIGNALS:
            yield pytest.param(name, signal, id=f"{name}-{signal}")


@pytest.mark.parametrize("name, signal", list(_cases()))
def test_a_record_without_information_is_never_called_converged(name, signal):
    est = methods.get(name)(SIGNALS[signal](), DT, PRIOR)
    per_mode = est.converged_per_mode
    assert per_mode.shape == (len(PRIOR),)
    assert not per_mode.any(), f"{name} on {signal}: {est.message}"
    assert not np.any(est.std == 0.0), f"{name} on {signal}: std {est.std}"
    assert np.all(np.isnan(est.std) | (np.isfinite(est.std) & (est.std > 0)))


@pytest.mark.parametrize("name", methods.names())
def test_every_method_shows_the_three_names_of_the_contract(name):
    module = methods._module(name)
    assert callable(module.identify) and callable(module.check_options)
    assert isinstance(methods.check_options(name, PRIOR, DT, {}), module.Options)


@pytest.mark.parametrize("name", methods.names())
def test_check_options_names_an_unknown_option_without_a_record(name):
    with pytest.raises(ValueError, match="unknown option 'colour'"):
        methods.check_options(name, PRIOR, DT, {"colour": "red"})


GOOD_Y = np.cos(3.3 * np.arange(256) * DT)

BAD_ARGUMENTS = {
    # (y, dt, prior), the argument the message must name
    "dt-None": ((GOOD_Y, None, PRIOR), "dt"),
    "dt-text": ((GOOD_Y, "0.02", PRIOR), "dt"),
    "dt-bool": ((GOOD_Y, True, PRIOR), "dt"),
    "prior-dict": ((GOOD_Y, DT, {"mode1": 3.8}), "prior"),
    "prior-text": ((GOOD_Y, DT, ["3.8", "16"]), "prior"),
    "prior-repeated": ((GOOD_Y, DT, [19.0, 19.0, 23.0, 55.0]), r"prior\[1\] = 19"),
    "prior-decreasing": ((GOOD_Y, DT, [3.8, 26.0, 16.0, 46.0]), r"prior\[2\] = 16"),
    "y-text": ((["0.1"] * 64, DT, PRIOR), "y must be"),
    "y-complex": ((GOOD_Y + 1j, DT, PRIOR), "y must be"),
    "y-bool": ((GOOD_Y > 0, DT, PRIOR), "y must be"),
    "y-huge": ((np.concatenate([GOOD_Y[:5], [1e300], GOOD_Y[6:]]), DT, PRIOR), r"y\[5\] = 1e\+300"),
    "y-minus-huge": ((np.concatenate([GOOD_Y[:7], [-1e300], GOOD_Y[8:]]), DT, PRIOR), r"y\[7\] = -1e\+300"),
}


@pytest.mark.parametrize("case", list(BAD_ARGUMENTS))
@pytest.mark.parametrize("name", methods.names())
def test_bad_arguments_raise_value_error_naming_them(name, case):
    (y, dt, prior), fragment = BAD_ARGUMENTS[case]
    with pytest.raises(ValueError, match=fragment):
        methods.get(name)(y, dt, prior)


def test_the_physical_limit_leaves_real_records_alone():
    """|y| up to 1e6 m/s² (1e5 g) passes; the limit is on units errors, not on strong signals."""
    y, dt, prior = methods.check_inputs(1e6 * GOOD_Y, DT, PRIOR)
    assert y.dtype == float and dt == DT and prior.tolist() == PRIOR
    y, _, _ = methods.check_inputs(list(range(64)), 1, [0.5])      # integers are real numbers
    assert y.dtype == float


@pytest.mark.parametrize("name", [n for n in methods.names() if methods.get_batch(n) is not None])
def test_a_batch_face_gives_each_record_what_identify_gives_it(name):
    rng = np.random.default_rng(12)
    t = np.arange(300) * DT
    y = np.array([np.cos(3.3 * t) + 4.0 * np.cos(20.0 * t + p) + 0.01 * rng.standard_normal(t.size)
                  for p in (0.0, 1.0, 2.0)] + [np.zeros(t.size)])
    got = methods.get_batch(name)(y, DT, PRIOR)
    for rec, est in zip(y, got, strict=True):
        ref = methods.get(name)(rec, DT, PRIOR)
        assert est.message == ref.message and est.converged == ref.converged
        np.testing.assert_allclose(est.frequencies, ref.frequencies, rtol=1e-9, equal_nan=True)
