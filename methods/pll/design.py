"""Design of one phase-locked loop (paper §3.4, Fig. 2): loop time constants, input filter, discretisation.

The continuous loop is

    input filter A(s) → phase detector (input × VCO output) → low-pass 1/(1 + T_VCO s)      (eq. 36)
      → controller F(s) = K (1 + T₂ s) / (T₁ s (1 + T₃ s))                                   (eq. 37)
      → voltage-controlled oscillator: dθ/dt = ω₀ + v, the instantaneous frequency is the estimate.

With a phase detector of unit gain (output sin φₑ, φₑ the phase error) the open loop is
L(s) = K (1 + T₂ s) / (T₁ s² (1 + T₃ s)(1 + T_VCO s)), and the design rule under eq. (37) puts its
crossover at ω_L with phase margin φ when K = 1 and T_VCO is neglected.

Everything here is pure numerics (numpy, scipy.signal) and is used by :mod:`methods.pll`.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.signal

# Table 6 uses T_VCO ≈ 0.5/ω_L for every loop (ω_L·T_VCO = 0.48, 0.48, 0.48, 0.51); the paper states no rule
# for T_VCO. The "rule" design uses this ratio so that a loop can be set up from ω_L alone.
VCO_LOWPASS_TIMES_OMEGA_L = 0.5


def loop_time_constants(omega_l: float, phase_margin_deg: float = 45.0) -> tuple[float, float, float]:
    """Controller time constants T₁, T₂, T₃ (s) from the loop operating frequency — the rule under eq. (37).

    T₃ = (sec φ − tan φ)/ω_L,  T₂ = 1/(ω_L² T₃),  T₁ = 1/(ω_L² (sec φ − tan φ)).

    The lead–lag pair is centred on ω_L (T₂T₃ = 1/ω_L²) and gives it the phase lead φ; T₁ sets
    |L(jω_L)| = K for a unit-gain detector. The paper states an acquisition range ≈ 1.5 ω_L and an
    acquisition time ≈ 4π/ω_L for this choice.

    Parameters
    ----------
    omega_l : float
        Loop operating frequency ω_L in rad/s (> 0).
    phase_margin_deg : float
        Phase margin φ at ω_L in degrees, 0 < φ < 90 ("normally set to 45 degrees").

    Returns
    -------
    (T1, T2, T3) : tuple of float, seconds.
    """
    if not (np.isfinite(omega_l) and omega_l > 0):
        raise ValueError(f"loop operating frequency omega_L = {omega_l} rad/s must be positive")
    if not 0 < phase_margin_deg < 90:
        raise ValueError(f"phase margin {phase_margin_deg} deg must be between 0 and 90 degrees")
    phi = math.radians(phase_margin_deg)
    sec_minus_tan = 1.0 / math.cos(phi) - math.tan(phi)
    t3 = sec_minus_tan / omega_l
    t2 = 1.0 / (omega_l**2 * t3)
    t1 = 1.0 / (omega_l**2 * sec_minus_tan)
    return t1, t2, t3


def omega_l_from_time_constants(t1: float, t2: float, t3: float, phase_margin_deg: float = 45.0) -> dict:
    """Invert the rule under eq. (37): the ω_L that each of T₁, T₂T₃ and T₃ implies (rad/s).

    If a set of time constants follows the rule, the three values agree; used to check Table 6.
    """
    phi = math.radians(phase_margin_deg)
    smt = 1.0 / math.cos(phi) - math.tan(phi)
    return {"from_T1": math.sqrt(1.0 / (t1 * smt)), "from_T2T3": 1.0 / math.sqrt(t2 * t3),
            "from_T3": smt / t3}


@dataclass(frozen=True)
class LoopParameters:
    """One loop's continuous-time parameters (Table 6 columns)."""

    omega_l: float      # loop operating frequency ω_L, rad/s
    t_vco: float        # low-pass time constant T_VCO, s (eq. 36)
    t1: float           # controller time constants, s (eq. 37)
    t2: float
    t3: float
    gain: float         # loop gain K (eq. 37)

    @property
    def acquisition_time_s(self) -> float:
        """≈ 4π/ω_L (§3.4)."""
        return 4.0 * math.pi / self.omega_l


def rule_parameters(omega_l: float, gain: float = 1.0, phase_margin_deg: float = 45.0) -> LoopParameters:
    """A whole loop from ω_L alone: T₁–T₃ by the rule under eq. (37), T_VCO = 0.5/ω_L as Table 6 does."""
    t1, t2, t3 = loop_time_constants(omega_l, phase_margin_deg)
    return LoopParameters(omega_l, VCO_LOWPASS_TIMES_OMEGA_L / omega_l, t1, t2, t3, gain)


