"""PEM against an independent implementation of the same estimator.

With the output-error predictor the PEM loss is the Gaussian likelihood of four damped sinusoids plus an
offset. Here that model is written directly — a_i e^(−ζω t) cos(ω√(1−ζ²) t + φ_i) + b, no state space, no
CasADi — and fitted with scipy.optimize.least_squares from PEM's answer nudged away. Both must land on the
same optimum: a check of the predictor, its derivatives and the search, by code that shares none of them.
"""

import numpy as np
import pytest
from scipy.optimize import least_squares

import methods
from experiments.simulate.datasets import UG


def model(theta, t, m):
    a, phi, w, z = (theta[i * m:(i + 1) * m] for i in range(4))
    r = np.sqrt(1 - z**2)
    return (a * np.exp(-np.outer(t, z * w)) * np.cos(np.outer(t, w * r) + phi)).sum(axis=1) + theta[-1]


@pytest.mark.parametrize("noise_ug, n, seed", [(1000.0, 256, 3), (100.0, 128, 4)])
def test_pem_output_error_matches_an_independent_ml_fit(plant, noise_ug, n, seed):
    dt = 0.02
    t = np.arange(n) * dt
    y = plant.tip_acceleration(n, dt) + noise_ug * UG * np.random.default_rng(seed).standard_normal(n)
    est = methods.get("pem")(y, dt, [2.65, 16.73, 17.32, 52.91])
    assert est.converged
    w0 = est.frequencies * (1 + 2e-4 * np.array([1, -1, 1, -1]))       # start off PEM's optimum
    z0 = np.full(4, 0.005)
    # amplitudes/phases for the start: linear least squares at the nudged frequencies
    basis = np.column_stack([np.exp(-z * w * t) * f(w * t) for w, z in zip(w0, z0, strict=True)
                             for f in (np.cos, np.sin)] + [np.ones(n)])
    c = np.linalg.lstsq(basis, y, rcond=None)[0]
    amp = np.hypot(c[0:8:2], c[1:8:2])
    phase = np.arctan2(-c[1:8:2], c[0:8:2])
    theta0 = np.concatenate([amp, phase, w0, z0, [c[-1]]])
    fit = least_squares(lambda th: model(th, t, 4) - y, theta0, method="lm", xtol=1e-14, ftol=1e-14,
                        gtol=1e-14, max_nfev=20000)
    w_indep = fit.x[8:12]
    np.testing.assert_allclose(est.frequencies, w_indep, atol=0.02 * est.std.max(), rtol=0)
    # and both sit at the same loss: PEM's estimate is the ML estimate, to a small fraction of its std
    assert np.all(np.abs(est.frequencies - w_indep) < 0.02 * est.std)
