"""The lock-step filters (methods/_modal_filter_batch.py) against the reference: filterpy's
ExtendedKalmanFilter run one record at a time (methods/_modal_filter.run_filter).

Each record of a batch must get what ``identify`` gives it alone: the same frequencies (to round-off: the
batch expands the Joseph form for a rank-one H instead of multiplying (I − KH) out), standard deviations,
per-sample history, convergence flags and messages, including a record that diverges mid-way (which
leaves the stack while the others go on) and a flat record."""

from __future__ import annotations

import numpy as np
import pytest
from _signals import DT, damped_modes

from methods import akf, wkf

FREQ, AMP = [3.23, 20.24, 22.0, 56.67], [1.0, -3.9, -5.1, 6.4]
PRIOR = np.array([3.8, 16.0, 26.0, 46.0])


def _records(n: int) -> np.ndarray:
    """Noise levels from 0.1 µg to 0.1 g, a sensor bias, a record from other modes, pure noise, a flat
    record: records that converge, that leave some modes undetermined, that diverge."""
    recs = [damped_modes(FREQ, AMP, n, noise_ug=u, seed=s) for s, u in enumerate([0.1, 10.0, 1e3, 1e5])]
    recs.append(damped_modes(FREQ, AMP, n, noise_ug=100.0, seed=7, bias=0.05))
    recs.append(damped_modes([2.9, 18.0, 24.0, 60.0], AMP, n, zeta=0.02, noise_ug=100.0, seed=8))
    recs.append(0.5 * np.random.default_rng(9).standard_normal(n))
    recs.append(np.full(n, 0.3))
    return np.array(recs)


def _same(got, ref):
    assert got.message == ref.message
    assert got.converged == ref.converged and got.iterations == ref.iterations
    assert got.extra["converged_per_mode"] == ref.extra["converged_per_mode"]
    np.testing.assert_allclose(got.frequencies, ref.frequencies, rtol=1e-9, equal_nan=True)
    np.testing.assert_allclose(got.std, ref.std, rtol=1e-6, equal_nan=True)
    if ref.history is not None:      # a diverging filter amplifies round-off on its way out: 1e-6 there
        rtol = 1e-6 if "diverged" in ref.message else 1e-9
        np.testing.assert_allclose(got.history, ref.history, rtol=rtol, atol=1e-12)


OPTIONS = [
    {},
    {"measurement": "acceleration"},
    {"estimate_bias": False},
    {"measurement": "acceleration", "estimate_bias": False, "damping_ratio": 0.02},
    {"measurement": "acceleration", "qd_modal": 0.0, "p0_modal_scale": 0.1},   # diverges on strong records
]


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()) or "default")
@pytest.mark.parametrize("module", [akf, wkf], ids=["akf", "wkf"])
def test_every_record_of_a_batch_gets_what_it_gets_alone(module, options):
    y = _records(200)
    got = module.identify_batch(y, DT, PRIOR, **options)
    assert len(got) == len(y)
    outcomes = set()
    for rec, est in zip(y, got, strict=True):
        ref = module.identify(rec, DT, PRIOR, **options)
        _same(est, ref)
        outcomes.add("diverged" if "diverged" in ref.message else "ok" if ref.converged else "failed")
    assert "failed" in outcomes           # the flat record
    if options.get("qd_modal") == 0.0:
        assert "diverged" in outcomes     # the case a record leaves the stack mid-way


def test_one_prior_per_record_and_the_default_p0_derived_from_each():
    y = _records(120)[:5]
    priors = PRIOR * np.linspace(0.85, 1.15, 5)[:, None]
    got = akf.identify_batch(y, DT, priors)
    for rec, prior, est in zip(y, priors, got, strict=True):
        _same(est, akf.identify(rec, DT, prior))


def test_a_bad_record_or_option_is_one_value_error_naming_it():
    y = _records(64)
    y[3, 10] = np.nan
    with pytest.raises(ValueError, match=r"record 3: y\[10\] = nan is not a finite number"):
        akf.identify_batch(y, DT, PRIOR)
    with pytest.raises(ValueError, match="rd = -1"):
        wkf.identify_batch(_records(64), DT, PRIOR, rd=-1.0)
    with pytest.raises(ValueError, match="2-D array"):
        akf.identify_batch(_records(64)[0], DT, PRIOR)
