"""The default search of :mod:`methods.pem` in few array operations: variable projection for the output-error
model, the same Levenberg–Marquardt rules as :func:`methods.pem.search.gauss_newton` (the reference path).

The model ŷ = Φ(ω, ζ)·c is linear in c = (x₀, b) (:class:`methods.pem.predictor.ClosedForm`). With c at its
least-squares value for every (ω, ζ), the search runs on (ω, ζ) alone with Kaufman's reduced Jacobian

    J_r = P⊥ J_n,   P⊥ = I − Φ(ΦᵀΦ)⁻¹Φᵀ,   J_n = ∂ε/∂(ω, ζ) at fixed c,

whose normal equations J_rᵀJ_r d = −J_rᵀε are the Schur complement of the full ones: the same Gauss–Newton
step and the same std of (ω, ζ), σ̂²·diag((J_rᵀJ_r)⁻¹), as the full p-unknown system, from a 2m × 2m matrix.
Everything the reference does per iteration — the basis, the linear solve, the residual, the Jacobian, the
normal equations — is one pass here over buffers of N × (2m + 1), about 25 numpy calls; the reference's
general evaluator interface (also used by the recursive Kalman predictor) costs about three times as many.
Only the Levenberg–Marquardt damping differs: λ scales the reduced system's largest eigenvalue, not the full
one's; damped steps differ, the minimum does not (test: the two paths agree to 1e-8 on noise-free data).

Hand-written because no kept library solves separable least squares: ``scipy.optimize.least_squares`` on
the full model (measured side by side in ``experiments.benchmarks.pem_speed``) is the comparison.
The same iteration as one CasADi Function (MX, or compiled to C) is slower at these sizes: its products are
not BLAS (``experiments.benchmarks.pem_casadi``; docs/notes/pem-speed.md, seventh pass).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from methods.pem import search
from methods.pem.predictor import _powers, scaled_lstsq

# A fit keeps its basis Φ (for the residual check, which would otherwise rebuild it) up to this many samples:
# at most 4096 × (2m + 1) values per start; a longer record's check rebuilds it rather than hold N × (2m + 1)
# per start through the multi-start (72 MB each at 10⁶ samples and 4 modes)
KEEP_BASIS_SAMPLES = 4096


@functools.lru_cache(maxsize=64)
def _sample_times(n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(k, t) = (0…N−1, kΔt as a column), read-only; kept per (N, Δt) up to ``KEEP_BASIS_SAMPLES`` samples
    (at most 64 × 64 kB: a warm fit's model makes no new ones), made afresh for a longer record."""
    k = np.arange(n)
    t = (k * dt)[:, None]
    k.flags.writeable = t.flags.writeable = False
    return k, t


