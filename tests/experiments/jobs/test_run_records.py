"""How a job runs a cell's records (experiments/jobs/identify.run_records): one batch call for a method
that has ``identify_batch``, one call per record otherwise, and the same estimates either way."""

import numpy as np
import pytest

import methods
from experiments.jobs import identify

DT = 0.02
PRIOR = np.array([3.8, 16.0, 26.0, 46.0])


def _cell(r=4, n=160):
    t = np.arange(n) * DT
    rng = np.random.default_rng(3)
    return np.array([np.cos(3.3 * t) + 4.0 * np.cos(20.0 * t + i) + 0.01 * rng.standard_normal(n) for i in range(r)])


def test_a_batch_method_gets_the_per_record_estimates_and_the_batch_time_shared(monkeypatch):
    y = _cell()
    out = identify.run_records("akf", y, DT, PRIOR, {}, progress=False)
    assert len({runtime for _, runtime in out}) == 1          # one batch: its time divided by the records
    monkeypatch.setattr(methods, "get_batch", lambda name: None)
    alone = identify.run_records("akf", y, DT, PRIOR, {}, progress=False)
    for (est, _), (ref, _) in zip(out, alone, strict=True):
        assert est.message == ref.message
        np.testing.assert_allclose(est.frequencies, ref.frequencies, rtol=1e-9)


def test_a_batch_that_raises_falls_back_to_one_call_per_record(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("a bug in the batch")

    monkeypatch.setattr(methods, "get_batch", lambda name: broken)
    out = identify.run_records("akf", _cell(), DT, PRIOR, {}, progress=False)
    assert all(est.converged for est, _ in out)
    with pytest.raises(ValueError, match="rd = -1"):         # bad options still raise, on record 0
        identify.run_records("akf", _cell(), DT, PRIOR, {"rd": -1.0}, progress=False)
