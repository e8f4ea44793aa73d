"""Phase-locked-loop bank: one loop per mode (paper §3.4, Fig. 2, eqs. 32–37; §4.4, Table 6).

Each loop, at the data's sample rate (Δt):

    u  = A(z) y                                   Chebyshev I band-pass input filter (optional, §4.4)
    q  = LP(u · cos θ),  i = LP(u · sin θ)        phase detector (eq. 34) and its in-phase arm,
                                                  LP = 1/(1 + T_VCO s) (eq. 36), Tustin prewarped at ω_L
    Â  = AGC(2 √(i² + q²))                        amplitude of the tracked component
    e  = K_d · q / (Â/2)  ≈ K_d sin φₑ            detector normalised to gain K_d (default 1 rad⁻¹)
    v  = F(z) e                                   F(s) = K(1 + T₂s)/(T₁s(1 + T₃s)) (eq. 37), Tustin at ω_L
    ω  = ω₀ + v,  θ ← θ + ω Δt                    VCO; ω is the frequency estimate at that sample

With u = A sin(ωt + φ) the low-frequency part of u·cos θ is (A/2) sin φₑ (eq. 34), that of u·sin θ is
(A/2) cos φₑ; so 2i/Â ≈ cos φₑ is the lock indicator (≈ 1 in lock, averaging to ≈ 0 while the loop slips).

Why an AGC: the raw detector gain A·B/2 is proportional to the input amplitude, which differs six-fold
between the modes and decays with damping, while the design rule under eq. (37) puts the crossover at
ω_L only for a unit detector gain. The AGC divides by an in-phase/quadrature amplitude estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.signal

from methods.estimate import Estimate, check_inputs, failed, flat_record, make_options
from methods.pll.design import (
    VCO_LOWPASS_TIMES_OMEGA_L,
    LoopParameters,
    default_filter_bandwidth,
    default_loop_bandwidth,
    discretise_loop,
    input_filter_sos,
    loop_time_constants,
    rule_parameters,
)

# Options holding one value per loop (in prior order); None = derived from the prior (see Options)
PER_LOOP_OPTIONS = ("loop_bandwidth_rad_s", "t_vco_s", "t1_s", "t2_s", "t3_s", "gain",
                    "filter_bandwidth_rad_s")


@dataclass
class Options:
    """Keyword options of :func:`identify`.

    The per-loop options (one entry per prior, or a single entry for every loop) default to None, i.e.
    derived from the prior ω₀ and Δt (methods/pll/design.py, methods/pll/README.md), so that any number of modes at
    any frequencies works: ω_L = 0.22 min(ω₀, π/Δt − ω₀) with ω_LΔt ≤ 0.25 (Table 6: ω_L/ω₀ ≈ 0.21–0.25);
    T₁, T₂, T₃ by the rule under eq. (37) at phase_margin_deg; T_VCO = 0.5/ω_L (Table 6's ratio); K = 1;
    input-filter bandwidth 0.5 ω₀, capped so that neighbouring pass bands do not overlap. The paper's own
    Table 6 values (for its prior 2.8, 16, 18, 52 rad/s) are written out in configs/method/pll.yaml.
    Fig. 6 of the paper also raises mode 1's K to 5; with a unit-gain detector that loop is unstable
    (see methods/pll/README.md).
    """

    # Table 6 columns, one entry per loop (a single entry is used for every loop); None: from the prior
    loop_bandwidth_rad_s: list[float] | None = None   # ω_L
    # ω_L in units of each loop's prior ω₀ (ω_L = loop_bandwidth_rel·ω₀): scales with a time-scaled record
    loop_bandwidth_rel: list[float] | None = None
    t_vco_s: list[float] | None = None                # eq. (36); None: 0.5/ω_L
    t1_s: list[float] | None = None                   # eq. (37); None: the rule under eq. (37) at ω_L
    t2_s: list[float] | None = None
    t3_s: list[float] | None = None
    gain: list[float] | None = None                   # K; None: 1 (Table 6; Fig. 6: mode 1 at 5)
    # "table": the time constants given above (None entries from the rule); "rule": T1–T3 from ω_L and
    # phase_margin_deg (rule under eq. 37) and T_VCO = 0.5/ω_L even where time constants are given
    design: str = "table"
    phase_margin_deg: float = 45.0
    # Input filters (§4.4): Chebyshev I band-pass, centred on the prior unless filter_centre_rad_s is given.
    # Bandwidth None: 0.5 × centre, capped at the geometric midpoints to the neighbouring centres
    # (pll_design.default_filter_bandwidth); Table 6 / §4.4: 5, 9, 9, 12 rad/s
    input_filter: bool = True
    filter_bandwidth_rad_s: list[float] | None = None
    filter_centre_rad_s: list[float] | None = None
    filter_order: int = 3                # §4.4: order 3
    filter_ripple_db: float = 0.5        # not given by the paper
    remove_mean: bool = True             # §4: a bias "is easy to estimate ... and then remove"
    # Phase-detector normalisation: "agc" (gain detector_gain per rad) or "none" (raw u·cos θ, gain A/2)
    normalisation: str = "agc"
    detector_gain: float = 1.0
    agc_time_factor: float = 2.0         # AGC time constant = agc_time_factor / ω_L
    # The AGC follows the amplitude down at most this far below its peak; below, the detector gain falls
    # with the signal and the loop holds its frequency instead of tracking leakage or noise. None: no limit.
    agc_range_db: float | None = None
    # Output: mean and spread over the final part of the record
    output_window_fraction: float = 0.25
    output_window_s: float | None = None  # overrides output_window_fraction when set
    # Lock: mean lock indicator over the window ≥ threshold, no cycle slip in it (indicator < 0), the
    # means of the window's two halves within steady_tolerance × estimate of each other (not still
    # acquiring), and a record at least min_acquisition_times × 4π/ω_L long (§3.4's acquisition time)
    lock_threshold: float = 0.8
    steady_tolerance: float = 0.01
    min_acquisition_times: float = 1.0


def identify(y, dt, prior, **options) -> Estimate:
    """Identify one frequency per prior entry with one phase-locked loop each.

    Parameters
    ----------
    y : array_like, shape (n,)
        Tip acceleration, m/s².
    dt : float
        Sample interval, s. The loops run at this rate.
    prior : array_like, shape (m,)
        A-priori frequencies ω₀ (rad/s): the VCO free-running frequencies and the input-filter centres.
    **options
        Fields of :class:`Options`.

    Returns
    -------
    Estimate
        ``history`` (n, m): VCO frequency after every sample. ``frequencies``/``std``: mean/standard
        deviation of the history over the output window. ``converged`` is False when any loop is not
        locked; ``extra['locked']`` says which. ``extra`` also holds ``lock_indicator`` (window mean of
        2i/Â), ``lock_history`` (n, m), ``amplitude_m_s2`` (final Â), ``window_s``, ``acquisition_time_s``.
    """
    y, dt, prior = check_inputs(y, dt, prior)
    opts = make_options(Options, options, "pll")
    loops, centres, bandwidths = _design(opts, prior, dt)
    flat = flat_record(y)
    if flat:
        return failed(prior, flat, iterations=y.size)
    n = y.size
    if opts.remove_mean:
        y = y - y.mean()

    window = _window_samples(opts, n, dt)
    history = np.empty((n, prior.size))
    lock = np.empty((n, prior.size))
    amplitude = np.empty(prior.size)
    clamped = np.zeros(prior.size, dtype=int)
    for j, p in enumerate(loops):
        u = y
        if opts.input_filter:
            sos = input_filter_sos(centres[j], bandwidths[j], dt, opts.filter_order, opts.filter_ripple_db)
            u = scipy.signal.sosfilt(sos, y)
        w_hist, l_hist, amp, n_clamp = _run_loop(u, dt, prior[j], p, opts)
        history[:, j] = w_hist
        lock[:, j] = l_hist
        amplitude[j] = amp
        clamped[j] = n_clamp
    est = _summarise(history, lock, amplitude, clamped, loops, window, dt, opts, prior)
    est.extra["loop_bandwidth_rad_s"] = np.array([p.omega_l for p in loops])
    est.extra["filter_bandwidth_rad_s"] = bandwidths if opts.input_filter else np.full(prior.size, np.nan)
    return est


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods` (validated without a record, before any work): the loops
    and input filters are designed, as :func:`identify` designs them."""
    opts = make_options(Options, options, "pll")
    _design(opts, prior, dt)
    return opts


# --------------------------------------------------------------------------------------------------------

def _design(opts: Options, prior: np.ndarray, dt: float):
    """Each loop's parameters, input-filter centres and bandwidths (NaN without input filters); raises
    ``ValueError`` naming an impossible option."""
    loops = _loop_parameters(opts, prior, dt)
    centres = prior if opts.filter_centre_rad_s is None else _per_loop(
        opts.filter_centre_rad_s, prior.size, "filter_centre_rad_s")
    if opts.filter_bandwidth_rad_s is not None:
        bandwidths = _per_loop(opts.filter_bandwidth_rad_s, prior.size, "filter_bandwidth_rad_s")
    elif opts.input_filter:
        bandwidths = default_filter_bandwidth(centres, dt)
    else:
        bandwidths = np.full(prior.size, np.nan)
    if opts.input_filter:       # a band that does not fit below Nyquist, a bad order or ripple
        for j in range(prior.size):
            input_filter_sos(centres[j], bandwidths[j], dt, opts.filter_order, opts.filter_ripple_db)
    return loops, centres, bandwidths


def _per_loop(values, m: int, name: str) -> np.ndarray:
    v = np.asarray(values, dtype=float).reshape(-1)
    if v.size == 1:
        v = np.full(m, v[0])
    if v.size != m:
        raise ValueError(f"pll option {name} has {v.size} entries; the prior has {m} (give one per loop, "
                         f"or a single value for all)")
    if not np.all(np.isfinite(v) & (v > 0)):
        raise ValueError(f"pll option {name} = {v.tolist()} must hold positive numbers")
    return v


def _loop_parameters(opts: Options, prior: np.ndarray, dt: float) -> list[LoopParameters]:
    """Each loop's parameters: the options where given, else derived from the prior (Options docstring)."""
    m = prior.size
    if opts.design not in ("table", "rule"):
        raise ValueError(f"pll option design = '{opts.design}' must be 'table' or 'rule'")
    if opts.normalisation not in ("agc", "none"):
        raise ValueError(f"pll option normalisation = '{opts.normalisation}' must be 'agc' or 'none'")
    for name in ("lock_threshold", "output_window_fraction"):
        if not 0 < getattr(opts, name) <= 1:
            raise ValueError(f"pll option {name} = {getattr(opts, name)} must be in (0, 1]")
    for name in ("detector_gain", "agc_time_factor", "steady_tolerance"):
        if not getattr(opts, name) > 0:
            raise ValueError(f"pll option {name} = {getattr(opts, name)} must be positive")
    if opts.agc_range_db is not None and not opts.agc_range_db > 0:
        raise ValueError(f"pll option agc_range_db = {opts.agc_range_db} dB must be positive (or None)")
    if opts.output_window_s is not None and not opts.output_window_s > 0:
        raise ValueError(f"pll option output_window_s = {opts.output_window_s} s must be positive")
    if not opts.min_acquisition_times >= 0:
        raise ValueError(f"pll option min_acquisition_times = {opts.min_acquisition_times} must be ≥ 0")
    if not 0 < opts.phase_margin_deg < 90:
        raise ValueError(f"pll option phase_margin_deg = {opts.phase_margin_deg} must be in (0, 90)")
    # Explicit lists are checked whatever the design (a wrong length is an error, not silently unused)
    given = {name: _per_loop(getattr(opts, name), m, name) for name in PER_LOOP_OPTIONS
             if getattr(opts, name) is not None}
    omega_l = given.get("loop_bandwidth_rad_s")
    if opts.loop_bandwidth_rel is not None:
        if omega_l is not None:
            raise ValueError(f"pll: give loop_bandwidth_rel or loop_bandwidth_rad_s, not both (loop_bandwidth_rel "
                             f"= {opts.loop_bandwidth_rel!r}, loop_bandwidth_rad_s = {opts.loop_bandwidth_rad_s!r})")
        omega_l = _per_loop(opts.loop_bandwidth_rel, m, "loop_bandwidth_rel") * prior
    if omega_l is None:
        omega_l = default_loop_bandwidth(prior, dt)
    gain = given.get("gain", np.ones(m))
    loops = []
    for j in range(m):
        wl = float(omega_l[j])
        if opts.design == "rule":
            loops.append(rule_parameters(wl, float(gain[j]), opts.phase_margin_deg))
            continue
        rule = dict(zip(("t1_s", "t2_s", "t3_s"), loop_time_constants(wl, opts.phase_margin_deg),
                        strict=True))
        rule["t_vco_s"] = VCO_LOWPASS_TIMES_OMEGA_L / wl
        t = {k: float(given[k][j]) if k in given else rule[k] for k in ("t_vco_s", "t1_s", "t2_s", "t3_s")}
        loops.append(LoopParameters(wl, t["t_vco_s"], t["t1_s"], t["t2_s"], t["t3_s"], float(gain[j])))
    return loops


def _window_samples(opts: Options, n: int, dt: float) -> int:
    if opts.output_window_s is not None:
        return int(min(n, max(1, round(opts.output_window_s / dt))))
    return int(min(n, max(1, round(opts.output_window_fraction * n))))


def _run_loop(u: np.ndarray, dt: float, w0: float, p: LoopParameters, opts: Options):
    """Run one loop over the record. Returns (frequency history, lock history, final Â, clamp count).

    A plain scalar loop: the recursion is sequential, and Python floats beat numpy scalars here.
    """
    d = discretise_loop(p, dt)
    lb0, lb1 = float(d.lowpass_b[0]), float(d.lowpass_b[1])
    la1 = float(d.lowpass_a[1])
    cb0, cb1, cb2 = (float(c) for c in d.control_b)
    ca1, ca2 = float(d.control_a[1]), float(d.control_a[2])
    agc = opts.normalisation == "agc"
    kd = opts.detector_gain
    # Initial AGC state: √2 × RMS of the (filtered) input over its first AGC time constant (at least two
    # periods of ω₀), so that the first samples are neither over- nor under-amplified by orders of magnitude.
    t_agc = opts.agc_time_factor / p.omega_l
    alpha = 1.0 - math.exp(-dt / t_agc)                                  # AGC: exponential smoothing
    n0 = max(2, min(u.size, int(round(max(t_agc, 4.0 * math.pi / w0) / dt))))
    amp = math.sqrt(2.0 * float(np.mean(u[:n0] ** 2)))
    if not amp > 0:
        amp = 1e-300
    floor = 1e-12 * amp                                                  # only a guard against 0/0
    peak = amp
    range_ratio = 0.0 if opts.agc_range_db is None else 10.0 ** (-opts.agc_range_db / 20.0)
    w_lo, w_hi = 1e-3 * w0, 0.99 * math.pi / dt                         # keep the VCO below Nyquist
    two_pi = 2.0 * math.pi
    cos, sin, sqrt = math.cos, math.sin, math.sqrt
    th = 0.0
    q = i = pq_old = pi_old = 0.0
    z1 = z2 = 0.0
    n_clamp = 0
    w_hist = [0.0] * u.size
    l_hist = [0.0] * u.size
    for k, x in enumerate(u.tolist()):
        c, s = cos(th), sin(th)
        pq, pi_ = x * c, x * s                                            # eq. (34) and in-phase arm
        q = lb0 * pq + lb1 * pq_old - la1 * q                             # eq. (36)
        i = lb0 * pi_ + lb1 * pi_old - la1 * i
        pq_old, pi_old = pq, pi_
        if agc:
            amp += alpha * (2.0 * sqrt(i * i + q * q) - amp)
            if amp > peak:
                peak = amp
            a_lock = 0.5 * amp if amp > floor else 0.5 * floor
            lowest = range_ratio * peak
            a_half = a_lock if amp > lowest else 0.5 * lowest
            e = kd * q / a_half
        else:
            e = q
        v = cb0 * e + z1                                                  # eq. (37), transposed DF II
        z1 = cb1 * e - ca1 * v + z2
        z2 = cb2 * e - ca2 * v
        w = w0 + v
        if w < w_lo or w > w_hi:
            w = w_lo if w < w_lo else w_hi
            n_clamp += 1
        w_hist[k] = w
        l_hist[k] = i / a_lock if agc else i / max(sqrt(i * i + q * q), 1e-300)
        th += w * dt
        if th > two_pi:
            th -= two_pi
    return np.array(w_hist), np.array(l_hist), amp, n_clamp


def _summarise(history, lock, amplitude, clamped, loops, window, dt, opts, prior) -> Estimate:
    n, m = history.shape
    tail = history[n - window:]
    freq = tail.mean(axis=0)
    std = tail.std(axis=0, ddof=1) if window > 1 else np.full(m, np.nan)
    lock_tail = lock[n - window:]
    lock_mean = lock_tail.mean(axis=0)
    slip = lock_tail.min(axis=0) < 0.0
    half = window // 2          # still acquiring: the two halves of the window disagree
    drift = (np.abs(tail[half:].mean(axis=0) - tail[:half].mean(axis=0)) if half
             else np.full(m, np.inf))
    unsteady = ~(drift <= opts.steady_tolerance * np.abs(freq))
    acq = np.array([p.acquisition_time_s for p in loops])
    record_s = n * dt
    short = record_s < opts.min_acquisition_times * acq
    locked = (lock_mean >= opts.lock_threshold) & ~slip & ~unsteady & ~short & (clamped == 0)
    reasons = []
    for j in range(m):
        if locked[j]:
            continue
        why = []
        if short[j]:
            why.append(f"record {record_s:.3g} s shorter than the acquisition time {acq[j]:.3g} s")
        if lock_mean[j] < opts.lock_threshold:
            why.append(f"lock indicator {lock_mean[j]:.2f} < {opts.lock_threshold}")
        if slip[j]:
            why.append("cycle slip in the output window")
        if unsteady[j]:
            why.append(f"estimate drifts by {drift[j]:.3g} rad/s across the output window")
        if clamped[j]:
            why.append(f"VCO frequency clamped {clamped[j]} times")
        reasons.append(f"loop {j + 1} ({prior[j]:g} rad/s) not locked: " + ", ".join(why))
    message = "; ".join(reasons) if reasons else f"all {m} loops locked"
    extra = {
        "locked": locked.tolist(),
        "lock_indicator": lock_mean,
        "lock_history": lock,
        "amplitude_m_s2": amplitude,
        "window_s": window * dt,
        "acquisition_time_s": acq,
        "vco_clamped_samples": clamped,
    }
    return Estimate(freq, std, history=history, converged=bool(locked.all()), iterations=n,
                    message=message, extra=extra, converged_per_mode=locked)
