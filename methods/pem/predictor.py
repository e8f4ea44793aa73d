"""The one-step predictor of the PEM identification model and its exact Jacobian (CasADi).

Identification model: eq. (8) without the frequency states x₉…x₁₂, i.e. m decoupled modes
q̈ᵢ + 2ζᵢωᵢq̇ᵢ + ωᵢ²qᵢ = 0 (eq. 7) sampled exactly with Δt, the tip *acceleration* as output (eq. 10), and a
constant sensor offset b, in the innovation form of eq. (31):

    x(k+1) = φ x(k) + K e(k),    y(k) = C x(k) + b + e(k).

The predictor works in the *modal acceleration* (real Jordan) coordinates of each mode, a similarity
transform of the paper's (qᵢ, q̇ᵢ) with C = [… −Wᵢωᵢ²  −2Wᵢζᵢωᵢ …] (eq. 10):

    φᵢ = e^{−σᵢΔt} [[cos ω_dᵢΔt, sin ω_dᵢΔt], [−sin ω_dᵢΔt, cos ω_dᵢΔt]],  Cᵢ = [1 0],
    σᵢ = ζᵢωᵢ,  ω_dᵢ = ωᵢ√(1 − ζᵢ²),

so that with K = 0 the output is Σ e^{−σᵢt}(Aᵢ cos ω_dᵢt + Bᵢ sin ω_dᵢt) + b with x₀ = (A₁, B₁, …) in m/s².
The transform leaves the predictor, the loss and the frequency estimates unchanged (the Kalman gain is
transformed with it, :func:`kalman_gain`), but it decouples the initial state from ω: in (q, q̇) the
acceleration amplitude is ∝ ω²q₀, a bilinear coupling that bends the loss valley of a poorly determined
mode and stalls Gauss–Newton. The predictor runs

    ε(k) = y(k) − C x̂(k) − b,    x̂(k+1) = φ x̂(k) + K ε(k),    x̂(0) = x₀,

and the loss of eq. (30) is V(θ) = (1/N) Σ ε(k)². The unknowns θ are, in this order, the m frequencies ω,
the m damping ratios ζ, the initial state x₀ (2m) and the offset b; a *free mask* selects the ones the
search estimates (the others are held at the value passed in).

Two evaluators of ε and its exact Jacobian: :class:`ClosedForm` for the output-error predictor (K = 0:
ε is a closed-form sum of damped sinusoids, numpy, O(N·m), no build), and :class:`Recursive` for the
Kalman predictor (CasADi: one step function repeated with ``mapaccum`` and differentiated algorithmically;
the graph's size does not depend on N; the functions are cached per (N, m, free mask, gain) — a
pure-function cache). φ is exact (no Euler step), so a noise-free sum of damped sinusoids is reproduced
to rounding.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.linalg

__all__ = ["n_params", "split", "paper_state_space", "kalman_gain", "modal_basis", "symmetric_eigh", "scaled_lstsq",
           "ClosedForm", "predictor", "Recursive", "make_evaluator"]

try:                                       # numpy's LAPACK kernels (private module; numpy 2.4 is pinned)
    from numpy.linalg import _umath_linalg
except ImportError:                        # pragma: no cover - a numpy without it: the public eigh
    _umath_linalg = None

# casadi and scipy.linalg are imported where the Kalman predictor needs them: the default (output-error)
# path uses neither, and a pipeline job that only runs it should not pay for their import.


def n_params(n_modes: int) -> int:
    """Length of the full parameter vector θ = [ω (m), ζ (m), x₀ (2m), b]."""
    return 4 * n_modes + 1


def split(theta: np.ndarray, n_modes: int):
    """(ω, ζ, x₀, b) views of a full parameter vector."""
    m = n_modes
    return theta[:m], theta[m:2 * m], theta[2 * m:4 * m], theta[4 * m]


def _modal_transition(w, z, dt, lib):
    """φᵢ in modal acceleration coordinates, row-major (φ11, φ12, φ21, φ22)."""
    e = lib.exp(-z * w * dt)
    arg = w * lib.sqrt(1.0 - z * z) * dt
    c, s = e * lib.cos(arg), e * lib.sin(arg)
    return c, s, -s, c


def _paper_transition(w, z, dt):
    """Exact e^{A dt} of q̈ + 2ζωq̇ + ω²q = 0 in the paper's coordinates (q, q̇), eq. (8)."""
    sig, wd = z * w, w * np.sqrt(1.0 - z * z)
    e, c, s = np.exp(-sig * dt), np.cos(wd * dt), np.sin(wd * dt)
    return e * np.array([[c + sig / wd * s, s / wd], [-(w * w / wd) * s, c - sig / wd * s]])


