"""Exact simulation of the spacecraft whose modal frequencies follow a schedule, under continuing excitation.

**The model.** The 20-state plant (``experiments.simulate.plant``) in its flexible modal coordinates: with
Φ the mass-normalised undamped mode shapes (ΦᵀMΦ = I, ``scipy.linalg.eigh(K, M)``), each flexible mode
i is an oscillator

    ξ̈ᵢ + 2ζᵢωᵢ(t) ξ̇ᵢ + ωᵢ(t)² ξᵢ = Σⱼ (φᵢ·gⱼ) uⱼ(t),

and the tip accelerometer reads  y = Σᵢ (c·φᵢ) ξ̈ᵢ + Σⱼ (c M⁻¹ gⱼ) uⱼ  (the rigid-body modes carry no
stiffness: they add only the direct term; c is the tip row of PHYSICS.md §2). Inputs gⱼ in the
coordinates η: ``torque_z``, an attitude-thruster torque about z on the body (N·m, gⱼ = e_θz);
``force_tip``, a force on the tip along y (N, gⱼ = c); ``force_body_y``, a force on the body's centre along
y (N, gⱼ = e_Y). ωᵢ(t) is the schedule
(``experiments.simulate.schedules``); ζᵢ and the gains are the nominal plant's.

**Exactly how it is discretised.** Over each sample interval [t_k, t_{k+1}) the frozen system holds:
ωᵢ = ωᵢ(t_k) and the inputs are zero-order held at u_k (a thruster pulse is a force held for whole samples).
Then x_{k+1} = e^{A_k Δt} x_k + A_k⁻¹(e^{A_k Δt} − I) B u_k exactly (:func:`oscillator_transition`), and
y_k = C_k x_k + D u_k. The truth stored with a record is ωᵢ(t_k) per sample: the eigenfrequency |λ| of the
frozen system that produced sample k.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from experiments.simulate.plant import N_RIGID, Plant

__all__ = ["INPUTS", "ModalModel", "modal_model", "oscillator_transition", "simulate"]

INPUTS = ("torque_z", "force_tip", "force_body_y")


@dataclass(frozen=True)
class ModalModel:
    """The flexible modes as the tip accelerometer sees them.

    Attributes
    ----------
    freq_rad_s, damping : ndarray, shape (m,)
        Nominal ωᵢ and ζᵢ (the plant's eigenvalues).
    tip_gain : ndarray, shape (m,)
        c·φᵢ: the tip acceleration per unit modal acceleration.
    input_gain : ndarray, shape (m, len(INPUTS))
        φᵢ·gⱼ: the modal force per unit input.
    feedthrough : ndarray, shape (len(INPUTS),)
        c M⁻¹ gⱼ: the tip acceleration per unit input, directly.
    xi0 : ndarray, shape (m,)
        Modal displacements of the plant's initial condition, ξ(0) = Φᵀ M η(0) (rates zero).
    """

    freq_rad_s: np.ndarray
    damping: np.ndarray
    tip_gain: np.ndarray
    input_gain: np.ndarray
    feedthrough: np.ndarray
    xi0: np.ndarray


def modal_model(plant: Plant) -> ModalModel:
    """The modal model of ``plant`` (mass-normalised undamped shapes, sorted by frequency)."""
    M, K = plant.M, plant.K
    n = M.shape[0]
    _, phi = scipy.linalg.eigh(K, M)                  # ascending: 6 rigid-body zeros, then the flexible ones
    phi = phi[:, N_RIGID:]
    m = phi.shape[1]
    if m != plant.freq_rad_s.size:
        raise ValueError(f"the plant has {m} flexible shapes but {plant.freq_rad_s.size} eigenfrequencies")
    c = plant.c_tip
    g = np.zeros((n, len(INPUTS)))
    g[2, 0] = 1.0                                     # torque about z on the body
    g[:, 1] = c                                       # force along y at the tip (virtual work: c·δη)
    g[4, 2] = 1.0                                     # force along y on the body's centre
    eta0 = plant.x0[:n]
    return ModalModel(freq_rad_s=plant.freq_rad_s.copy(), damping=plant.damping.copy(), tip_gain=c @ phi,
                      input_gain=phi.T @ g, feedthrough=c @ np.linalg.solve(M, g), xi0=phi.T @ M @ eta0)


def oscillator_transition(w, zeta, dt_s: float):
    """e^{AΔt} and A⁻¹(e^{AΔt} − I) of the oscillators A = [[0, 1], [−ω², −2ζω]], in closed form.

    With ω_d = ω√(1−ζ²), E = e^{−ζωΔt}, c = cos ω_dΔt, s = sin ω_dΔt:

        e^{AΔt} = E [[c + (ζω/ω_d) s,  s/ω_d], [−(ω²/ω_d) s,  c − (ζω/ω_d) s]].

    The ZOH input matrix is A⁻¹(e^{AΔt} − I) times the input column (A is invertible for ω > 0).
    Written out because a record has 10⁵ distinct (sample, mode) matrices: ``scipy.linalg.expm`` on a stack
    of 1.2·10⁵ took 6.7 s, this takes milliseconds; tests check it against ``scipy.linalg.expm``.

    Parameters
    ----------
    w, zeta : array_like, broadcastable
        ω (rad/s) and ζ (real, or complex for a complex-step derivative).

    Returns
    -------
    phi : ndarray, shape (..., 2, 2)
    gamma : ndarray, shape (..., 2, 2)
        A⁻¹(e^{AΔt} − I): its second column is the ZOH response to a unit modal force.
    """
    w, zeta = np.broadcast_arrays(np.asarray(w), np.asarray(zeta))
    dtype = np.result_type(w, zeta, float)      # complex in: the complex-step derivatives of the bound
    wd = w * np.sqrt(1.0 - zeta**2)
    e = np.exp(-zeta * w * dt_s)
    c, s = np.cos(wd * dt_s), np.sin(wd * dt_s)
    phi = np.empty(w.shape + (2, 2), dtype=dtype)
    phi[..., 0, 0] = e * (c + zeta * w / wd * s)
    phi[..., 0, 1] = e * s / wd
    phi[..., 1, 0] = -e * w**2 / wd * s
    phi[..., 1, 1] = e * (c - zeta * w / wd * s)
    # A⁻¹ = [[−2ζ/ω, −1/ω²], [1, 0]]
    a_inv = np.zeros_like(phi)
    a_inv[..., 0, 0] = -2.0 * zeta / w
    a_inv[..., 0, 1] = -1.0 / w**2
    a_inv[..., 1, 0] = 1.0
    gamma = a_inv @ (phi - np.eye(2))
    return phi, gamma


def simulate(model: ModalModel, w: np.ndarray, dt_s: float, u: np.ndarray | None = None,
             xi0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free tip acceleration of R records whose frequencies follow ``w``, and their modal states.

    x_{k+1} = Φ_k x_k + Γ_k u_k,  y_k = Σᵢ (c·φᵢ)(−ωᵢ,k² ξᵢ,k − 2ζᵢωᵢ,k ξ̇ᵢ,k) + D u_k  (module docstring).

    Parameters
    ----------
    model : ModalModel
    w : ndarray, shape (N, m)
        ωᵢ(t_k), rad/s.
    u : ndarray, shape (R, N, len(INPUTS)), optional
        The inputs, held over each sample (N·m, N). None: no input, one record.
    xi0 : ndarray, shape (m,), optional
        Initial modal displacements (default: none; the paper's release is ``model.xi0``).

    Returns
    -------
    y : ndarray, shape (R, N)
        m/s².
    x : ndarray, shape (R, N, m, 2)
        The modal states [ξᵢ, ξ̇ᵢ] at each sample (before that sample's input acts).
    """
    w = np.asarray(w, dtype=float)
    n, m = w.shape
    if u is None:
        u = np.zeros((1, n, len(INPUTS)))
    r = u.shape[0]
    phi, gamma = oscillator_transition(w, model.damping[None, :], dt_s)          # (N, m, 2, 2)
    force = np.einsum("mj,rnj->rnm", model.input_gain, u)                          # modal forces (R, N, m)
    drive = gamma[None, :, :, :, 1] * force[..., None]                             # (R, N, m, 2)
    x = np.empty((r, n, m, 2))
    state = np.zeros((r, m, 2))
    if xi0 is not None:
        state[:, :, 0] = xi0
    # a time-varying recursion: each step needs the previous state, so it is a loop (vectorised over records
    # and modes); no library propagates a time-varying discrete system
    for k in range(n):
        x[:, k] = state
        state = np.einsum("mab,rmb->rma", phi[k], state) + drive[:, k]
    zeta = model.damping
    modal_acc = -(w**2)[None] * x[..., 0] - 2.0 * (zeta * w)[None] * x[..., 1]
    y = modal_acc @ model.tip_gain + u @ model.feedthrough
    return y, x
