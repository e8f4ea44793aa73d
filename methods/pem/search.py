"""The search of the prediction-error method: Gauss–Newton (eq. 30) from one start, exact derivatives.

Used by :mod:`methods.pem`; ``opts`` is its ``Options``. Unknowns θ = [ω (m), ζ (m), x₀ (2m), b] as in
:mod:`methods.pem.predictor`; ``free`` selects the estimated ones, ``bounds`` = (lower, upper) of (ω, ζ).
"""

from __future__ import annotations

import math

import numpy as np

from methods.pem import predictor as pp

__all__ = ["MAX_HALVINGS", "LM_HALVINGS", "IDENTIFIED_REL_STD", "LOCATED_REL_STD", "SETTLED_STD",
           "SETTLED_ITERATIONS", "MAX_GROWTH_EXPONENT", "LOSS_FLOOR_REL", "PHASE_ROUNDING", "JOIN_STD",
           "fit_one_start", "solve_linear", "gauss_newton", "SETTLED_MESSAGE", "at_iteration_limit", "loss_floor",
           "JOINED_MESSAGE", "stop_after_step", "damped_step", "search_bounds", "LinearizedSystem",
           "NormalEquations", "lstsq_step", "valid_modes"]

MAX_HALVINGS = 40               # the paper's rule: μ = 1, 1/2, 1/4, … until the loss decreases
LM_HALVINGS = 5                 # with Levenberg–Marquardt damping: halvings before λ grows
IDENTIFIED_REL_STD = 0.01       # a mode is 'determined by the data' when std(ω) ≤ 1 % of ω
LOCATED_REL_STD = 0.1           # … 'located' when std(ω) ≤ 10 % of ω
SETTLED_STD = 0.01              # a located mode has 'settled' when it moved less than this many std
SETTLED_ITERATIONS = 5          # … over this many iterations
MAX_GROWTH_EXPONENT = 20.0      # no mode may grow by more than e²⁰ over the record
LOSS_FLOOR_REL = 1e-13         # a residual rms this far below the data's rms is rounding: stop there
PHASE_ROUNDING = 1e-15          # … plus this times the largest phase ω·NΔt the model reaches (rad)
JOIN_STD = 0.1                  # a later start within this many std of an earlier fit in every (ω, ζ) has joined it


def fit_one_start(y, dt, w0, z0, shape, free, opts, bounds, join=None) -> dict:
    """Gauss–Newton from one start; a dict with θ, loss, ε, J, the stopping reason and convergence.

    ``join``: (θ, std of θ_free) of an earlier start's converged fit, or None. A search that comes within
    ``JOIN_STD`` std of it in every free (ω, ζ) stops there (``fit["joined"]`` True): it is in the same
    basin and would converge to the same minimum, so the remaining iterations would be spent for nothing
    (most of a multi-start fit's time went to later starts re-converging to the first one's answer)."""
    m = w0.size
    theta = np.concatenate([np.clip(np.r_[w0, z0], *bounds), np.zeros(2 * m), [0.0]])
    w0, z0 = theta[:m], theta[m:2 * m]
    with_gain = opts.predictor == "kalman"
    try:
        K = (pp.kalman_gain(w0, z0, dt, shape, opts.kalman_qd, opts.kalman_rd) if with_gain
             else np.zeros(2 * m))
    except (np.linalg.LinAlgError, ValueError) as exc:
        return _bad(theta, f"no steady-state Kalman gain at the start ({exc})")
    ev = pp.make_evaluator(y, dt, m, free, K if with_gain else None)
    theta, _, loss = solve_linear(ev, theta, m)              # x₀, b: exact LS at the start's (ω, ζ)
    if not np.isfinite(loss):
        return _bad(theta, "the predictor diverges at the start")
    return gauss_newton(theta, np.flatnonzero(free), ev, dt, opts, bounds, join)