def paper_state_space(omega, zeta, dt: float, tip_shape) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """φ, C of eqs. (8), (10) in (q₁, q̇₁, …), and T with x_paper = T x_modal (block diagonal)."""
    m = len(omega)
    phi, C, T = np.zeros((2 * m, 2 * m)), np.zeros((1, 2 * m)), np.zeros((2 * m, 2 * m))
    for i, (w, z, W) in enumerate(zip(omega, zeta, tip_shape, strict=True)):
        blk = slice(2 * i, 2 * i + 2)
        phi_p = _paper_transition(w, z, dt)
        c_p = np.array([-W * w * w, -2.0 * W * z * w])
        phi_m = np.reshape(_modal_transition(w, z, dt, np), (2, 2))
        # same observability matrix [C; Cφ] in both coordinates: O_p T = O_m
        T[blk, blk] = np.linalg.solve(np.vstack([c_p, c_p @ phi_p]), np.array([[1.0, 0.0], phi_m[0]]))
        phi[blk, blk], C[0, blk] = phi_p, c_p
    return phi, C, T


def kalman_gain(omega, zeta, dt: float, tip_shape, qd: float, rd: float) -> np.ndarray:
    """Steady-state predictor gain K of the innovation form, eq. (31), in modal acceleration coordinates.

    In the paper's coordinates P solves the discrete algebraic Riccati equation
    P = φPφᵀ − φPCᵀ(CPCᵀ + Rd)⁻¹CPφᵀ + Qd·I (eqs. 14–17 at steady state, Γ = I as in eq. 8) and
    K_paper = φPCᵀ(CPCᵀ + Rd)⁻¹ is the gain on the innovation in x(k+1) = φx(k) + Ke(k); here K = T⁻¹K_paper.
    (The paper used MATLAB's LQE with Qd = 0.001, Rd = 0.4, §4.3.)
    """
    phi, C, T = paper_state_space(omega, zeta, dt, tip_shape)
    n = phi.shape[0]
    P = scipy.linalg.solve_discrete_are(phi.T, C.T, qd * np.eye(n), np.array([[rd]]))
    k_paper = phi @ P @ C.T / (C @ P @ C.T + rd)
    return np.linalg.solve(T, k_paper).ravel()


_BLOCK = 512


