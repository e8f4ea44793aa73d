"""The tracking yardstick that does not know the force: the posterior Cramér–Rao bound of a random-walk
frequency model whose oscillators are driven by an unknown white force of known intensity.

Beside the **genie** bound of ``experiments.simulate.pcrb`` (``cell_pcrb``: every input known, the oscillators
without process noise), which under a white force is far below anything attainable: a tracker that knew the
force would read the frequency off the ratio of response to force. This is the **unknown-force** bound.

**The model.** The augmented state z = [ξ₁, ξ̇₁, …, ξₘ, ξ̇ₘ, ω₁…ωₘ, (ζ₁…ζₘ)] (as in ``pcrb``); a white force
f_k of known variance σ_f² per sample, held over the sample (the simulator's zero-order hold), acts on
input j (``force_body_y`` or ``force_tip``) with modal gains bᵢ = φᵢ·gⱼ and direct term D = c M⁻¹ gⱼ:

    [ξᵢ; ξ̇ᵢ]_{k+1} = Φ(ωᵢ,ζᵢ)[ξᵢ; ξ̇ᵢ]_k + Γ(ωᵢ,ζᵢ) bᵢ (u_k + f_k),   ω_{k+1} = ω_k + w_k,   ζ constant,
    y_k = Σᵢ cᵢ(−ωᵢ² ξᵢ − 2ζᵢωᵢ ξ̇ᵢ) + D (u_k + f_k) + e_k,

with u_k the known inputs (the thruster pulses: known to this bound too), w_k ~ N(0, diag q_k) the random walk
matched to the schedule step by step (``pcrb.matched_walk_q``: q_k = (ω(t_{k+1}) − ω(t_k))²) and
e_k ~ N(0, σ²). The process noise is
v_k = g_k f_k, g_k = [Γ(ωᵢ,ζᵢ)[:, 1] bᵢ]ᵢ stacked (rank one: one force drives every mode), so
Q_k = σ_f² g_k g_kᵀ on the oscillator block; the force also enters y_k, so the measurement noise
D f_k + e_k has variance R = σ² + D²σ_f² and is correlated with v_k: S_k = E[v_k(Df_k + e_k)] = σ_f² D g_k.

**The recursion.** Tichavský, Muravchik & Nehorai (IEEE TSP 46(5), 1998), J_{k+1} = D22 − D21(J_k + D11)⁻¹D12,
with the Jacobians F̃_k = ∇f, H̃_k = ∇h evaluated along the true trajectory (the true states and the true
force: ∂Γ/∂ω·f_k enters F̃ as ∂Γ/∂ω·u_k does in the genie), in the covariance form that accepts the singular
Q (``pcrb.pcrb_covariance``): the correlated noise is removed by writing the transition given y_k,
F̃ ← F̃ − S_k H̃_k/R, Q_k ← Q_k − S_kS_kᵀ/R (there).

**What it is checked against** (tests/experiments/simulate/test_pcrb_force.py): one mode at a constant
frequency, stationary white-force response, no random walk. The information the bound accumulates equals the
exact Fisher information of ω (and ζ) from N samples, I = ½ tr(C⁻¹∂C C⁻¹∂C) with C the covariance of the
whole record, and at large N Whittle's N/(4π)∫(∂log S/∂θ)(∂log S/∂θ')dλ of the sampled acceleration spectrum.
Along the true trajectory the expected information is (1/2π)∫σ_f²|∂G/∂θ|²/S dλ per sample (G the transfer
function from force to acceleration, S = σ_f²|G|² + σ² the spectrum) while Whittle's is
(1/4π)∫(∂log S/∂θ)²dλ: the two are equal when σ → 0 (G minimum phase: ∂log G/∂θ has equal real and
imaginary energy), and with measurement noise the trajectory's is the larger (a looser bound). On the
paper's plant under the grid's 5 N body force they differ by 0.2–1.3 % at 100–1000 µg and by 4–11 % at
10 mg (docs/tracking.md §2).
"""