def solve_linear(ev, theta, m):
    """θ with the linear unknowns c = (x₀, b) set to their least-squares values at θ's (ω, ζ).

    ε(θ) is affine in c, ε = ε₀ + G c, so one linear solve is exact. Returns (θ, ε, loss).
    """
    if hasattr(ev, "project"):                 # the closed form's own lean solve (None: near-singular)
        done = ev.project(theta)
        if done is not None:
            return done
    theta = theta.copy()
    theta[2 * m:2 * m + ev.n_linear] = 0.0                    # a fixed offset stays at its value
    e0, G = ev.linear_part(theta)
    if not (np.all(np.isfinite(e0)) and np.all(np.isfinite(G))):
        return theta, e0, np.inf
    c = _linear_solve(G, e0)
    theta[2 * m:2 * m + ev.n_linear] += c
    e = e0 + G @ c
    return theta, e, float(e @ e / e.size)


def gauss_newton(theta, free_idx, ev, dt, opts, bounds, join=None) -> dict:
    """Eq. (30): θ ← θ + μ d, μ = 1 halved until the loss decreases (the paper's rule).

    ``search="gauss_newton"``: d is the Gauss–Newton step −(JᵀJ)⁻¹Jᵀε on all free unknowns, halved up to
    40 times. ``search="levenberg_marquardt"``: d = −(JᵀJ + λ·s₀²I)⁻¹Jᵀε in column-scaled unknowns (s₀ the
    largest singular value); after 5 fruitless halvings λ grows ×10 and the step is recomputed, after a full
    step it shrinks ÷10, so near the optimum it is plain Gauss–Newton. The damping matters when one mode is
    poorly determined: its sloppy direction dominates the Gauss–Newton step, the halving then shortens
    every other unknown's step alike and the search crawls (MATLAB's later ``pem`` adapts the same way).

    With ``separable`` every trial point keeps the step in (ω, ζ) and re-solves the linear unknowns
    (x₀, b) exactly (variable projection, Golub & Pereyra 1973, with Kaufman's Jacobian — which is what the
    step is at a point where (x₀, b) are already optimal); without it the whole step is taken, as
    MATLAB's ``pem`` does.
    """
    m = (theta.size - 1) // 4
    nonlin = free_idx < 2 * m
    joined = False
    if join is not None:
        join_at, join_tol = join[0][free_idx[nonlin]], JOIN_STD * join[1][nonlin]
    lm = opts.search == "levenberg_marquardt"
    lam = 0.0
    e, J = ev.residual_jacobian(theta)
    n = e.size
    loss = e @ e / n
    # A noise-free record is fitted to rounding; below this every step's decrease is rounding noise, and
    # proving "no decrease" costs ~85 trial points (every halving at every λ) — on 10⁶ samples, minutes.
    # The model's own rounding grows with the phase ωt it reaches (t = kΔt is rounded): ~ε_mach·ω·t_max.
    floor = loss_floor(theta[:m], ev.y, dt)
    message, converged, iterations = "iteration limit", False, 0
    history, step_lengths = [theta[:m].copy()], []
    std_free = None
    while iterations < opts.max_iterations:
        iterations += 1
        system = NormalEquations(J, e)
        d = system.step(0.0)
        blocked = _blocked_by_bounds(theta, free_idx, d, bounds)
        if blocked.any():                     # active set: a ζ at its bound that the step pushes out stays
            system = system.without(blocked)
            d = system.step(0.0)
        if not np.all(np.isfinite(d)):
            message = "singular Jacobian"
            break
        if _settled(theta, system.std[:m], history):
            message, converged = SETTLED_MESSAGE, True
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            step_in_std = float(np.nanmax(np.abs(d) / system.std))
        if step_in_std < opts.tol_step:
            message, converged = f"step size below {opts.tol_step:g} std", True
            if not blocked.any() and system.well_conditioned:
                std_free = system.std          # at the final θ: the SVD's std to ~1e-10 (see the class)
            break

        def try_point(d, mu, base=theta):
            cand = base.copy()
            if opts.separable:
                cand[free_idx[nonlin]] += mu * d[nonlin]
            else:
                cand[free_idx] += mu * d
            head = cand[:2 * m]                      # np.clip's values, two ufunc calls without its wrapper
            np.minimum(np.maximum(head, bounds[0], out=head), bounds[1], out=head)
            if not _valid(cand, dt, n):
                return None
            if opts.separable:
                cand, _, loss_new = solve_linear(ev, cand, m)
            else:
                e_new = ev.residual(cand)
                loss_new = e_new @ e_new / n
            return loss_new, cand

        found, mu, lam, trial = damped_step(system, lam, loss, lm, try_point)
        if found:
            loss_new, cand = trial
        if not found:
            # No decrease along any damped step: a minimum to rounding.
            message = f"no loss decrease along the search direction ({step_in_std:.2g} std)"
            converged = lm or step_in_std < 1.0
            break
        improvement = (loss - loss_new) / loss if loss > 0 else 0.0
        step_lengths.append(mu)
        theta, loss = cand, loss_new
        e, J = ev.residual_jacobian(theta)
        at_join = join is not None and bool(np.all(np.abs(theta[free_idx[nonlin]] - join_at) <= join_tol))
        stop = stop_after_step(opts, improvement, loss, floor, at_join)
        if stop:
            message, converged, joined = stop, True, at_join and stop == JOINED_MESSAGE
            break
        history.append(theta[:m].copy())
    else:
        message, converged = at_iteration_limit(theta[:m], LinearizedSystem(J, e).std[:m], history)
    return {"theta": theta, "loss": loss, "e": e, "J": J, "iterations": iterations, "message": message,
            "converged": converged, "step_lengths": step_lengths, "joined": joined, "floor": floor,
            **({} if std_free is None else {"std_free": std_free})}