# --------------------------------------------------------------------------------------------------------
# Defaults derived from the prior (the per-loop options of methods/pll/_loop.py left at None)
# --------------------------------------------------------------------------------------------------------

# Table 6 has ω_L/ω₀ = 0.6/2.8, 4/16, 4/18, 11.3/52 = 0.214, 0.250, 0.222, 0.217.
OMEGA_L_PER_PRIOR = 0.22
# Table 6's largest ω_L·Δt is 0.226 (loop 4 at Δt = 0.02 s). The VCO's one-sample delay costs phase margin
# (rule loop, K = 1: 20.1° continuous, 14.0° at ω_LΔt = 0.226, 13.4° at 0.25, 9.3° at 0.4); cap at 0.25.
MAX_OMEGA_L_DT = 0.25
# Input filter: bandwidth 0.5 ω₀, a pass band of about ω₀ ± 25 % — §4.4's "at least 7–8 rad/s" for priors
# 16 and 18 rad/s that are 21–27 % below the truth (Table 6 itself: 5, 9, 9, 12 rad/s; see methods/pll/README.md).
FILTER_BANDWIDTH_PER_PRIOR = 0.5
# Never narrower than 0.1 ω₀ (priors too close to give each loop its own band)
MIN_FILTER_BANDWIDTH_PER_PRIOR = 0.1
# The upper band edge stays below ω₀ + 0.9 (π/Δt − ω₀)
FILTER_EDGE_NYQUIST_FRACTION = 0.9


def default_loop_bandwidth(prior, dt: float) -> np.ndarray:
    """ω_L (rad/s) of each loop from its prior ω₀: 0.22 min(ω₀, π/Δt − ω₀), and ω_L Δt ≤ 0.25.

    0.22 ω₀ is Table 6's ratio. It puts the detector's 2ω₀ ripple at 9 ω_L; near the Nyquist frequency that
    ripple aliases to 2π/Δt − 2ω₀, hence the min. The ω_LΔt cap keeps ≥ 13° of phase margin at K = 1.
    """
    prior = np.asarray(prior, dtype=float).reshape(-1)
    nyquist = math.pi / dt
    if not np.all((prior > 0) & (prior < nyquist)):
        raise ValueError(f"priors {prior.tolist()} rad/s must lie between 0 and the Nyquist frequency "
                         f"{nyquist:.4g} rad/s")
    return np.minimum(OMEGA_L_PER_PRIOR * np.minimum(prior, nyquist - prior), MAX_OMEGA_L_DT / dt)


def _warp(omega, dt: float):
    return np.tan(np.asarray(omega, dtype=float) * dt / 2.0)


def _unwarp(tau, dt: float):
    return 2.0 * np.arctan(tau) / dt


def bandwidth_for_upper_edge(centre: float, upper: float, dt: float) -> float:
    """The bandwidth (rad/s) of the :func:`band_edges` band centred on ``centre`` whose upper edge is ``upper``."""
    lower = _unwarp(_warp(centre, dt) ** 2 / _warp(upper, dt), dt)
    return float(upper - lower)


def bandwidth_for_lower_edge(centre: float, lower: float, dt: float) -> float:
    """The bandwidth (rad/s) of the :func:`band_edges` band centred on ``centre`` whose lower edge is ``lower``."""
    upper = _unwarp(_warp(centre, dt) ** 2 / _warp(lower, dt), dt)
    return float(upper - lower)


