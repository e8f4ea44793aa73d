"""The lock-step filters (methods/kalman/_lockstep.py) against the reference: filterpy's
ExtendedKalmanFilter run one record at a time (methods/kalman/_filter.run_filter).

Each record of a batch must get what ``identify`` gives it alone: the same frequencies (to round-off: the
batch expands the Joseph form for a rank-one H instead of multiplying (I − KH) out; the tolerance is derived
from the record's own sensitivity to round-off, see ``_roundoff_sensitivity``), standard deviations,
per-sample history, convergence flags and messages, including a record that diverges mid-way (which
leaves the stack while the others go on) and a flat record."""

from __future__ import annotations

import numpy as np
import pytest
from _signals import DT, damped_modes

from methods.kalman import akf, wkf

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


def _roundoff_sensitivity(module, rec, prior, options) -> tuple[float, float]:
    """How far this filter moves on this record when its input is perturbed at the level of round-off:
    the largest relative change of the history and of the std over three records y·(1 + ε·N(0, 1)).

    The lock-step and the per-record runs differ only in the order of their floating-point operations,
    so they may differ by what the filter makes of round-off, and by no more. That amplification depends
    on the record (a filter near divergence amplifies it most) and on the machine's BLAS kernels, which is
    why a fixed tolerance that held on one machine failed on another."""
    ref = module.identify(rec, DT, prior, **options)
    eps = np.finfo(float).eps
    moved_h, moved_s = 0.0, 0.0
    for seed in range(3):
        noise = np.random.default_rng(seed).standard_normal(rec.size)
        pert = module.identify(rec * (1 + eps * noise), DT, prior, **options)
        if ref.history is not None and pert.history is not None and pert.history.shape == ref.history.shape:
            moved_h = max(moved_h, float(np.nanmax(np.abs(pert.history - ref.history)
                                                   / (np.abs(ref.history) + 1e-12), initial=0.0)))
        both = np.isfinite(ref.std) & np.isfinite(pert.std)
        if both.any():
            moved_s = max(moved_s, float(np.max(np.abs(pert.std - ref.std)[both] / np.abs(ref.std)[both])))
    return moved_h, moved_s


# A real error of the lock-step path (a wrong gain, a missed step) moves the answers by 1e-3 or more; the
# differences allowed here are at most 1000 times the record's own round-off sensitivity, with floors of
# 1e-10 (history, frequencies) and 1e-6 (std) for a record that happens not to move at all.
AMPLIFICATION = 1e3


def _same(got, ref, sensitivity=(0.0, 0.0)):
    moved_h, moved_s = sensitivity
    rtol_h = max(1e-10, AMPLIFICATION * moved_h)
    rtol_s = max(1e-6, AMPLIFICATION * moved_s)
    assert got.message == ref.message
    assert got.converged == ref.converged and got.iterations == ref.iterations
    np.testing.assert_array_equal(got.converged_per_mode, ref.converged_per_mode)
    np.testing.assert_allclose(got.frequencies, ref.frequencies, rtol=rtol_h, equal_nan=True)
    np.testing.assert_allclose(got.std, ref.std, rtol=rtol_s, equal_nan=True)
    if ref.history is not None:
        np.testing.assert_allclose(got.history, ref.history, rtol=rtol_h, atol=1e-12)


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
        _same(est, ref, _roundoff_sensitivity(module, rec, PRIOR, options))
        outcomes.add("diverged" if "diverged" in ref.message else "ok" if ref.converged else "failed")
    assert "failed" in outcomes           # the flat record
    if options.get("qd_modal") == 0.0:
        assert "diverged" in outcomes     # the case a record leaves the stack mid-way


def test_one_prior_per_record_and_the_default_p0_derived_from_each():
    y = _records(120)[:5]
    priors = PRIOR * np.linspace(0.85, 1.15, 5)[:, None]
    got = akf.identify_batch(y, DT, priors)
    for rec, prior, est in zip(y, priors, got, strict=True):
        _same(est, akf.identify(rec, DT, prior), _roundoff_sensitivity(akf, rec, prior, {}))


def test_a_bad_record_or_option_is_one_value_error_naming_it():
    y = _records(64)
    y[3, 10] = np.nan
    with pytest.raises(ValueError, match=r"record 3: y\[10\] = nan is not a finite number"):
        akf.identify_batch(y, DT, PRIOR)
    with pytest.raises(ValueError, match="rd = -1"):
        wkf.identify_batch(_records(64), DT, PRIOR, rd=-1.0)
    with pytest.raises(ValueError, match="2-D array"):
        akf.identify_batch(_records(64)[0], DT, PRIOR)
