"""The CasADi form of pem's search iteration (experiments.benchmarks.pem_casadi) computes what pem's own
separable model does, so its timing compares like with like."""

from __future__ import annotations

import numpy as np
import pytest

from experiments.benchmarks import pem_casadi
from methods import pem


def test_the_function_matches_pems_separable_model():
    dt, n = 0.05, 128
    w, z = np.array([2.0, 7.5]), np.array([0.01, 0.03])
    t = np.arange(n) * dt
    rng = np.random.default_rng(7)
    y = (np.exp(-z[0] * w[0] * t) * np.cos(w[0] * np.sqrt(1 - z[0] ** 2) * t)
         + 0.4 * np.exp(-z[1] * w[1] * t) * np.sin(w[1] * np.sqrt(1 - z[1] ** 2) * t)
         + 0.1 + 0.01 * rng.standard_normal(n))
    x = np.r_[w * 1.01, z * 1.2]                     # off the optimum: a non-zero step
    model = pem.SeparableModel(y, dt, 2, True, 0.0)
    c, e, loss, solver = model.fit(x[:2], x[2:])
    jr = model.reduced_jacobian(x[:2], x[2:], c, solver, True)
    out = [np.array(v) for v in pem_casadi.iteration_function(n, 2)(x, y, t)]
    assert np.allclose(out[0].ravel(), c, rtol=1e-8, atol=1e-10 * np.abs(c).max())
    assert out[2].item() == pytest.approx(loss, rel=1e-8)
    assert np.allclose(out[5], jr, rtol=0, atol=1e-8 * np.abs(jr).max())
    assert np.allclose(out[3], jr.T @ jr, rtol=0, atol=1e-8 * np.abs(jr.T @ jr).max())
    assert np.allclose(out[4].ravel(), jr.T @ e, rtol=0, atol=1e-8 * np.abs(jr.T @ e).max())


def test_bad_arguments_are_refused(capsys):
    assert pem_casadi.main(["--repeats", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --repeats 0") and err.count("\n") == 1