from __future__ import annotations

import numpy as np

from experiments.simulate.pcrb import RW_FLOOR_REL, jacobians, matched_walk_q, pcrb_covariance, prior_covariance
from experiments.simulate.timevarying import INPUTS, ModalModel, oscillator_transition

__all__ = ["force_noise", "unknown_force_pcrb"]


def force_noise(model: ModalModel, w, dt_s: float, force_std_n: float, force_input: str = "force_body_y", *,
                damping: bool = True) -> tuple[np.ndarray, np.ndarray, float]:
    """The unknown white force as noise of the bound's model (module docstring).

    Parameters
    ----------
    w : ndarray, shape (N, m)
        The true frequencies per sample (Γ depends on them).
    force_std_n : float
        σ_f, the force's 1σ per sample (N; N·m for ``torque_z``).
    force_input : str
        Which of ``timevarying.INPUTS`` it acts on.

    Returns
    -------
    Q : ndarray, shape (N, d, d)
        σ_f² g_k g_kᵀ, the process noise that drives z_k → z_{k+1}.
    S : ndarray, shape (N, d)
        σ_f² D g_k, its covariance with the measurement noise of sample k.
    direct_var : float
        D²σ_f², the force's share of the measurement noise.
    """
    if force_input not in INPUTS:
        raise ValueError(f"force_input = {force_input!r} must be one of {', '.join(INPUTS)}")
    if not (np.isfinite(force_std_n) and force_std_n >= 0):
        raise ValueError(f"force_std_n = {force_std_n} must be a finite number ≥ 0")
    w = np.asarray(w, dtype=float)
    n, m = w.shape
    d = (4 if damping else 3) * m
    j = INPUTS.index(force_input)
    _, gamma = oscillator_transition(w, model.damping[None, :], dt_s)            # (N, m, 2, 2)
    g = np.zeros((n, d))
    g[:, : 2 * m] = (gamma[..., 1] * model.input_gain[None, :, j, None]).reshape(n, 2 * m)
    var = float(force_std_n) ** 2
    direct = float(model.feedthrough[j])
    return var * g[:, :, None] * g[:, None, :], var * direct * g, direct**2 * var