SETTLED_MESSAGE = (f"the located frequencies settled to {SETTLED_STD:g} std over {SETTLED_ITERATIONS} "
                   "iterations (the others are not located)")


def at_iteration_limit(w, w_std, history) -> tuple[str, bool]:
    """(message, converged) of a search that reached the iteration limit. Modes the record does not
    determine can crawl along a flat, curved valley for hundreds of iterations; the answer still counts
    when every mode the data locate (std ≤ 10 % of ω) has settled over the last iterations."""
    m = w.size
    located = w_std <= LOCATED_REL_STD * w
    drift = np.abs(history[-1] - history[max(len(history) - SETTLED_ITERATIONS, 0)])
    if located.any() and np.all(drift[located] < SETTLED_STD * w_std[located]):
        return (f"iteration limit; the located frequencies settled to {SETTLED_STD:g} std "
                f"({m - located.sum()} not located)"), True
    return "iteration limit", False


def loss_floor(w: np.ndarray, y: np.ndarray, dt: float) -> float:
    """The loss below which a fit is at the rounding level of the data: the residual rms ``LOSS_FLOOR_REL``
    of the data's, plus the model's own rounding, which grows with the phase ωt it reaches (t = kΔt is
    rounded): ~ε_mach·ω·t_max."""
    n = y.size
    floor_rel = LOSS_FLOOR_REL + PHASE_ROUNDING * float(w.max()) * n * dt
    return floor_rel ** 2 * float(y @ y) / n


JOINED_MESSAGE = f"joined an earlier start's fit (within {JOIN_STD:g} std)"


def stop_after_step(opts, improvement: float, loss: float, floor: float, at_join: bool) -> str | None:
    """Why a search ends after an accepted step — the relative loss improvement below ``tol_loss``, the
    loss at the data's rounding level, or the point within ``JOIN_STD`` std of an earlier start's fit
    (checked in this order) — or None to go on. Shared with :mod:`methods.pem._fast`."""
    if improvement < opts.tol_loss:
        return f"relative loss improvement below {opts.tol_loss:g}"
    if loss <= floor:
        return "residual at the rounding level of the data"
    return JOINED_MESSAGE if at_join else None