@functools.lru_cache(maxsize=64)
def _power_grid(n: int) -> tuple[np.ndarray, int]:
    """(r, then jB, of k = jB + r for k < n) in one read-only column, and the number of r: B = ``_BLOCK``
    above 2·``_BLOCK`` samples, ⌈√n⌉ below (made once per n)."""
    block = _BLOCK if n > 2 * _BLOCK else math.isqrt(max(n - 1, 0)) + 1
    grid = np.concatenate([np.arange(block, dtype=float), np.arange(-(-n // block), dtype=float) * block])
    grid.flags.writeable = False
    return grid, block


def _powers(logp: np.ndarray, n: int) -> np.ndarray:
    """e^{k·logpᵢ} for k < n, shape (n, m) (logp = sΔt): as e^{jB·logp}·e^{r·logp} (k = jB + r), one
    complex product per entry instead of one complex exponential (which dominated the closed form's cost on
    long records, and was 40 % of a 256-sample fit's basis: 2√n exponentials per mode here); each factor is
    exact to rounding, so the product is too (a few ulp from e^{k·logp} itself, whose argument k·logp is
    rounded alike)."""
    grid, block = _power_grid(n)
    # e^{r·logp} (r < B) and e^{jB·logp} in one product and one exp (each entry its own: the same values)
    powers = np.exp(np.multiply.outer(grid, logp))
    head, steps = powers[:block], powers[block:]
    return (steps[:, None, :] * head).reshape(-1, logp.size)[:n]


def modal_basis(w: np.ndarray, z: np.ndarray, dt: float, n: int) -> np.ndarray:
    """Φ (n × 2m + 1) with ŷ = Φ·(x₀, b): columns e^{−σᵢt} cos ω_dᵢt, e^{−σᵢt} sin ω_dᵢt (i = 1…m), then 1."""
    m = w.size
    zl = z.tolist()
    if all(abs(zi) < 1.0 for zi in zl):
        # sΔt over m Python floats: the same IEEE operations as the array expression below (bit-identical),
        # a fifth of its calls (the reference search builds a basis at every trial point)
        logp = np.array([complex(-zi * wi * dt, wi * math.sqrt(1.0 - zi * zi) * dt)
                         for wi, zi in zip(w.tolist(), zl, strict=True)])
    else:
        logp = (-z * w + 1j * (w * np.sqrt(1.0 - z * z))) * dt
    rot = _powers(logp, n)
    phi = np.empty((n, 2 * m + 1))
    phi[:, 0:2 * m:2] = rot.real
    phi[:, 1:2 * m:2] = rot.imag
    phi[:, 2 * m] = 1.0
    return phi


def symmetric_eigh(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``numpy.linalg.eigh(A)`` of a real symmetric matrix through numpy's own LAPACK kernel (``eigh_lo``,
    the one ``eigh`` calls) without the wrapper's type checks and error-state context: the same values to
    the bit, a third less time on the searches' 8 × 8 to 17 × 17 matrices (measured 15 → 10 µs; a short
    record's search makes thousands of these calls). Where the kernel did not converge (NaN out), the
    wrapper itself runs and raises as before."""
    if _umath_linalg is None:
        return np.linalg.eigh(A)
    lam, V = _umath_linalg.eigh_lo(A, signature="d->dd")
    if not math.isfinite(lam.sum()):
        return np.linalg.eigh(A)
    return lam, V


def scaled_lstsq(F: np.ndarray, target: np.ndarray):
    """c minimising |target − F c| through the normal equations of the column-scaled F and their
    eigendecomposition (a p × p problem: far cheaper than an SVD of N × p), and the pieces that apply
    (FᵀF)⁻¹ again: (c, (norms, eigenvalues, eigenvectors)). None where FᵀF is not finite or its scaled
    condition number exceeds 1e12 (the caller takes the SVD route)."""
    H = F.T @ F
    norms = np.sqrt(H.diagonal())
    if not (norms.min() > 0 and np.isfinite(H).all()):
        return None
    lam, V = symmetric_eigh(H / np.multiply.outer(norms, norms))      # np.outer's values, less wrapper
    if not lam[0] > 1e-12 * lam[-1]:
        return None
    return (V @ ((V.T @ (F.T @ target / norms)) / lam)) / norms, (norms, lam, V)


class ClosedForm:
    """The output-error predictor (K = 0) in closed form, with its exact Jacobian: no recursion at all.

    With K = 0 the predictor output is the sum of damped sinusoids of the module docstring,

        ŷ(k) = Σᵢ e^{−σᵢt}(Aᵢ cos ω_dᵢt + Bᵢ sin ω_dᵢt) + b,   t = kΔt,   ε = y − ŷ,

    so ε and every column of ∂ε/∂θ are elementwise expressions in t (O(N·m), nothing to unroll, nothing
    compiled): with gᵢ = e^{−σᵢt}(Aᵢ cos + Bᵢ sin) and hᵢ = e^{−σᵢt}(Bᵢ cos − Aᵢ sin) (the derivative with
    respect to the phase), ∂ŷ/∂σᵢ = −t gᵢ, ∂ŷ/∂ω_dᵢ = t hᵢ, and by the chain rule

        ∂ŷ/∂ωᵢ = −ζᵢ t gᵢ + √(1 − ζᵢ²) t hᵢ,    ∂ŷ/∂ζᵢ = −ωᵢ t gᵢ − ωᵢζᵢ/√(1 − ζᵢ²) t hᵢ,

    ∂ŷ/∂Aᵢ = e^{−σᵢt} cos ω_dᵢt, ∂ŷ/∂Bᵢ = e^{−σᵢt} sin ω_dᵢt, ∂ŷ/∂b = 1. This replaces the CasADi graph
    unrolled per record length (cold first call 0.3–2.8 s at N = 256, 1.9 s and 118 MB at N = 2048, no
    finish at 10⁶): here a first call costs what a later one does and time and memory grow as N.
    It equals the recursion (:class:`Recursive` with K = 0) to rounding (test), and is more accurate for
    long records (no accumulation of the rotation's rounding over N steps).
    """

    def __init__(self, y: np.ndarray, dt: float, n_modes: int, free: tuple[bool, ...]):
        m = n_modes
        if len(free) != n_params(m):
            raise ValueError(f"free mask has {len(free)} entries, expected {n_params(m)}")
        self.y = np.ascontiguousarray(y, dtype=float)
        self.t = np.arange(self.y.size) * float(dt)
        self.dt = float(dt)
        self.m = m
        self.free_idx = np.flatnonzero(free)
        lin = self.free_idx[self.free_idx >= 2 * m]
        self.n_linear = lin.size
        self._lin_cols = lin - 2 * m                 # columns of the basis [A₁, B₁, …, b] that are free
        self._all_linear_free = lin.size == 2 * m + 1
        free_idx = self.free_idx
        self._n_w, self._n_z = int(np.count_nonzero(free_idx < m)), int(np.count_nonzero(free_idx < 2 * m))
        # the Jacobian's column selections, made once (every (ω, ζ) free — the default — is a plain slice)
        self._w_cols = free_idx[:self._n_w]
        self._z_cols = free_idx[self._n_w:self._n_z] - m
        self._c_cols = free_idx[self._n_z:] - 2 * m
        self._every_w_z = self._n_w == m and self._n_z == 2 * m
        self._key = None

    def basis(self, theta: np.ndarray) -> np.ndarray:
        """Φ with ŷ = Φ·(x₀, b): columns e^{−σᵢt} cos ω_dᵢt, e^{−σᵢt} sin ω_dᵢt (i = 1…m), then 1."""
        m = self.m
        key = theta[:2 * m].tobytes()
        if key != self._key:                        # the search asks twice at an accepted point
            self._key, self._phi = key, modal_basis(theta[:m], theta[m:2 * m], self.dt, self.t.size)
        return self._phi

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return self.y - self.basis(theta) @ theta[2 * self.m:]

    def project(self, theta: np.ndarray):
        """θ with its free linear unknowns (x₀, b) at their least-squares values for θ's (ω, ζ), its ε and
        loss — :func:`methods.pem.search.solve_linear` for this predictor, in a few array operations (the
        search calls it at every trial point): the normal equations of the column-scaled basis, solved
        through their eigendecomposition. None where they are near-singular (scaled condition number above
        1e12): the caller then takes the SVD route."""
        m = self.m
        phi = self.basis(theta)
        if self._all_linear_free:                   # nothing held fixed (the default): no target to shift
            target, F = self.y, phi
        else:
            fixed = theta[2 * m:].copy()
            fixed[self._lin_cols] = 0.0
            target = self.y - phi @ fixed if fixed.any() else self.y
            F = phi[:, self._lin_cols]
        solved = scaled_lstsq(F, target)
        if solved is None:
            return None
        c = solved[0]
        out = theta.copy()
        out[2 * m:][self._lin_cols] = c
        e = target - F @ c
        self._e_key, self._e = out.tobytes(), e
        return out, e, float(e @ e / e.size)

    def linear_part(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ε(θ) and G = ∂ε/∂c_free = −Φ[:, free linear columns] (ε is affine in x₀ and b)."""
        return self.residual(theta), -self.basis(theta)[:, self._lin_cols]

    def residual_jacobian(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ε(θ) and the exact ∂ε/∂θ_free, shape (N, p_free), free columns in θ order."""
        m = self.m
        w, z = theta[:m], theta[m:2 * m]
        phi = self.basis(theta)
        ec, es = phi[:, 0:2 * m:2], phi[:, 1:2 * m:2]
        a, b = theta[2 * m:4 * m:2], theta[2 * m + 1:4 * m:2]
        tg = (ec * a + es * b) * self.t[:, None]
        th = (ec * b - es * a) * self.t[:, None]
        root = np.sqrt(1.0 - z * z)
        n_w, n_z = self._n_w, self._n_z
        J = np.empty((self.t.size, self.free_idx.size))
        if self._every_w_z:                         # the same values, written in place without a gather
            np.subtract(z * tg, root * th, out=J[:, :m])                                 # −∂ŷ/∂ω
            np.add(w * tg, (w * z / root) * th, out=J[:, m:2 * m])                     # −∂ŷ/∂ζ
        else:
            J[:, :n_w] = (z * tg - root * th)[:, self._w_cols]
            J[:, n_w:n_z] = (w * tg + (w * z / root) * th)[:, self._z_cols]
        cols = self._c_cols
        np.negative(phi if cols.size == phi.shape[1] else phi[:, cols], out=J[:, n_z:])   # −∂ŷ/∂(x₀, b)
        e = self._e if getattr(self, "_e_key", None) == theta.tobytes() else self.y - phi @ theta[2 * m:]
        return e, J


@functools.lru_cache(maxsize=32)
def _step_function(n_modes: int, with_gain: bool, columns: tuple[int, ...]):
    """One step of the predictor and of its forward sensitivities S = ∂x̂/∂θ_columns, a graph of fixed size:

        (x̂(k), S(k), y(k), θ, K, Δt) ↦ (x̂(k+1), S(k+1), ε(k), ∂ε(k)/∂θ_columns),
        S(k+1) = (∂x̂(k+1)/∂x̂(k)) S(k) + ∂x̂(k+1)/∂θ,   ∂ε(k)/∂θ = −C S(k) − ∂b/∂θ.

    Differentiating one step symbolically (SX) and repeating it with ``mapaccum`` costs the same for every
    N; differentiating the repeated map instead (MX) took 2 s to build and 160 ms to evaluate at N = 256."""
    import casadi as ca  # 0.2 s of start-up, paid only by the CasADi predictor, not the fast path

    m = n_modes
    p = len(columns)
    x = ca.SX.sym("x", 2 * m)
    S = ca.SX.sym("S", 2 * m, p)
    yk = ca.SX.sym("yk")
    theta = ca.SX.sym("theta", n_params(m))
    K = ca.SX.sym("K", 2 * m)
    dt = ca.SX.sym("dt")
    w, z, b = theta[:m], theta[m:2 * m], theta[4 * m]
    e_k = yk - b - sum(x[2 * i] for i in range(m))               # Cᵢ = [1 0]
    nxt = []
    for i in range(m):
        p11, p12, p21, p22 = _modal_transition(w[i], z[i], dt, ca)
        q, v = x[2 * i], x[2 * i + 1]
        nxt += [p11 * q + p12 * v, p21 * q + p22 * v]
    nxt = ca.vertcat(*nxt)
    if with_gain:
        nxt = nxt + K * e_k
    th_cols = ca.vertcat(*[theta[j] for j in columns]) if p else ca.SX(0, 1)
    de = ca.jacobian(e_k, x) @ S + (ca.jacobian(e_k, th_cols) if p else ca.SX(1, 0))
    S_next = ca.jacobian(nxt, x) @ S + (ca.jacobian(nxt, th_cols) if p else ca.SX(2 * m, 0))
    return ca.Function("pem_step", [ca.vertcat(x, ca.vec(S)), yk, theta, K, dt],
                       [ca.vertcat(nxt, ca.vec(S_next)), e_k, ca.densify(de.T)])


@functools.lru_cache(maxsize=32)
def predictor(n_samples: int, n_modes: int, free: tuple[bool, ...], with_gain: bool):
    """Cached CasADi functions for one shape, all (θ, y, K, dt) ↦ …, exact (algorithmic) derivatives.

    The recursion is :func:`_step_function` repeated N times with ``Function.mapaccum`` (state x̂ and its
    sensitivities carried along): the graph has a fixed size whatever N is (the unrolled SX graph this
    replaces grew with N: 1.9 s to build at N = 2048), so a new record length costs milliseconds.

    Returns
    -------
    residual : casadi.Function
        ↦ ε, shape (N, 1).
    residual_and_jacobian : casadi.Function
        ↦ (ε, ∂ε/∂θ_free), shapes (N, 1) and (N, p_free), free columns in θ order.
    linear_part : casadi.Function
        ↦ (ε, ∂ε/∂c_free) with c = (x₀, b) the unknowns that enter ε affinely; columns in θ order.
    """
    import casadi as ca  # 0.2 s of start-up, paid only by the CasADi predictor, not the fast path

    m = n_modes
    if len(free) != n_params(m):
        raise ValueError(f"free mask has {len(free)} entries, expected {n_params(m)}")
    theta = ca.MX.sym("theta", n_params(m))
    y = ca.MX.sym("y", n_samples)
    K = ca.MX.sym("K", 2 * m)
    dt = ca.MX.sym("dt")
    args = [theta, y, K, dt]
    names = ["theta", "y", "K", "dt"]

    def errors_and_jacobian(columns):
        run = _step_function(m, with_gain, tuple(columns)).mapaccum("pem_run", n_samples)
        S0 = np.zeros((2 * m, len(columns)))              # x̂(0) = x₀: ∂x̂(0)/∂x₀ⱼ = eⱼ
        for k, j in enumerate(columns):
            if 2 * m <= j < 4 * m:
                S0[j - 2 * m, k] = 1.0
        _, eps, de = run(ca.vertcat(theta[2 * m:4 * m], ca.DM(S0.ravel(order="F"))), y.T, theta, K, dt)
        return eps.T, de.T

    free_idx = [j for j in range(n_params(m)) if free[j]]
    eps, jac = errors_and_jacobian(free_idx)
    _, jac_c = errors_and_jacobian([j for j in free_idx if j >= 2 * m])
    return (ca.Function("pem_residual", args, [eps], names, ["eps"]),
            ca.Function("pem_residual_jacobian", args, [eps, jac], names, ["eps", "jac"]),
            ca.Function("pem_linear_part", args, [eps, jac_c], names, ["eps", "jac_c"]))


class Recursive:
    """The predictor run as a recursion (CasADi, any K): zero-copy evaluation of the cached functions.

    CasADi's buffer interface reads the arguments from, and writes the results into, numpy arrays owned
    here (a plain call converts every argument and result, which costs more than the evaluation itself at
    N = 256). An Evaluator belongs to one :func:`methods.pem.identify` call; it is not shared.
    """

    def __init__(self, n_samples: int, n_modes: int, free: tuple[bool, ...], with_gain: bool,
                 y: np.ndarray, K: np.ndarray, dt: float):
        residual, residual_jacobian, linear_part = predictor(n_samples, n_modes, free, with_gain)
        self.n_linear = int(sum(free[2 * n_modes:]))
        self._theta = np.zeros(n_params(n_modes))
        self._args = [self._theta, np.ascontiguousarray(y, dtype=float),
                      np.ascontiguousarray(K, dtype=float), np.array([float(dt)])]
        self.y = self._args[1]
        self._e = np.empty(n_samples)
        self._jt = np.empty((int(sum(free)), n_samples))      # column-major N × p_free, as CasADi writes it
        self._gt = np.empty((self.n_linear, n_samples))
        self._res = self._bind(residual, [self._e])
        self._res_jac = self._bind(residual_jacobian, [self._e, self._jt])
        self._lin = self._bind(linear_part, [self._e, self._gt])

    def _bind(self, fun, outputs):
        buf, trigger = fun.buffer()
        for i, a in enumerate(self._args):
            buf.set_arg(i, memoryview(a))
        for j, a in enumerate(outputs):
            buf.set_res(j, memoryview(a))
        return buf, trigger          # keep buf alive with the trigger

    def residual(self, theta: np.ndarray) -> np.ndarray:
        """Prediction errors ε(θ), shape (N,)."""
        self._theta[:] = theta
        self._res[1]()
        return self._e.copy()

    def residual_jacobian(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ε(θ) and the exact ∂ε/∂θ_free, shape (N, p_free)."""
        self._theta[:] = theta
        self._res_jac[1]()
        return self._e.copy(), self._jt.T.copy()

    def linear_part(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ε(θ) and G = ∂ε/∂c_free (independent of c: ε is affine in x₀ and b), shape (N, n_linear)."""
        self._theta[:] = theta
        self._lin[1]()
        return self._e.copy(), self._gt.T.copy()


def make_evaluator(y: np.ndarray, dt: float, n_modes: int, free: tuple[bool, ...], K: np.ndarray | None):
    """The evaluator for one record: closed form without a gain (output error), the recursion with one."""
    if K is None:
        return ClosedForm(y, dt, n_modes, free)
    return Recursive(y.size, n_modes, free, True, y, K, dt)


Evaluator = Recursive      # the name the search used before the closed form existed