def default_filter_bandwidth(centres, dt: float) -> np.ndarray:
    """Input-filter bandwidths (rad/s) from the filter centres (the priors), for :func:`input_filter_sos`.

    B = 0.5 ω₀, then capped so that a band does not reach past the (prewarped) geometric midpoint
    2/Δt·atan(√(tan(ω₀Δt/2) tan(ω₁Δt/2))) between its centre ω₀ and a neighbouring centre ω₁: neighbouring
    pass bands then at most touch, and each filter attenuates its neighbours' centres by ≥ 19 dB
    (order 3, 0.5 dB ripple). Not below 0.1 ω₀ (if priors are that close the bands must overlap). The
    upper edge stays below ω₀ + 0.9 (π/Δt − ω₀). Equal centres are not neighbours.
    """
    centres = np.asarray(centres, dtype=float).reshape(-1)
    nyquist = math.pi / dt
    if not np.all((centres > 0) & (centres < nyquist)):
        raise ValueError(f"filter centres {centres.tolist()} rad/s must lie between 0 and the Nyquist "
                         f"frequency {nyquist:.4g} rad/s")
    out = np.empty(centres.size)
    for j, c in enumerate(centres):
        b = FILTER_BANDWIDTH_PER_PRIOR * c
        above, below = centres[centres > c], centres[centres < c]
        if above.size:
            mid = float(_unwarp(np.sqrt(_warp(c, dt) * _warp(above.min(), dt)), dt))
            b = min(b, bandwidth_for_upper_edge(c, mid, dt))
        if below.size:
            mid = float(_unwarp(np.sqrt(_warp(c, dt) * _warp(below.max(), dt)), dt))
            b = min(b, bandwidth_for_lower_edge(c, mid, dt))
        b = max(b, MIN_FILTER_BANDWIDTH_PER_PRIOR * c)
        top = c + FILTER_EDGE_NYQUIST_FRACTION * (nyquist - c)
        out[j] = min(b, bandwidth_for_upper_edge(c, top, dt))
    return out


# --------------------------------------------------------------------------------------------------------
# Discretisation of the loop filters
# --------------------------------------------------------------------------------------------------------

def bilinear_prewarped(b, a, dt: float, omega_p: float) -> tuple[np.ndarray, np.ndarray]:
    """Tustin discretisation of B(s)/A(s) with prewarping at ω_p (exact response at ω_p).

    s = c (z − 1)/(z + 1) with c = ω_p / tan(ω_p Δt / 2); ``scipy.signal.bilinear`` with fs = c/2.
    """
    if not 0 < omega_p * dt < math.pi:
        raise ValueError(f"prewarping frequency {omega_p} rad/s is not below the Nyquist frequency "
                         f"{math.pi / dt:.4g} rad/s")
    c = omega_p / math.tan(omega_p * dt / 2.0)
    bz, az = scipy.signal.bilinear(b, a, fs=c / 2.0)
    return np.asarray(bz, dtype=float) / az[0], np.asarray(az, dtype=float) / az[0]


@dataclass(frozen=True)
class DiscreteLoop:
    """Coefficients of one discretised loop (normalised, a[0] = 1)."""

    lowpass_b: np.ndarray     # 1/(1 + T_VCO s), 2 coefficients each
    lowpass_a: np.ndarray
    control_b: np.ndarray     # F(s), 3 coefficients each; one pole at z = 1 (the integrator)
    control_a: np.ndarray


@functools.lru_cache(maxsize=64)
def discretise_loop(p: LoopParameters, dt: float) -> DiscreteLoop:
    """Tustin with prewarping at ω_L, where the loop's phase margin is decided, for eqs. (36) and (37)."""
    omega_p = min(p.omega_l, 0.5 * math.pi / dt)
    lb, la = bilinear_prewarped([1.0], [p.t_vco, 1.0], dt, omega_p)
    cb, ca = bilinear_prewarped([p.gain * p.t2, p.gain], [p.t1 * p.t3, p.t1, 0.0], dt, omega_p)
    return DiscreteLoop(lb, la, cb, ca)


def open_loop_response(p: LoopParameters, omega: np.ndarray, dt: float | None = None,
                       detector_gain: float = 1.0) -> np.ndarray:
    """Open-loop frequency response L(jω) of the phase loop (phase error in, VCO phase out).

    Continuous (``dt=None``): K_d (1/(1+T_VCO s)) F(s) / s. Discrete: the Tustin filters of
    :func:`discretise_loop` and the VCO phase update θ_{k+1} = θ_k + ω_k Δt, i.e. Δt z⁻¹/(1 − z⁻¹).
    """
    omega = np.asarray(omega, dtype=float)
    if dt is None:
        s = 1j * omega
        f = p.gain * (1 + p.t2 * s) / (p.t1 * s * (1 + p.t3 * s))
        return detector_gain * f / (1 + p.t_vco * s) / s
    d = discretise_loop(p, dt)
    z = np.exp(1j * omega * dt)
    lp = np.polyval(d.lowpass_b, z) / np.polyval(d.lowpass_a, z)
    f = np.polyval(d.control_b, z) / np.polyval(d.control_a, z)
    vco = dt / (z - 1.0)
    return detector_gain * lp * f * vco