def damped_step(system, lam: float, loss: float, lm: bool, try_point):
    """The step rule of eq. (30), shared by this search and :mod:`methods.pem._fast`: from the system's
    step for damping λ, μ = 1 halved until ``try_point(d, μ)`` — (loss, payload) of the trial point, or
    None where it is not valid — gives a lower loss (40 halvings for pure Gauss–Newton; for
    Levenberg–Marquardt 5, then λ grows ×10 and the step is recomputed; a full step shrinks λ ÷10).
    Returns (found, μ, λ, (loss, payload) of the accepted point or None)."""
    halvings = LM_HALVINGS if lm else MAX_HALVINGS
    found, trial = False, None
    while not found:
        d = system.step(lam)
        mu = 1.0
        for _ in range(halvings):
            out = try_point(d, mu)
            if out is not None and math.isfinite(out[0]) and out[0] < loss:
                found, trial = True, out
                break
            mu *= 0.5
        if not lm or lam > 1e8:
            break
        if not found:
            lam = max(10.0 * lam, 1e-8)
        elif mu == 1.0:
            lam = 0.0 if lam <= 1e-8 else lam / 10.0
    return found, mu, lam, trial


def _settled(theta, w_std, history) -> bool:
    """Whether a search with modes the record does not locate (std > 10 % of ω) can stop: every located
    mode moved less than ``SETTLED_STD`` std over the last ``SETTLED_ITERATIONS`` iterations. The others
    crawl along a flat valley for as long as they are allowed (50 iterations, at every start and repair:
    most of the time of a short or very noisy record went there) without moving the located ones."""
    if len(history) <= SETTLED_ITERATIONS:
        return False
    m = w_std.size
    located = w_std <= LOCATED_REL_STD * theta[:m]
    if not located.any() or located.all():
        return False
    drift = np.abs(history[-1] - history[-1 - SETTLED_ITERATIONS])
    return bool(np.all(drift[located] < SETTLED_STD * w_std[located]))


def _blocked_by_bounds(theta, free_idx, d, bounds) -> np.ndarray:
    """Free columns whose (ω or ζ) entry sits on a bound that the step d would cross."""
    lo, hi = bounds
    nonlin = free_idx < lo.size
    idx = np.where(nonlin, free_idx, 0)
    v = theta[free_idx]
    return nonlin & (((v <= lo[idx]) & (d < 0)) | ((v >= hi[idx]) & (d > 0)))


def search_bounds(prior: np.ndarray, dt: float, opts):
    """(lower, upper) of (ω, ζ): ω within prior·(1 + band)^±1 and below Nyquist, ζ within damping_bounds."""
    band = np.inf if opts.frequency_band is None else opts.frequency_band
    top = 0.98 * np.pi / dt
    p = np.asarray(prior, dtype=float).tolist()           # (m Python floats: numpy's values, two calls)
    z_lo, z_hi = float(opts.damping_bounds[0]), float(opts.damping_bounds[1])
    return (np.array([w / (1.0 + band) for w in p] + [z_lo] * len(p)),
            np.array([min(w * (1.0 + band), top) for w in p] + [z_hi] * len(p)))


class LinearizedSystem:
    """ε(θ + d) ≈ ε + J d, solved through the SVD of the column-scaled J (scaling fixes the units).

    The SVD is that of R from J/norms = QR (R is p × p; the QR of a tall matrix is the cheap part of a
    tall SVD, and nothing N × p but J itself is kept), with Uᵀε = S⁻¹Vᵀ(J/norms)ᵀε."""

    def __init__(self, J: np.ndarray, e: np.ndarray):
        norms = np.linalg.norm(J, axis=0)
        zero = norms == 0
        norms[zero] = 1.0
        Js = J / norms
        R = np.linalg.qr(Js, mode="r")
        _, s, vt = np.linalg.svd(R)
        self._keep = s > s[0] * 1e-14 if s.size and s[0] > 0 else np.zeros(s.size, bool)
        s_inv = np.where(self._keep, 1.0 / np.where(self._keep, s, 1.0), 0.0)
        self._norms, self._s, self._vt, self._g = norms, s, vt, s_inv * (vt @ (Js.T @ e))
        var = (vt.T ** 2) @ (s_inv ** 2) / norms ** 2              # diag((JᵀJ)⁻¹)
        sigma2 = e @ e / max(e.size - J.shape[1], 1)
        # an unknown whose column is exactly zero (e.g. the frequency of a mode of zero amplitude: an
        # all-zero record) is not determined at all, even when the residual is zero too
        self.std = np.where((var > 0) & ~zero, np.sqrt(sigma2 * var), np.inf)

    def step(self, lam: float) -> np.ndarray:
        """−(JᵀJ + λs₀²I)⁻¹Jᵀε in scaled unknowns; λ = 0 is the (pseudo-inverse) Gauss–Newton step."""
        s = self._s
        f = np.where(self._keep, s / np.where(self._keep, s * s + lam * s[0] ** 2, 1.0), 0.0)
        return -(self._vt.T @ (f * self._g)) / self._norms


