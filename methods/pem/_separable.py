"""Variable projection over a record's pulse-free segments (one segment: a plain free decay): the
least-squares (under white noise, maximum likelihood) fit of m damped sinusoids whose frequencies and damping
are shared by every segment and whose amplitudes, phases and offset are each segment's own.

Between two thruster pulses the response is a free decay; a pulse resets every mode's amplitude and phase but
not its pole. With the window cut at the flagged samples into segments S₁ … S_q (sample k of segment s at
t = (k − k_s)Δt from its own start), the model is

    y(k) = Σᵢ e^{−ζᵢωᵢt}(A_{s,i} cos ω_dᵢt + B_{s,i} sin ω_dᵢt) + b_s,    k ∈ S_s,

linear in c_s = (A_s, B_s, b_s) for fixed θ = (ω, ζ). With every c_s at its least-squares value the residual
is ε(θ) = [P⊥_s y_s]_s and the reduced Jacobian (Kaufman) is block-stacked, J_r = [P⊥_s ∂ε_s/∂θ]_s, since
the projections are block-diagonal. Each block is :class:`methods.pem.SeparableModel` (the basis, the
linear solve and the reduced Jacobian of pem's own search); the search over θ is
``scipy.optimize.least_squares`` (trust-region reflective within bounds on ω and ζ), warm-started by the
caller (``gated_pencil``: the pencil's poles or the last window's; the peers' mode picker: a library's poles,
to confirm them). The std of ω is σ̂²(J_rᵀJ_r)⁻¹ at the minimum, σ̂² = Σε²/(N − p), p the number of
all unknowns (2m + 2m·q + q): the Cramér–Rao bound of the window under white noise, evaluated at the
estimate.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.optimize

from methods.pem._fast import _Model as SeparableModel

__all__ = ["MIN_ZETA", "MAX_ZETA", "separable_fit"]

MIN_ZETA, MAX_ZETA = 1e-5, 0.3


class _Piecewise:
    """Residual and reduced Jacobian of the piecewise model over the segments of one window."""

    def __init__(self, y: np.ndarray, dt: float, m: int, runs: list[tuple[int, int]]):
        self.models = [SeparableModel(y[a:b], dt, m, True, 0.0) for a, b in runs]
        self.m = m
        self.n = sum(b - a for a, b in runs)
        self._x = None
        self._parts = None

    def _evaluate(self, x: np.ndarray):
        if self._x is not None and np.array_equal(x, self._x):
            return self._parts
        w, z = x[:self.m], x[self.m:]
        parts = []
        for model in self.models:
            fitted = model.fit(w, z)
            if fitted is None:
                parts = None
                break
            c, e, _, solver = fitted
            parts.append((e, model.reduced_jacobian(w, z, c, solver, True)))
        self._x, self._parts = x.copy(), parts
        return parts

    def residual(self, x):
        parts = self._evaluate(x)
        if parts is None:
            return np.full(self.n, 1e30)
        return np.concatenate([e for e, _ in parts])

    def jacobian(self, x):
        parts = self._evaluate(x)
        if parts is None:
            return np.zeros((self.n, 2 * self.m))
        return np.concatenate([j for _, j in parts])


def separable_fit(y: np.ndarray, dt: float, runs: list[tuple[int, int]], w0: np.ndarray, z0: np.ndarray,
                  max_steps: int, residual: bool = False) -> tuple | None:
    """(ω, ζ, std of ω) of the piecewise model from the start (w0, z0); None when the problem is
    ill-posed (fewer samples than unknowns, a singular basis). std is NaN where JᵀJ is singular.

    With ``residual``, also the residual ε at the optimum (the segments' samples, in order) and the columns
    spanning the fit's tangent space there — each segment's basis Φ_s (block-diagonal) and J_r — for a
    whiteness test of ε (:func:`methods.pem.residual_check`'s ``basis``)."""
    m = w0.size
    q = len(runs)
    n = sum(b - a for a, b in runs)
    p = 2 * m + q * (2 * m + 1)
    if n <= p + 2:
        return None
    nyquist = np.pi / dt
    problem = _Piecewise(y, dt, m, runs)
    lo = np.r_[np.full(m, 1e-3 * nyquist), np.full(m, MIN_ZETA)]
    hi = np.r_[np.full(m, 0.999 * nyquist), np.full(m, MAX_ZETA)]
    x0 = np.clip(np.r_[w0, z0], lo * (1 + 1e-9), hi * (1 - 1e-9))
    if problem._evaluate(x0) is None:
        return None
    try:
        sol = scipy.optimize.least_squares(problem.residual, x0, jac=problem.jacobian, bounds=(lo, hi),
                                           method="trf", x_scale="jac", max_nfev=max_steps)
    except (ValueError, np.linalg.LinAlgError):
        return None
    parts = problem._evaluate(sol.x)
    if parts is None:
        return None
    e = np.concatenate([r for r, _ in parts])
    J = np.concatenate([j for _, j in parts])
    sigma2 = float(e @ e) / (n - p)
    try:
        cov = sigma2 * np.linalg.inv(J.T @ J)
        std = np.sqrt(np.clip(np.diag(cov)[:m], 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(m, np.nan)
    if not residual:
        return sol.x[:m], sol.x[m:], std
    # each model's Φ is that of its last fit: the one at sol.x that gave ``parts``
    basis = np.hstack([scipy.linalg.block_diag(*[model.phi for model in problem.models]), J])
    return sol.x[:m], sol.x[m:], std, e, basis