def unknown_force_pcrb(model: ModalModel, w, x, dt_s: float, noise_std: float, prior, *, force_std_n: float,
                       force_input: str = "force_body_y", u=None, rw_q=None,
                       prior_rel_std: float | None = None, damping: bool = True, P0=None,
                       rate_std=None) -> np.ndarray:
    """The **unknown-force** PCRB std (rad/s) of every frequency at every sample, per replicate.

    The white force on ``force_input`` (1σ ``force_std_n`` per sample) is unknown to the bound and enters as
    process noise on the oscillators (and, through the direct term, as correlated measurement noise); the
    other inputs in ``u`` (thruster pulses) are known to it. The frequencies walk with per-sample variance
    ``rw_q`` (default ``pcrb.matched_walk_q(w)``: matched to the schedule step by step, as the genie's); ζ is
    an unknown constant with ``damping``. Module docstring for the model and the recursion.

    Parameters
    ----------
    model : ModalModel
    w : ndarray, shape (N, m)
        The true frequencies (rad/s) per sample.
    x : ndarray, shape (R, N, m, 2)
        The true modal states of every replicate.
    dt_s : float
    noise_std : float
        σ of the accelerometer's white noise (m/s²).
    prior : ndarray, shape (R, m) or (m,)
        The prior frequencies the trackers get (they set the bound's prior spread, ``pcrb.prior_covariance``).
    force_std_n : float
        σ_f (N per sample). 0 gives the genie bound (``pcrb.cell_pcrb``) with this walk.
    u : ndarray, shape (R, N, len(INPUTS)), optional
        The true inputs, the white force included: the Jacobians are taken along the true trajectory.
    rw_q : ndarray, shape (m,) or (N, m), optional
        The walk's per-sample variance (rad²/s²), constant or per sample, instead of the schedule's.
    P0 : ndarray, shape (d, d), optional
        The prior covariance of z_0 instead of ``pcrb.prior_covariance`` (e.g. the oscillators' stationary one).
    rate_std : array_like, shape (m,) or scalar, optional
        The **unknown-rate** bound: each frequency is a line, ω_{k+1} = ω_k + Δt ω̇, its rate ω̇ an unknown
        constant with prior N(0, rate_std²) (rad/s per s), appended to the state; the default walk is then
        the floor alone, (RW_FLOOR_REL·ω)²/N per sample (the line moves the frequency, not a walk). The
        schedule's walk knows the size of a drift's every step, not its direction; where the record informs
        slowly (a white force) it acts as the bound of a tracker told the rate, and this one, of a tracker
        that is not, is about twice it (a line's end point: about twice a constant's std from the same
        samples); where the record informs fast (known pulses) the walk's own spread dominates and this one is
        the lower. Meaningful where the truth is a line (drifts, a constant); ``P0``, if given, covers the
        appended rates too.

    Returns
    -------
    ndarray, shape (R, N, m)
    """
    w = np.asarray(w, dtype=float)
    x = np.asarray(x, dtype=float)
    m = x.shape[2]
    if rate_std is not None:
        rate_std = np.broadcast_to(np.asarray(rate_std, dtype=float), (m,))
        if not np.all(np.isfinite(rate_std) & (rate_std > 0)):
            raise ValueError(f"rate_std = {rate_std.tolist()} must be finite numbers > 0 (rad/s per s)")
    F, H = jacobians(model, w, x, dt_s, u, damping=damping)
    d = F.shape[-1]
    Qf, S, direct_var = force_noise(model, w, dt_s, force_std_n, force_input, damping=damping)
    if rw_q is None:
        rw_q = matched_walk_q(w) if rate_std is None else (RW_FLOOR_REL * w[0]) ** 2 / w.shape[0]
    q = np.broadcast_to(rw_q, w.shape)
    Qf[:, np.arange(2 * m, 3 * m), np.arange(2 * m, 3 * m)] += q
    if P0 is None:
        p0 = prior_covariance(model, w, x, prior, prior_rel_std=prior_rel_std, damping=damping)
        if rate_std is not None:
            p0 = np.concatenate([p0, rate_std**2])
        P0 = np.diag(p0)
    if rate_std is not None:       # the rates: d + m states, ω_{k+1} = ω_k + Δt ω̇, ω̇ constant
        F, H, Qf, S = _with_rates(F, H, Qf, S, m, dt_s)
        d += m
    if np.shape(P0) != (d, d):
        raise ValueError(f"P0 has shape {np.shape(P0)}; the bound's state has {d} entries")
    var = pcrb_covariance(F, H, Qf, noise_std**2 + direct_var, P0, cross=S if direct_var > 0 else None)
    return np.sqrt(np.maximum(var[:, :, 2 * m: 3 * m], 0.0))


def _with_rates(F, H, Q, S, m: int, dt_s: float):
    """The model with m rate states appended (ω_{k+1} = ω_k + Δt ω̇, ω̇ constant, no noise)."""
    r, n, d, _ = F.shape
    Fr = np.zeros((r, n, d + m, d + m))
    Fr[:, :, :d, :d] = F
    Fr[:, :, np.arange(2 * m, 3 * m), np.arange(d, d + m)] = dt_s
    Fr[:, :, np.arange(d, d + m), np.arange(d, d + m)] = 1.0
    Hr = np.concatenate([H, np.zeros((r, n, m))], axis=-1)
    Qr = np.zeros((n, d + m, d + m))
    Qr[:, :d, :d] = Q
    return Fr, Hr, Qr, np.concatenate([S, np.zeros((n, m))], axis=-1)