class NormalEquations:
    """The Gauss–Newton/LM step of :class:`LinearizedSystem` from JᵀJ and Jᵀε (column-scaled, eigh of a
    p × p matrix) instead of the SVD of the N × p Jacobian: the same step wherever (JᵀJ) is not
    near-singular to rounding, at a fraction of the cost (the SVD of a 256 × 17 matrix was half of the
    search's time), and nothing N × p is kept. Directions with eigenvalue below 1e-15 of the largest —
    singular values below 3e-8 of the largest, unidentifiable in double precision through JᵀJ — are left
    out (pseudo-inverse). The reported std at the optimum still comes from the SVD (:func:`lstsq_step`)."""

    def __init__(self, J: np.ndarray | None, e: np.ndarray, _gram=None):
        if _gram is None:
            H, g, ee, n = J.T @ J, J.T @ e, float(e @ e), e.size
        else:
            H, g, ee, n = _gram
        self._gram = (H, g, ee, n)
        # (the fast search builds one of these per iteration: the common case — every column non-zero,
        # every direction kept — takes the short branches, with the same arithmetic as the general ones)
        norms = np.sqrt(H.diagonal())
        if norms.size and not norms.min() > 0:
            norms = np.where(norms > 0, norms, 1.0)
        scale = np.multiply.outer(norms, norms)               # np.outer's values without its wrapper
        lam2, V = pp.symmetric_eigh(H / scale)
        # the eigenvalues come ascending: every direction is kept when the smallest is (Python floats, no
        # mask in the common case)
        top = float(lam2[-1]) if lam2.size else 0.0
        low = float(lam2[0]) if lam2.size else 0.0
        self._all_kept = lam2.size == 0 or (top > 0 and low > top * 1e-15)
        keep = None if self._all_kept else (lam2 > top * 1e-15 if top > 0 else np.zeros(lam2.size, bool))
        self._norms, self._lam2, self._V, self._keep, self._top = norms, lam2, V, keep, top
        self._gv = V.T @ (g / norms)
        # scaled singular values within 1e-5 of each other: the eigh's std equals the SVD's to ~1e-10
        self.well_conditioned = self._all_kept and low > 1e-10 * top
        inv = self._inv = 1.0 / lam2 if self._all_kept else np.where(keep, 1.0 / np.where(keep, lam2, 1.0), 0.0)
        var = (V * V) @ inv / scale.diagonal()                 # the diagonal is norms * norms
        self.sigma2 = sigma2 = ee / max(n - H.shape[0], 1)
        if var.size and var.min() > 0:
            self.std = np.sqrt(sigma2 * var)
        else:
            self.std = np.where(var > 0, np.sqrt(sigma2 * var), np.inf)
        self._gauss_newton = None

    def predicted_decrease(self) -> float:
        """The decrease of Σε² that the Gauss–Newton step d = −(JᵀJ)⁻¹Jᵀε promises on the linearised model,
        |ε|² − |ε + Jd|² = Jᵀε·(JᵀJ)⁻¹Jᵀε (the kept directions): over σ̂² it is the step's squared length in
        the metric of the covariance σ̂²(JᵀJ)⁻¹."""
        gv = self._gv
        return float((gv * gv) @ self._inv)

    @property
    def size(self) -> int:
        """The number of unknowns (columns of J)."""
        return self._lam2.size

    def inverse(self) -> np.ndarray:
        """(JᵀJ)⁻¹ from the eigendecomposition of the column-scaled JᵀJ: W Λ⁻¹ Wᵀ, W = V/norms (the
        pseudo-inverse where directions were left out)."""
        W = self._V / self._norms[:, None]
        return (W * self._inv) @ W.T

    def without(self, columns: np.ndarray) -> NormalEquations:
        """The system with the given columns of J set to zero (an active bound)."""
        H, g, ee, n = self._gram
        H, g = H.copy(), g.copy()
        H[columns, :] = 0.0
        H[:, columns] = 0.0
        g[columns] = 0.0
        return NormalEquations(None, None, (H, g, ee, n))

    def step(self, lam: float) -> np.ndarray:
        """−(JᵀJ + λs₀²I)⁻¹Jᵀε in scaled unknowns; λ = 0 is the (pseudo-inverse) Gauss–Newton step (computed
        once: the search asks for it again in its step rule; treat the array as read-only)."""
        if lam == 0.0 and self._gauss_newton is not None:
            return self._gauss_newton
        lam2 = self._lam2
        if self._all_kept:
            f = 1.0 / (lam2 + lam * self._top)
        else:
            f = np.where(self._keep, 1.0 / np.where(self._keep, lam2 + lam * self._top, 1.0), 0.0)
        d = -(self._V @ (f * self._gv)) / self._norms
        if lam == 0.0:
            self._gauss_newton = d
        return d