def stability_margins(p: LoopParameters, dt: float | None = None, detector_gain: float = 1.0) -> dict:
    """Crossover frequency (rad/s), phase margin (deg) and gain margin (dB) of the open loop.

    Read off a dense frequency grid (the loop is type 2: the phase starts at −180° and the lead of
    (1 + T₂ s) lifts it above; a negative phase margin means the linearised loop is unstable).
    """
    top = 50.0 * p.omega_l if dt is None else 0.999 * math.pi / dt
    omega = np.geomspace(1e-3 * p.omega_l, top, 20000)
    ell = open_loop_response(p, omega, dt, detector_gain)
    mag = np.abs(ell)
    phase = np.unwrap(np.angle(ell))
    phase -= 2 * math.pi * round(phase[0] / (2 * math.pi) + 0.5)     # start in (−2π, 0]: type-2 loop at −π
    above = np.flatnonzero(mag >= 1.0)
    wc_i = above[-1] if above.size else 0
    pm = math.degrees(phase[wc_i] + math.pi)
    past = np.flatnonzero((phase[:-1] > -math.pi) & (phase[1:] <= -math.pi) & (np.arange(omega.size - 1)
                                                                               > np.argmax(phase)))
    gm = -20 * math.log10(mag[past[0]]) if past.size else math.inf
    return {"crossover_rad_s": float(omega[wc_i]), "phase_margin_deg": pm, "gain_margin_db": gm}


# --------------------------------------------------------------------------------------------------------
# Input filter A(s): Chebyshev type I band-pass (§4.4)
# --------------------------------------------------------------------------------------------------------

def band_edges(centre: float, bandwidth: float, dt: float) -> tuple[float, float]:
    """Digital pass-band edges ω₁ < ω₂ (rad/s) with ω₂ − ω₁ = bandwidth and centre ω_c.

    The centre of a band-pass made by the bilinear transform is where the low-pass prototype sits at
    zero frequency: tan(ω_c Δt/2)² = tan(ω₁ Δt/2) tan(ω₂ Δt/2) (the geometric centre of the prewarped
    edges). Solving for ω₁ makes both the bandwidth and the centre exact after discretisation.
    """
    nyq = math.pi / dt
    if not (0 < centre < nyq and bandwidth > 0):
        raise ValueError(f"input filter centre {centre} rad/s and bandwidth {bandwidth} rad/s must be "
                         f"positive with the centre below the Nyquist frequency {nyq:.4g} rad/s")
    tc2 = math.tan(centre * dt / 2) ** 2

    def mismatch(w1):
        return math.tan(w1 * dt / 2) * math.tan((w1 + bandwidth) * dt / 2) - tc2

    hi = min(centre, nyq - bandwidth) * (1 - 1e-12)
    if hi <= 0 or mismatch(hi) < 0:
        raise ValueError(f"input filter band {centre} ± {bandwidth / 2} rad/s does not fit below the "
                         f"Nyquist frequency {nyq:.4g} rad/s")
    w1 = scipy.optimize.brentq(mismatch, 0.0, hi, xtol=1e-14, rtol=1e-14)
    return w1, w1 + bandwidth


def input_filter_sos(centre: float, bandwidth: float, dt: float, order: int = 3,
                     ripple_db: float = 0.5) -> np.ndarray:
    """Chebyshev type I band-pass, prototype order ``order`` (2·order poles), as second-order sections.

    ``scipy.signal.cheby1`` with ``fs`` designs the analog filter on prewarped edges and applies the
    bilinear transform; the edges from :func:`band_edges` make the digital centre and band edges (where
    the gain is −ripple_db) equal the specification. Gain at the centre: 0 dB for odd ``order``.
    The design is cached: it costs more than filtering a record.
    """
    return _input_filter_sos(float(centre), float(bandwidth), float(dt), int(order), float(ripple_db)).copy()


@functools.lru_cache(maxsize=64)
def _input_filter_sos(centre: float, bandwidth: float, dt: float, order: int, ripple_db: float) -> np.ndarray:
    if order < 1:
        raise ValueError(f"filter_order = {order}: the input filter's order must be at least 1")
    if not ripple_db > 0:
        raise ValueError(f"input filter ripple {ripple_db} dB must be positive")
    w1, w2 = band_edges(centre, bandwidth, dt)
    fs = 2 * math.pi / dt                                        # rad/s, the unit of the edges
    return scipy.signal.cheby1(order, ripple_db, [w1, w2], btype="bandpass", fs=fs, output="sos")