class _Model:
    """Basis, linear solve, residual and reduced Jacobian of the damped-sinusoid model at (ω, ζ)."""

    def __init__(self, y: np.ndarray, dt: float, m: int, with_offset: bool, fixed_offset: float):
        self.y = np.ascontiguousarray(y, dtype=float)
        n = self.y.size
        self.k, self.t = _sample_times(n, dt) if n <= KEEP_BASIS_SAMPLES else _sample_times.__wrapped__(n, dt)
        self.dt, self.m = dt, m
        self.target = self.y - fixed_offset if fixed_offset else self.y
        self.phi = np.empty((n, 2 * m + with_offset))      # columns: e^{−σt}cos (m), e^{−σt}sin (m), [1]
        if with_offset:
            self.phi[:, 2 * m] = 1.0

    def fit(self, w: np.ndarray, z: np.ndarray):
        """(c, ε, loss, solver) at (ω, ζ); None where ΦᵀΦ is near-singular or not finite. ``solver`` keeps
        what the reduced Jacobian at this point needs (the basis Φ itself stays in ``self.phi`` until the
        next call)."""
        m, phi, n, dt = self.m, self.phi, self.k.size, self.dt
        # sΔt = (−ζω + jω√(1 − ζ²))Δt over m Python floats (|ζ| < 0.9 inside the bounds): the same IEEE
        # operations as the array expression, a fifth of its calls
        root = [math.sqrt(1.0 - zi * zi) for zi in z.tolist()]
        logp = np.array([complex(-zi * wi * dt, wi * ri * dt)
                         for wi, zi, ri in zip(w.tolist(), z.tolist(), root, strict=True)])
        p = _powers(logp, n)
        phi[:, :m] = p.real
        phi[:, m:2 * m] = p.imag
        solved = scaled_lstsq(phi, self.target)
        if solved is None:
            return None
        c, (norms, lam, V) = solved
        e = self.target - phi @ c
        return c, e, float(e @ e) / n, (norms, lam, V, root)

    def reduced_jacobian(self, w, z, c, solver, estimate_damping: bool) -> np.ndarray:
        """J_r = P⊥ ∂ε/∂(ω[, ζ]) (N × m or N × 2m) at a point where c is the least-squares solution.

        With pᵢ(t) = e^{(−σᵢ + jω_dᵢ)t} and the mode's complex amplitude αᵢ = Aᵢ − jBᵢ, its output is
        Re(αᵢpᵢ) = gᵢ and −Im(αᵢpᵢ) = hᵢ (the :class:`methods.pem.predictor.ClosedForm` docstring), so
        −∂ŷ/∂ωᵢ = t·Re(αᵢpᵢ·(ζᵢ − j√(1 − ζᵢ²))) and −∂ŷ/∂ζᵢ = t·Re(αᵢpᵢ·(ωᵢ + jωᵢζᵢ/√(1 − ζᵢ²))): the
        chain rule's coefficients folded into one complex factor fⱼ per column. With Re pᵢ, Im pᵢ the basis
        columns, Re(pᵢfⱼ) = Re pᵢ·Re fⱼ − Im pᵢ·Im fⱼ: Jₙ = t·(Φ₁..₂ₘ M), one product with a sparse
        2m × p matrix M."""
        m, phi = self.m, self.phi
        norms, lam, V, root = solver
        # the m (or 2m) factors and M in Python complex arithmetic: cheaper than a dozen calls on m-vectors
        w, z = w.tolist(), z.tolist()
        alpha = [complex(a, -b) for a, b in zip(c[:m].tolist(), c[m:2 * m].tolist(), strict=True)]
        factor = [al * complex(zi, -ri) for al, zi, ri in zip(alpha, z, root, strict=True)]
        if estimate_damping:
            factor += [al * complex(wi, wi * zi / ri) for al, wi, zi, ri in zip(alpha, w, z, root, strict=True)]
        cols = len(factor)
        M = [0.0] * (2 * m * cols)                                   # row-major 2m × cols
        for j, f in enumerate(factor):
            M[(j % m) * cols + j], M[(m + j % m) * cols + j] = f.real, -f.imag
        Jn = phi[:, :2 * m] @ np.array(M).reshape(2 * m, cols)
        Jn *= self.t
        # P⊥Jn = Jn − Φ (ΦᵀΦ)⁻¹ ΦᵀJn, through the eigendecomposition of the scaled ΦᵀΦ of the linear solve
        # (in place: two N × 2m temporaries fewer)
        W = V / norms[:, None]
        Jn -= phi @ (W @ ((W.T @ (phi.T @ Jn)) / lam[:, None]))
        return Jn


class _Handover(Exception):
    """Raised inside a trial point: this start goes to the reference search."""


def _reduced(Jr: np.ndarray, e: np.ndarray, n_unknowns: int, loss: float) -> search.NormalEquations:
    """The (ω, ζ) normal equations J_rᵀJ_r, column-scaled (:class:`methods.pem.search.NormalEquations`),
    with σ̂² = Σε²/(N − p) for all p = ``n_unknowns`` free unknowns, as in the full system (Σε² = N·loss,
    the fit's own sum)."""
    return search.NormalEquations(None, None, (Jr.T @ Jr, Jr.T @ e, loss * e.size,
                                               e.size - n_unknowns + Jr.shape[1]))