def _linear_solve(G: np.ndarray, e0: np.ndarray) -> np.ndarray:
    """c minimising |e0 + G c|: normal equations of the column-scaled G (a p × p Cholesky-like solve,
    far cheaper than the SVD of N × p), the SVD pseudo-inverse where they are near-singular."""
    H = G.T @ G
    norms = np.sqrt(np.diag(H))
    if np.all(norms > 0):
        Hs = H / np.outer(norms, norms)
        w = np.linalg.eigvalsh(Hs) if H.shape[0] > 0 else np.ones(1)
        if w[0] > 1e-12 * w[-1]:
            return -np.linalg.solve(Hs, (G.T @ e0) / norms) / norms
    return lstsq_step(G, e0)[0]


def lstsq_step(J: np.ndarray, e: np.ndarray):
    """Gauss–Newton step d = −J⁺ε and the std σ̂√diag((JᵀJ)⁻¹), σ̂² = Σε²/(N − p)."""
    system = LinearizedSystem(J, e)
    return system.step(0.0), system.std


def _valid(theta, dt, n) -> bool:
    """:func:`valid_modes` of the (ω, ζ) of a full parameter vector."""
    m = (theta.size - 1) // 4
    return valid_modes(theta[:m], theta[m:2 * m], dt, n)


def valid_modes(w, z, dt, n) -> bool:
    """Frequencies positive, damped frequency below Nyquist, |ζ| < 0.9, and no mode growing more than
    e²⁰ over the record (a negative ζ lets a mode the record does not determine mimic a trend)."""
    # called for every trial point: a loop over m Python floats costs a quarter of the vectorised test
    # (a 1-D array as it is: np.ravel's wrapper cost as much as the test itself)
    w = w if isinstance(w, np.ndarray) and w.ndim == 1 else np.ravel(w)
    z = z if isinstance(z, np.ndarray) and z.ndim == 1 else np.ravel(z)
    for wi, zi in zip(w.tolist(), z.tolist(), strict=True):
        if not (wi > 0 and abs(zi) < 0.9 and wi * math.sqrt(max(1.0 - zi * zi, 0.0)) * dt < math.pi
                and -zi * wi * dt * n < MAX_GROWTH_EXPONENT):
            return False
    return True


def _bad(theta, message) -> dict:
    return {"theta": theta, "loss": np.inf, "e": None, "J": None, "iterations": 0, "message": message,
            "converged": False, "joined": False}
