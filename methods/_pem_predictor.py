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

The recursion is unrolled symbolically (CasADi SX) and differentiated exactly, once per shape; the
``casadi.Function`` objects are cached per (N, m, free mask, with/without gain) — a pure-function cache.
φ is exact (no Euler step), so a noise-free sum of damped sinusoids is reproduced to rounding.
"""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import scipy.linalg


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


def _predictor_graph(n_samples: int, n_modes: int, with_gain: bool):
    """Symbols and the unrolled prediction errors ε(θ) (SX)."""
    m = n_modes
    theta = ca.SX.sym("theta", n_params(m))
    y = ca.SX.sym("y", n_samples)
    K = ca.SX.sym("K", 2 * m)
    dt = ca.SX.sym("dt")
    w, z = theta[:m], theta[m:2 * m]
    b = theta[4 * m]
    phi = [_modal_transition(w[i], z[i], dt, ca) for i in range(m)]
    x = [theta[2 * m + j] for j in range(2 * m)]
    eps = []
    for k in range(n_samples):
        e_k = y[k] - b
        for i in range(m):
            e_k = e_k - x[2 * i]                       # Cᵢ = [1 0]
        eps.append(e_k)
        nxt = []
        for i in range(m):
            q, v = x[2 * i], x[2 * i + 1]
            p11, p12, p21, p22 = phi[i]
            nxt += [p11 * q + p12 * v, p21 * q + p22 * v]
        if with_gain:
            nxt = [nxt[j] + K[j] * e_k for j in range(2 * m)]
        x = nxt
    return theta, y, K, dt, ca.vertcat(*eps)


@functools.lru_cache(maxsize=32)
def predictor(n_samples: int, n_modes: int, free: tuple[bool, ...], with_gain: bool):
    """Cached CasADi functions for one shape, all (θ, y, K, dt) ↦ …, exact (algorithmic) derivatives.

    Returns
    -------
    residual : casadi.Function
        ↦ ε, shape (N, 1).
    residual_and_jacobian : casadi.Function
        ↦ (ε, ∂ε/∂θ_free), shapes (N, 1) and (N, p_free), free columns in θ order.
    linear_part : casadi.Function
        ↦ (ε, ∂ε/∂c_free) with c = (x₀, b) the unknowns that enter ε affinely; columns in θ order.
    """
    if len(free) != n_params(n_modes):
        raise ValueError(f"free mask has {len(free)} entries, expected {n_params(n_modes)}")
    theta, y, K, dt, eps = _predictor_graph(n_samples, n_modes, with_gain)
    free_idx = [j for j in range(theta.numel()) if free[j]]
    theta_free = ca.vertcat(*[theta[j] for j in free_idx])
    c_free = ca.vertcat(*[theta[j] for j in free_idx if j >= 2 * n_modes])
    args = [theta, y, K, dt]
    names = ["theta", "y", "K", "dt"]
    # dense outputs: the buffer interface writes the structural nonzeros only
    jac = ca.densify(ca.jacobian(eps, theta_free))
    jac_c = ca.densify(ca.jacobian(eps, c_free))
    return (ca.Function("pem_residual", args, [eps], names, ["eps"]),
            ca.Function("pem_residual_jacobian", args, [eps, jac], names, ["eps", "jac"]),
            ca.Function("pem_linear_part", args, [eps, jac_c], names, ["eps", "jac_c"]))


class Evaluator:
    """Zero-copy evaluation of the cached predictor functions for one record.

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