def applies(opts) -> bool:
    """Whether a fit with these options takes this path (else the reference, search.gauss_newton)."""
    return opts.predictor == "output_error" and opts.separable and opts.search == "levenberg_marquardt"


def fit_one_start(y, dt, w0, z0, free, opts, bounds, join=None) -> dict | None:
    """:func:`methods.pem.search.fit_one_start` for the options :func:`applies` to: the same dict (θ, loss,
    ε, iterations, message, converged, ...; ``J`` None, ``std_free`` with NaN for the linear unknowns).

    None — the caller then runs the reference search from the same start — as soon as a mode is not
    determined by the record (std of ω above 1 % of ω) or the basis is near-singular: there the two
    searches' damped steps differ (λ scales a different matrix) and their paths through a flat valley can
    end at different points, so such a start gets exactly the reference's behaviour (short or very noisy
    records; measured: ``experiments.benchmarks.pem --part grid``), and the fast path is used where every
    mode is determined, which is where its speed matters."""
    m = w0.size
    est_z = bool(free[m])
    with_offset = bool(free[4 * m])
    n_unknowns = int(sum(free))
    lo, hi = bounds
    x = np.concatenate([w0, z0])                                 # (ω, ζ); ζ fixed when not estimated
    np.minimum(np.maximum(x, lo, out=x), hi, out=x)                 # np.clip's values, two ufunc calls
    model = _Model(y, dt, m, with_offset, 0.0)
    n = model.y.size
    sol = model.fit(x[:m], x[m:])
    if sol is None or not np.isfinite(sol[2]):
        return _result(model, x, None, np.inf, 0, "the predictor diverges at the start", False, [], free, None)
    c, e, loss, solver = sol
    nn = m * (1 + est_z)                                          # free nonlinear unknowns
    floor = search.loss_floor(x[:m], model.y, dt)
    if join is not None:
        join_at, join_tol = join[0][:nn], search.JOIN_STD * join[1][:nn]
    lo_z, hi_z = lo[m:].tolist(), hi[m:].tolist()
    lam = 0.0
    message, converged, iterations, joined = "iteration limit", False, 0, False
    history, step_lengths, std_free, final, phi_at_x = [x[:m].copy()], [], None, None, True
    Jr = model.reduced_jacobian(x[:m], x[m:], c, solver, est_z)
    system = None
    while iterations < opts.max_iterations:
        iterations += 1
        system = _reduced(Jr, e, n_unknowns, loss)
        d = system.step(0.0)
        blocked = None
        if est_z:                                                   # active set: ζ at its bound stays
            bz = [(v <= low and s < 0) or (v >= high and s > 0)    # (m Python floats: cheaper than arrays)
                  for v, s, low, high in zip(x[m:].tolist(), d[m:].tolist(), lo_z, hi_z, strict=True)]
            if any(bz):
                blocked = np.array([False] * m + bz)
                system = system.without(blocked)
                d = system.step(0.0)
        std = system.std
        # the tests over the ≤ 2m Python floats (numpy's values, a third of the calls)
        d_l, std_l = d.tolist(), std.tolist()
        if not (all(math.isfinite(v) for v in d_l)
                and all(s <= search.IDENTIFIED_REL_STD * w for s, w in zip(std_l[:m], x[:m].tolist(), strict=True))):
            return None     # a mode the record does not determine here: the reference search takes over
        if search._settled(x, std[:m], history):
            message, converged = search.SETTLED_MESSAGE, True
            break
        if all(s > 0 for s in std_l):         # the usual case: no 0/0, so max is nanmax
            step_in_std = max(abs(v) / s for v, s in zip(d_l, std_l, strict=True))
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                step_in_std = float(np.nanmax(np.abs(d) / std))
        # a step below tol_step std, or the statistical stop: the step would lower Σε² by less than
        # tol_decrease·σ̂², i.e. the point is within √tol_decrease std of the local minimum in the covariance's
        # metric (so within that many std in every (ω, ζ)), far inside the estimate's own scatter; the
        # iteration that would take the step and confirm it (a model evaluation, a reduced Jacobian, a
        # normal-equation solve) is not made
        if step_in_std < opts.tol_step:
            stop = f"step size below {opts.tol_step:g} std"
        elif system.predicted_decrease() < opts.tol_decrease * system.sigma2:
            stop = f"predicted loss decrease below {opts.tol_decrease:g} σ̂²"
        else:
            stop = None
        if stop is not None:
            message, converged = stop, True
            if blocked is None and system.well_conditioned:
                std_free, final = system.std, system
            break

        def try_point(d, mu, base=x):
            cand = base.copy()
            cand[:nn] += d if mu == 1.0 else mu * d          # (1.0·d is d: one product fewer)
            np.minimum(np.maximum(cand, lo, out=cand), hi, out=cand)     # np.clip's values, two ufunc calls
            if not search.valid_modes(cand[:m], cand[m:], dt, n):
                return None
            trial = model.fit(cand[:m], cand[m:])
            if trial is None:
                raise _Handover      # a near-singular basis: the reference's SVD route takes over
            return trial[2], (cand, trial)

        try:
            found, mu, lam, trial = search.damped_step(system, lam, loss, True, try_point)
        except _Handover:
            return None
        if not found:
            message = f"no loss decrease along the search direction ({step_in_std:.2g} std)"
            converged, phi_at_x = True, False        # the basis buffer holds a rejected trial point's
            break
        cand, (c, e, loss_new, solver) = trial[1]
        improvement = (loss - loss_new) / loss if loss > 0 else 0.0
        step_lengths.append(mu)
        x, loss = cand, loss_new
        Jr = model.reduced_jacobian(x[:m], x[m:], c, solver, est_z)
        at_join = join is not None and bool(np.all(np.abs(x[:nn] - join_at) <= join_tol))
        stop = search.stop_after_step(opts, improvement, loss, floor, at_join)
        if stop:
            message, converged, joined = stop, True, at_join and stop == search.JOINED_MESSAGE
            break
        history.append(x[:m].copy())
    else:
        message, converged = search.at_iteration_limit(x[:m], _reduced(Jr, e, n_unknowns, loss).std[:m],
                                                       history)
    if std_free is None:                     # the std at the final point (a stop other than the step rule)
        final = _reduced(Jr, e, n_unknowns, loss)
        std_free = final.std
    fit = _result(model, x, c, loss, iterations, message, converged, step_lengths, free, std_free)
    # Jr: the robust std; Φ, Jr and the factorisations of ΦᵀΦ and J_rᵀJ_r at the optimum: the residual
    # check's projection (methods.pem._residual.tangent_gram_inverse)
    keep_basis = phi_at_x and n <= KEEP_BASIS_SAMPLES
    fit.update(e=e, joined=joined, floor=floor, Jr=Jr, basis=model.phi if keep_basis else None,
               basis_solver=solver[:3], jr_system=final)
    return fit


def _result(model, x, c, loss, iterations, message, converged, step_lengths, free, std_nonlin) -> dict:
    """The reference's fit dict: θ = [ω, ζ, x₀ (A₁, B₁, …), b] and the std of the free unknowns."""
    m = model.m
    theta = np.zeros(4 * m + 1)
    theta[:2 * m] = x
    if c is not None:
        theta[2 * m:4 * m:2], theta[2 * m + 1:4 * m:2] = c[:m], c[m:2 * m]
        if c.size > 2 * m:
            theta[4 * m] = c[2 * m]
    fit = {"theta": theta, "loss": loss, "e": None, "J": None, "iterations": iterations, "message": message,
           "converged": converged, "step_lengths": step_lengths, "joined": False}
    if std_nonlin is not None:
        std = np.full(int(sum(free)), np.nan)
        std[:std_nonlin.size] = std_nonlin
        fit["std_free"] = std
    return fit
