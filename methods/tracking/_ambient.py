"""``akf_ambient``: the augmented filter reformulated for continuing random excitation.

Per mode i the state is (ξᵢ, ξ̇ᵢ, ωᵢ): ξᵢ the tip displacement of mode i (unit tip gain, as in ``akf``), ωᵢ its
natural frequency. An unknown white force, held over each sample, drives the modes' velocities; the
frequencies walk at random; the accelerometer reads acceleration with its direct term:

    ξᵢ(k+1) = Φᵢ(ωᵢ) ξᵢ(k) + Γᵢ(ωᵢ) Σⱼ bᵢⱼ uⱼ(k),     uⱼ(k) ~ N(0, 1) white
    ωᵢ(k+1) = ωᵢ(k) + ηᵢ(k),                          ηᵢ(k) ~ N(0, (ν ωᵢ)² Δt),  ν = rate·√horizon
    y(k)    = Σᵢ (−ωᵢ² ξᵢ − 2ζωᵢ ξ̇ᵢ) + Σⱼ dⱼ uⱼ(k) + v(k),       v(k) ~ N(0, r)

Φᵢ = expm(AᵢΔt), Aᵢ = [[0, 1], [−ωᵢ², −2ζωᵢ]], Γᵢ = Aᵢ⁻¹(Φᵢ − I)[0, 1]ᵀ: exact for a force held over the
sample (zero-order hold; tested against ``scipy.signal.cont2discrete``). The forces of the current sample
are states (predicted 0 with variance 1), so their direct term and its correlation with the drive need no
cross-covariance. ``force_model``: ``"diagonal"`` (default) one force per mode, bᵢᵢ = √qᵢ, no direct term
(it is in r); ``"single"`` one force behind every mode, signed gains bᵢ and a direct term d (Whittle fit,
:func:`fit_single_force`; with ``fit_memory_looks`` > 1 a forgetting sum of the looks' losses,
:func:`whittle_losses`). ``frequency_model="trend"`` adds each frequency's rate (a local linear trend):

    ωᵢ(k+1) = ωᵢ(k) + Δt ω̇ᵢ(k) + ηᵢ(k),   ω̇ᵢ(k+1) = ω̇ᵢ(k) + κᵢ(k),   κᵢ(k) ~ N(0, (rate ωᵢ)² Δt / horizon_trend),

ω̇ᵢ's prior 0 ± rate·ωᵢ (the stated rate), reset with ωᵢ at a restart. ``frequency_model="slosh"`` knows that a
modulation may be present and that it is one wave for every mode (sloshing is one fluid mode): the walk ω̄ᵢ
times a shared modulation,

    ωᵢ(k) = ω̄ᵢ(k)(1 + s(k)),   s̈ + 2ζₛΩṡ + Ω²s = white of intensity qₛ  (exact transition over Δt),

s starting off (qₛ = 0). Every hop, once the track has half the longest modulation period searched behind it,
its history (at most two such periods) gives Ω and qₛ (:func:`slosh_look`: block means of ln ω̂ᵢ weighted
by each mode's information ω̂ᵢ²/Var ω̂ᵢ, differenced, Hann periodogram; the largest line in the band of
``slosh_periods`` (periods of the slowest prior mode) above ``slosh_gate`` × the median bin); the
oscillator's stationary variance qₛ/(4ζₛΩ³) is set to the line's a²/2 (covariance matching), and to 0 while
no line passes. The estimates read from the track follow it, so a modulation learnt late is under-stated at
first and grows over a few tens of seconds. Under this model, modes that cross are swapped back to the
prior's order (states, gains, restart records): a close pair moved by a modulation can otherwise trade
labels. The extended Kalman filter linearises
the transition in ω with the exact ∂Φ/∂ω (``methods.kalman.modal_transition``) and the measurement with
∂h/∂ωᵢ = −2ωᵢξᵢ − 2ζξ̇ᵢ (``"slosh"``: through ωᵢ = ω̄ᵢ(1 + s), ∂/∂ω̄ᵢ = (1 + s)∂/∂ωᵢ, ∂/∂s = Σᵢ ω̄ᵢ ∂/∂ωᵢ; the
reported variance is [1 + s, ω̄ᵢ] P [1 + s, ω̄ᵢ]ᵀ).

What the paper's filter does not do, each an established technique:

* **noise intensities from the data** (covariance matching in the frequency domain): every hop the Hann
  periodogram of the last window gives the floor r̂ (median bin away from the modes / ln 2) and each mode's
  acceleration variance σᵢ² (the PSD above the floor over its band), whence qᵢ = bᵢᵢ² = 4ζσᵢ²/(ωᵢΔt) (the
  stationary acceleration variance of an oscillator under a white force of intensity qᵢΔt is ωᵢqᵢΔt/(4ζ));
* **re-acquisition** (a change detector): the periodogram's peak near each mode is a window estimate; when it
  is further from the filter's ω̂ᵢ than ``restart_gate`` × the running scale of that disagreement (median
  absolute value / 0.6745) and than the window's resolution 2π/T, on ``restart_after`` looks in a row, ωᵢ
  restarts at the peak with 1σ max(1 % ω, resolution/4) — a step the filter alone cannot leave its basin for;
* **impulsive process noise** (thruster pulses): a sample whose normalised innovation e²/S exceeds
  ``pulse_gate`` is not used; instead each mode's state covariance grows by ``pulse_inflation``·e² in
  acceleration units (its amplitude and phase re-learnt, its frequency kept).

Written by hand: filterpy's ``ExtendedKalmanFilter`` has the same arithmetic, but the adaptation, restarts
and pulse inflation act on P between its calls, and its per-call overhead would take the cost past the
on-board budget (0.2 ms per sample here).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.signal

from methods.estimate import make_options
from methods.kalman import modal_transition
from methods.tracking._track import Track

# A mode counts as converged while its 1σ is at most this share of its frequency (2 %: inside the ±30 % band,
# and below the 1 % tolerance's scale only once the filter has accumulated a few periods of data).
DETERMINED_REL_STD = 0.02


@dataclass
class SharedOptions:
    """The options ``akf_ambient`` and ``rpem_ambient`` share; every default follows from Δt and the prior.

    Attributes
    ----------
    damping_ratio : float
        ζ assumed for every mode (``akf_ambient``: not estimated, as ``akf``'s; ``rpem_ambient``: its start).
    rate_rel_per_s : float
        How fast a frequency may move, relative per s (0.001: 0.1 %/s). With ``horizon_s`` it sets the walk:
        ν = rate·√horizon per √s, a walk whose spread over the horizon equals the drift over it.
    horizon_s : float or None
        The horizon of that match; None: the window.
    window_s : float or None
        The periodogram's window; None: five periods of the slowest prior mode (10 s for 3.2 rad/s).
    hop_s : float or None
        How often the periodogram is taken; None: a tenth of the window.
    band : float
        Half-width of a mode's search band, relative, cut at the geometric midpoints to its neighbours.
    restart_gate, restart_after : float, int
        A mode restarts at the window's peak when its disagreement exceeds ``restart_gate`` running robust
        scales (and the window's resolution) on ``restart_after`` looks in a row.
    pulse_gate : float
        e²/S above this (χ², 1 dof) is a pulse: the sample does not update the frequencies.
    """

    damping_ratio: float = 0.005
    rate_rel_per_s: float = 0.001
    horizon_s: float | None = None
    window_s: float | None = None
    hop_s: float | None = None
    band: float = 0.3
    restart_gate: float = 4.0
    restart_after: int = 2
    pulse_gate: float = 25.0


@dataclass
class Options(SharedOptions):
    """Options of ``akf_ambient``: :class:`SharedOptions` and

    Attributes
    ----------
    pulse_inflation : float
        At a pulse, each mode's state covariance grows by this × e² in acceleration units.
    force_model : str
        ``"diagonal"`` (one force per mode, no direct term) or ``"single"`` (one force, signed gains, a direct
        term; module docstring).
    frequency_model : str
        ``"walk"`` (default): ωᵢ a random walk alone; ``"trend"``: each frequency also carries its rate ω̇ᵢ
        (a local linear trend, module docstring); ``"slosh"``: the walk times one shared modulation
        (1 + s(t)), s a damped oscillator whose frequency and intensity come from the tracks' own history
        (module docstring).
    trend_horizon_s : float or None
        ``"trend"``: the rate may change by the stated rate (``rate_rel_per_s``·ω) over this horizon, a
        random walk of ω̇ of variance (rate·ω)²/horizon per s; None: ten windows (50 periods of the slowest
        prior mode).
    slosh_periods : tuple of float
        ``"slosh"``: the band of modulation periods searched, in periods of the slowest prior mode (3–20:
        5.8–39 s, 0.026–0.17 Hz for 3.2 rad/s; the issue's 0.05–0.1 Hz is 5–10). A modulation faster than a
        few periods of the slowest mode is no frequency of it; a slower one the walk follows.
    slosh_damping : float
        ``"slosh"``: ζ of the modulation's oscillator (its band ±ζΩ around the detected peak).
    slosh_gate : float
        ``"slosh"``: the line of the tracks' common differenced spectrum must exceed this × its median bin
        for a modulation to be modelled (the largest of ~10 independent bins of a white spectrum is about
        3–4× the median).
    refit_looks : int
        ``"single"``: the Whittle fit of signs and direct term every this many looks (magnitudes every look).
    fit_memory_looks : int
        ``"single"``: the fit minimises a forgetting sum of the looks' Whittle losses, each look weighted
        (1 − 1/this) per look older (1: the last look alone). The force's gains and direct term are the
        structure's, constant while the frequencies move, so a memory longer than the window steadies them.
    """

    pulse_inflation: float = 10.0
    force_model: str = "diagonal"
    refit_looks: int = 10
    fit_memory_looks: int = 1
    frequency_model: str = "walk"
    trend_horizon_s: float | None = None
    slosh_periods: tuple[float, float] = (3.0, 20.0)
    slosh_damping: float = 0.1
    slosh_gate: float = 10.0


def _window_samples(opts: SharedOptions, dt: float, prior: np.ndarray) -> tuple[int, int]:
    window_s = opts.window_s if opts.window_s is not None else 5 * 2 * math.pi / float(prior[0])
    hop_s = opts.hop_s if opts.hop_s is not None else window_s / 10
    return max(8, int(round(window_s / dt))), max(1, int(round(hop_s / dt)))


def check_shared(name: str, opts: SharedOptions, prior, dt: float, n_samples: int | None) -> None:
    """``ValueError`` (one line naming the option) for an impossible shared option."""
    if not (isinstance(opts.damping_ratio, (int, float)) and 0 <= opts.damping_ratio < 1):
        raise ValueError(f"{name}: damping_ratio = {opts.damping_ratio!r} must be in [0, 1)")
    for key in ("rate_rel_per_s", "band", "restart_gate", "pulse_gate"):
        value = getattr(opts, key)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name}: {key} = {value!r} must be a positive number")
    for key in ("horizon_s", "window_s", "hop_s"):
        value = getattr(opts, key)
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value >= dt):
            raise ValueError(f"{name}: {key} = {value!r} must be None or at least one sample ({dt} s)")
    if isinstance(opts.restart_after, bool) or not isinstance(opts.restart_after, int) or opts.restart_after < 1:
        raise ValueError(f"{name}: restart_after = {opts.restart_after!r} must be an integer ≥ 1")
    W, _ = _window_samples(opts, dt, np.asarray(prior, float))
    if n_samples is not None and W > n_samples:
        raise ValueError(f"{name}: the window ({W} samples) is longer than the record ({n_samples} samples)")


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None) -> Options:
    opts = make_options(Options, options, name)
    check_shared(name, opts, prior, dt, n_samples)
    if not (isinstance(opts.pulse_inflation, (int, float)) and math.isfinite(opts.pulse_inflation)
            and opts.pulse_inflation > 0):
        raise ValueError(f"{name}: pulse_inflation = {opts.pulse_inflation!r} must be a positive number")
    if opts.force_model not in ("single", "diagonal"):
        raise ValueError(f"{name}: force_model = {opts.force_model!r} must be 'single' or 'diagonal'")
    if isinstance(opts.refit_looks, bool) or not isinstance(opts.refit_looks, int) or opts.refit_looks < 1:
        raise ValueError(f"{name}: refit_looks = {opts.refit_looks!r} must be an integer ≥ 1")
    if isinstance(opts.fit_memory_looks, bool) or not isinstance(opts.fit_memory_looks, int) \
            or opts.fit_memory_looks < 1:
        raise ValueError(f"{name}: fit_memory_looks = {opts.fit_memory_looks!r} must be an integer ≥ 1")
    if opts.frequency_model not in ("slosh", "trend", "walk"):
        raise ValueError(f"{name}: frequency_model = {opts.frequency_model!r} must be 'slosh', 'trend' or 'walk'")
    sp = opts.slosh_periods
    if not (isinstance(sp, (tuple, list)) and len(sp) == 2
            and all(isinstance(v, (int, float)) and math.isfinite(v) for v in sp) and 0 < sp[0] < sp[1]):
        raise ValueError(f"{name}: slosh_periods = {sp!r} must be two increasing positive numbers")
    if not (isinstance(opts.slosh_damping, (int, float)) and 0 < opts.slosh_damping < 1):
        raise ValueError(f"{name}: slosh_damping = {opts.slosh_damping!r} must be in (0, 1)")
    if not (isinstance(opts.slosh_gate, (int, float)) and math.isfinite(opts.slosh_gate) and opts.slosh_gate > 0):
        raise ValueError(f"{name}: slosh_gate = {opts.slosh_gate!r} must be a positive number")
    h = opts.trend_horizon_s
    if h is not None and not (isinstance(h, (int, float)) and math.isfinite(h) and h >= dt):
        raise ValueError(f"{name}: trend_horizon_s = {h!r} must be None or at least one sample ({dt} s)")
    return opts


def _bands(ref: np.ndarray, band: float) -> tuple[np.ndarray, np.ndarray]:
    """Per mode the search interval: ±band, capped at the geometric midpoints to its neighbours."""
    lo, hi = ref / (1 + band), ref * (1 + band)
    mid = np.sqrt(ref[1:] * ref[:-1])
    lo[1:] = np.maximum(lo[1:], mid)
    hi[:-1] = np.minimum(hi[:-1], mid)
    return lo, hi


def periodogram_look(seg: np.ndarray, dt: float, ref: np.ndarray, band: float, zeta: float,
                     pair_edges: bool = False):
    """Peaks, floor and per-mode acceleration variances from the Hann periodogram of ``seg``.

    Returns (peak rad/s (m,), r̂ (m/s²)², σ² (m,) (m/s²)², (f Hz, one-sided PSD)); a peak NaN where the band
    holds no interior maximum. ``pair_edges``: a band's maximum on its edge toward a neighbour is re-assigned
    with the neighbour's peak (:func:`_pair_edge_peaks`).
    """
    n = seg.size
    nfft = 4 * int(2 ** math.ceil(math.log2(n)))
    f, p = scipy.signal.periodogram(seg, fs=1.0 / dt, window="hann", nfft=nfft, detrend="constant")
    w = 2 * math.pi * f
    lo, hi = _bands(ref, band)
    outside = np.ones(w.size, dtype=bool)
    for a, b in zip(lo, hi, strict=True):
        outside &= ~((w >= a) & (w <= b))
    # a periodogram bin of white noise is its PSD × an exponential variable, whose median is ln 2 × its mean
    floor = (float(np.median(p[outside & (w > 0)])) if np.any(outside & (w > 0)) else float(np.median(p))) / math.log(2)
    r = floor / (2 * dt)                    # one-sided PSD of white noise of variance r: 2rΔt
    m = ref.size
    peak = np.full(m, np.nan)
    var = np.zeros(m)
    df = f[1] - f[0]
    lp = np.log(np.maximum(p, 1e-300))
    for i in range(m):
        sel = np.flatnonzero((w >= lo[i]) & (w <= hi[i]))
        if sel.size < 3:
            continue
        var[i] = max(float(np.sum(p[sel] - floor) * df), 0.0)
        j = sel[np.argmax(p[sel])]
        if j in (sel[0], sel[-1]):
            continue
        peak[i] = _vertex(f, lp, j)
    if pair_edges:
        peak = _pair_edge_peaks(w, f, p, lp, peak, lo, hi, ref)
    return peak, r, var, (f, p)


def _vertex(f: np.ndarray, lp: np.ndarray, j: int) -> float:
    """The parabola's vertex through log p at bins j − 1, j, j + 1, in rad/s."""
    a, b, c = lp[j - 1], lp[j], lp[j + 1]
    den = a - 2 * b + c
    off = 0.5 * (a - c) / den if den < 0 else 0.0
    return 2 * math.pi * (f[j] + off * (f[1] - f[0]))


def _pair_edge_peaks(w, f, p, lp, peak, lo, hi, ref) -> np.ndarray:
    """Peaks of a close pair assigned together: a mode whose band's maximum lies on its edge toward a neighbour
    (the geometric midpoint of the two estimates) takes the largest local maximum of the periodogram between
    the neighbour's own (interior) peak and the mode's far edge, other than the neighbour's.

    The midpoint splits the pair's ground between the two current estimates; after a step of the pair, the
    stepped mode's new peak can lie beyond it (the issue's −7 % step of modes 2–4: mode 3's true 20.46 rad/s
    against a midpoint of 20.2–20.4) and the mode sees no peak at all until its estimate has walked there.
    A mode whose band holds only its neighbour's skirt takes a ripple of it (a noise maximum or a side lobe):
    one look's strike, which the restart rule's ``restart_after`` looks in a row and its running scale absorb
    (the design seeds' drifts were unchanged to ±0.1× the bound, docs/measured/tracking_ambient.md)."""
    out = peak.copy()
    m = ref.size
    bin_w = w[1] - w[0]
    maxima = None
    for i in range(m):
        if np.isfinite(peak[i]):
            continue
        sel = np.flatnonzero((w >= lo[i]) & (w <= hi[i]))
        if sel.size < 3:
            continue
        j = sel[np.argmax(p[sel])]
        # only an edge capped at the midpoint to a neighbour (`_bands` caps both sides of a pair or neither,
        # so the band then meets the neighbour's): a maximum on a band's own ±band edge is no pair's
        if j == sel[0] and i > 0 and np.isfinite(peak[i - 1]) and lo[i] == hi[i - 1]:
            a, b = peak[i - 1], hi[i]                                    # toward the lower neighbour
        elif j == sel[-1] and i < m - 1 and np.isfinite(peak[i + 1]) and hi[i] == lo[i + 1]:
            a, b = lo[i], peak[i + 1]                                    # toward the upper neighbour
        else:
            continue
        if maxima is None:
            maxima = scipy.signal.find_peaks(p)[0]                          # the periodogram's local maxima
        k = maxima[(w[maxima] > a) & (w[maxima] < b)]
        # not the neighbour's own maximum (the bin its vertex lies in)
        k = k[np.abs(w[k] - (a if j == sel[0] else b)) > bin_w]
        if k.size:
            out[i] = _vertex(f, lp, int(k[np.argmax(p[k])]))
    return out


def visible(var: np.ndarray, r: float, ref: np.ndarray, band: float, dt: float) -> np.ndarray:
    """Per mode: its variance above the floor exceeds the white floor's own variance in its band (a mode the
    window can see; white noise alone or a zero record shows none)."""
    lo, hi = _bands(ref, band)
    return var > r * 2 * dt * (hi - lo) / (2 * math.pi)


def modes_to_restart(modes, deviation: np.ndarray, scale, floor: float, d_log: np.ndarray, strikes: np.ndarray,
                     hist_d: list[list[float]], opts: SharedOptions) -> list[tuple[int, float]]:
    """The restart rule both ambient filters share: which modes restart at the window's peak this look.

    A mode's disagreement with the window's peak is judged against its running robust scale
    s_i = median|d| / 0.6745 of its last 30 agreeing looks' log-ratios d = ln(peak / ω̂) (∞ before three):
    mode i disagrees when |deviation_i| > max(restart_gate · s_i · scale_i, floor) (``akf_ambient``: the
    deviation in rad/s, scale ω̂, floor the window's resolution; ``rpem_ambient``: the same, ω̂ carried back to
    the window's middle by its rate, the floor 2π/T with a rate in θ, else none). A disagreement is a strike,
    an agreement clears the strikes and joins the history; ``restart_after`` strikes in a row restart the
    mode. ``strikes`` and ``hist_d`` are updated in place.

    Returns
    -------
    list of (int, float)
        (mode, s_i) of each mode to restart, in the order of ``modes``; its strikes are cleared. A restart
        touches only its own mode's state, so the caller applies them after the look.
    """
    restarts = []
    for i in modes:
        s_i = np.median(np.abs(hist_d[i])) / 0.6745 if len(hist_d[i]) >= 3 else np.inf
        if abs(deviation[i]) > max(opts.restart_gate * s_i * scale[i], floor):
            strikes[i] += 1
        else:
            strikes[i] = 0
            hist_d[i] = (hist_d[i] + [float(d_log[i])])[-30:]
        if strikes[i] >= opts.restart_after:
            strikes[i] = 0
            restarts.append((i, s_i))
    return restarts


def slosh_look(logw: np.ndarray, weights: np.ndarray, dt_block: float, f_band: tuple[float, float],
               gate: float) -> tuple[float, float]:
    """The common modulation of tracked log-frequencies from their differenced spectrum.

    ``logw`` (n, m) block means of ln ω̂ᵢ every ``dt_block`` s; c = Σᵢ wᵢ ln ω̂ᵢ / Σ wᵢ (``weights`` wᵢ, the
    modes' information), differenced: a drift becomes a constant, a step one sample, a walk white, and a
    modulation a sin(2πft) stays a line of variance (a²/2)·(2 sin(πfΔ) sinc(fΔ))² (Δ = ``dt_block``, block
    means). The Hann periodogram's largest maximum in ``f_band`` (Hz, parabolic on log p) is the modulation
    when it is interior and exceeds ``gate`` × the median bin outside its main lobe (±2 bins, up to the
    blocks' Nyquist: the differenced walk is white there); its power over the lobe above that median,
    divided by the line's factor, is a²/2.

    Returns
    -------
    (f Hz, a²/2)
        NaN and 0 when no maximum passes the gate.
    """
    c = logw @ (weights / weights.sum())
    d = np.diff(c)
    n = d.size
    if n < 8:
        return math.nan, 0.0
    nfft = 8 * int(2 ** math.ceil(math.log2(n)))
    f, p = scipy.signal.periodogram(d, fs=1.0 / dt_block, window="hann", nfft=nfft, detrend="constant")
    sel = np.flatnonzero((f >= f_band[0]) & (f <= f_band[1]))
    if sel.size < 3:
        return math.nan, 0.0
    j = sel[np.argmax(p[sel])]
    lp = np.log(np.maximum(p, 1e-300))
    den = lp[j - 1] - 2 * lp[j] + lp[j + 1]
    fp = f[j] + (0.5 * (lp[j - 1] - lp[j + 1]) / den if den < 0 else 0.0) * (f[1] - f[0])
    lobe = np.abs(f - fp) <= 2.0 / (n * dt_block)
    floor = float(np.median(p[(f > 0) & ~lobe]))
    if j in (sel[0], sel[-1]) or not p[j] > gate * floor:
        return math.nan, 0.0
    power = float(np.sum(np.maximum(p[lobe] - floor, 0.0)) * (f[1] - f[0]))
    x = math.pi * fp * dt_block
    line = (2 * math.sin(x) * (math.sin(x) / x if x > 0 else 1.0)) ** 2
    return float(fp), power / line


def _gamma(phi: np.ndarray, w: np.ndarray, zeta: float) -> np.ndarray:
    """Γᵢ = Aᵢ⁻¹(Φᵢ − I)[0, 1]ᵀ, shape (m, 2): the held unit force's effect over one sample."""
    g = np.empty((w.size, 2))
    g[:, 0] = -2 * zeta / w * phi[:, 0, 1] - (phi[:, 1, 1] - 1.0) / (w * w)
    g[:, 1] = phi[:, 0, 1]
    return g


def _modal_response(f: np.ndarray, w: np.ndarray, zeta: float, dt: float) -> np.ndarray:
    """G_i(e^{j2πfΔt}) = C_i(zI − Φ_i)⁻¹Γ_i: a unit held force's way to mode i's acceleration, (len(f), m)."""
    phi, _ = modal_transition(w, zeta, dt)
    g = _gamma(phi, w, zeta)
    z = np.exp(2j * math.pi * f * dt)[:, None]
    a, b, c, d = phi[:, 0, 0], phi[:, 0, 1], phi[:, 1, 0], phi[:, 1, 1]
    det = (z - a) * (z - d) - b * c
    x0 = ((z - d) * g[:, 0] + b * g[:, 1]) / det           # (zI − Φ)⁻¹Γ, adjugate over determinant
    x1 = (c * g[:, 0] + (z - a) * g[:, 1]) / det
    return -(w * w) * x0 - 2 * zeta * w * x1


ALPHAS = np.linspace(0.0, 1.0, 11)     # the direct term's share of the floor, d² = α r̂


def _sign_codes(m: int) -> np.ndarray:
    """Every sign pattern of b₂…bₘ relative to b₁ (b₁ > 0), shape (2^(m−1), m)."""
    codes = np.arange(2 ** (m - 1))
    return np.column_stack([np.ones(codes.size)] + [np.where((codes >> i) & 1, -1.0, 1.0) for i in range(m - 1)])


def whittle_losses(spectrum, w: np.ndarray, zeta: float, dt: float, var: np.ndarray, r: float) -> np.ndarray:
    """Whittle's loss of one white force behind every mode, for every sign pattern, α and sign of d.

    Σ log M + p/M over the periodogram p (every fourth bin of ``periodogram_look``'s 4× zero-padded one, the
    bins of the unpadded window: nearly independent) under M(f) = 2Δt(|Σᵢ sᵢ|bᵢ|Gᵢ + d|² + r_v), |bᵢ| from each
    mode's band variance (σᵢ² = ωᵢ|bᵢ|²/(4ζ) per unit force), d = ±√(α r̂), r_v = (1 − α) r̂ (the floor r̂ holds
    the direct term and the sensor noise). Shape (2^(m−1), len(ALPHAS), 2): [pattern, α, sign of d].
    """
    f, p = spectrum
    keep = np.flatnonzero(f > 0)[::4]
    f, p = f[keep], p[keep]
    G = _modal_response(f, w, zeta, dt)
    mag = np.sqrt(np.maximum(4 * zeta * var / (w * dt), 0.0))
    B = (_sign_codes(w.size) * mag) @ G.T                                    # (patterns, bins)
    d = np.sqrt(ALPHAS * r)[:, None] * np.array([1.0, -1.0])[None, :]        # (α, sign)
    rv = np.maximum((1 - ALPHAS) * r, 1e-12 * r)
    M = 2 * dt * (np.abs(B[:, None, None, :] + d[None, :, :, None]) ** 2 + rv[None, :, None, None])
    return np.sum(np.log(M) + p / M, axis=-1)


def single_force_from_losses(losses: np.ndarray, w: np.ndarray, zeta: float, dt: float, var: np.ndarray,
                             r: float):
    """The gains b (m,), direct term d and sensor variance r_v at the least of ``losses``
    (:func:`whittle_losses`, one look's or a forgetting sum of several)."""
    code, a, ds = np.unravel_index(int(np.argmin(losses)), losses.shape)
    mag = np.sqrt(np.maximum(4 * zeta * var / (w * dt), 0.0))
    d = (1.0 if ds == 0 else -1.0) * math.sqrt(ALPHAS[a] * r)
    return _sign_codes(w.size)[code] * mag, d, max((1 - ALPHAS[a]) * r, 1e-12 * r)


def fit_single_force(spectrum, w: np.ndarray, zeta: float, dt: float, var: np.ndarray, r: float):
    """One white force behind every mode from one window: signed gains b (m,), direct term d and sensor
    variance r_v, maximising Whittle's likelihood (:func:`whittle_losses`) over the signs of b₂…bₘ relative to
    b₁, α on a grid of 11 and the sign of d. The signs decide where the spectrum has its zeros between modes,
    which a sum of independent modes does not have.
    """
    return single_force_from_losses(whittle_losses(spectrum, w, zeta, dt, var, r), w, zeta, dt, var, r)


def _restart(x: np.ndarray, P: np.ndarray, j: int, ja: int | None, w0: float, resolution: float,
             rate_var: float) -> None:
    """Start (or restart) frequency state ``j`` at ``w0`` with 1σ max(1 % ω, resolution/4), uncorrelated with
    the rest; its rate state ``ja`` (if any) at 0 ± the stated rate. In place."""
    for i, v0, var0 in ((j, w0, max(0.01 * w0, resolution / 4) ** 2), (ja, 0.0, rate_var * w0 * w0)):
        if i is None:
            continue
        x[i] = v0
        P[i, :] = 0.0
        P[:, i] = 0.0
        P[i, i] = var0


@dataclass
class _Run:
    freq: np.ndarray
    var: np.ndarray
    started: np.ndarray
    n_restarts: int
    n_pulses: int
    seen: np.ndarray
    n_swaps: int = 0


def ambient_filter(y: np.ndarray, dt: float, prior: np.ndarray, opts: Options) -> _Run:
    """The filter of the module docstring over the record; per sample the frequency states and variances.

    State [ξ₁, ξ̇₁, …, ξₘ, ξ̇ₘ, ω₁…ωₘ, (ω̇₁…ω̇ₘ), u₁…u_f]: the forces u of the current sample are states (white, so
    they are predicted as 0 with their variance), which carries the direct term and its correlation with
    the oscillators' drive without a cross-covariance: ``single``: one force, mode gains b, direct term d;
    ``diagonal``: one force per mode, no direct term (it is then in r).
    """
    m, n = prior.size, y.size
    zeta = float(opts.damping_ratio)
    W, hop = _window_samples(opts, dt, prior)
    horizon = opts.horizon_s if opts.horizon_s is not None else W * dt
    nu2 = opts.rate_rel_per_s ** 2 * horizon
    resolution = 2 * math.pi / (W * dt)       # the window's Fourier resolution, rad/s
    single = opts.force_model == "single"
    trend = opts.frequency_model == "trend"
    slosh = opts.frequency_model == "slosh"
    nf = 1 if single else m
    na = m if trend else 0
    iq, iv, iw = 2 * np.arange(m), 2 * np.arange(m) + 1, 2 * m + np.arange(m)
    ia = 3 * m + np.arange(na)
    iu = 3 * m + na + np.arange(nf)
    ns = 3 * m + na + nf + (2 if slosh else 0)
    i_s, i_sd = ns - 2, ns - 1               # "slosh": the shared modulation s and its rate (the last two)
    if slosh:
        period = 2 * math.pi / float(np.min(prior))
        f_band = (1.0 / (opts.slosh_periods[1] * period), 1.0 / (opts.slosh_periods[0] * period))
        block = max(1, int(round(opts.slosh_periods[0] * period / 8 / dt)))   # 8 blocks per shortest period
        first_look = int(round(opts.slosh_periods[1] * period / 2 / dt))      # history before the first look
        memory = int(round(2 * opts.slosh_periods[1] * period / dt))          # two of the longest periods
        zeta_s = float(opts.slosh_damping)
        omega_s = q_s = 0.0
        phi_s = np.eye(2)
        k_on = 0
    # the rate's prior spread is the stated rate; its walk lets it change by that much over the trend horizon
    rate_var = opts.rate_rel_per_s ** 2
    trend_h = opts.trend_horizon_s if opts.trend_horizon_s is not None else 10 * W * dt
    x = np.zeros(ns)
    x[iw] = prior
    scale = float(np.std(y[:W])) or 1.0
    P = np.zeros((ns, ns))
    P[iq, iq] = (scale / prior ** 2) ** 2
    P[iv, iv] = (scale / prior) ** 2
    P[iw, iw] = (0.1 * prior) ** 2
    P[ia, ia] = opts.rate_rel_per_s ** 2 * prior[:na] ** 2
    gains = np.zeros((m, nf))            # force j's per-sample drive of mode i, tip acceleration units
    direct = np.zeros(nf)
    gains[np.arange(m), np.arange(m) if not single else 0] = scale * np.sqrt(4 * zeta / (prior * dt) / m)
    r = scale ** 2
    P[iu, iu] = 1.0
    F = np.eye(ns)
    F[iu, iu] = 0.0
    if trend:
        F[iw, ia] = dt
    Q = np.zeros((ns, ns))
    Q[iu, iu] = 1.0
    Hrow = np.zeros(ns)
    freq = np.full((n, m), np.nan)
    var = np.full((n, m), np.nan)
    started = np.zeros(n, dtype=bool)
    seen = np.zeros((n, m), dtype=bool)
    seen_now = np.zeros(m, dtype=bool)
    hist_d: list[list[float]] = [[] for _ in range(m)]
    strikes = np.zeros(m, dtype=int)
    n_restarts = n_pulses = looks = n_swaps = 0
    acc = None                           # single force: the forgetting sum of Whittle's losses
    on = False
    for k in range(n):
        g1 = 1.0 + x[i_s] if slosh else 1.0
        if k > 0:
            wb = x[iw]
            w = wb * g1
            phi, dphi = modal_transition(w, zeta, dt)
            g = _gamma(phi, w, zeta)
            xi = x[:2 * m].reshape(m, 2)
            F[iq, iq], F[iq, iv], F[iv, iq], F[iv, iv] = phi[:, 0, 0], phi[:, 0, 1], phi[:, 1, 0], phi[:, 1, 1]
            dx = np.einsum("mab,mb->ma", dphi, xi)
            F[iq, iw], F[iv, iw] = dx[:, 0] * g1, dx[:, 1] * g1
            if slosh:
                F[iq, i_s], F[iv, i_s] = dx[:, 0] * wb, dx[:, 1] * wb
                F[i_s:, i_s:] = phi_s
            drive = gains @ x[iu]
            F[iq[:, None], iu] = g[:, :1] * gains
            F[iv[:, None], iu] = g[:, 1:] * gains
            x[:2 * m] = (np.einsum("mab,mb->ma", phi, xi) + g * drive[:, None]).ravel()
            if trend:
                x[iw] += dt * x[ia]
            if slosh:
                x[i_s:] = phi_s @ x[i_s:]
                Q[i_sd, i_sd] = q_s * dt
            x[iu] = 0.0
            Q[iw, iw] = nu2 * dt * wb * wb
            Q[ia, ia] = (rate_var / trend_h * dt * w * w)[:na]
            P = F @ P @ F.T + Q
        g1 = 1.0 + x[i_s] if slosh else 1.0
        wb = x[iw]
        w = wb * g1
        Hrow[iq] = -w * w
        Hrow[iv] = -2 * zeta * w
        dh = -2 * w * x[iq] - 2 * zeta * x[iv]            # ∂h/∂ωᵢ of the effective frequencies
        Hrow[iw] = dh * g1
        if slosh:
            Hrow[i_s] = dh @ wb
        Hrow[iu] = direct
        h = float(Hrow[iq] @ x[iq] + Hrow[iv] @ x[iv] + direct @ x[iu])
        PH = P @ Hrow
        S = float(Hrow @ PH) + r
        e = y[k] - h
        if on and e * e > opts.pulse_gate * S:
            n_pulses += 1
            infl = opts.pulse_inflation * e * e
            P[iq, iq] += infl / w ** 4
            P[iv, iv] += infl / w ** 2
        else:
            K = PH / S
            x = x + K * e
            P = P - np.outer(K, PH)
            P = 0.5 * (P + P.T)
        if k + 1 >= W and (k + 1 - W) % hop == 0:
            g1 = 1.0 + x[i_s] if slosh else 1.0
            ref = x[iw] * g1 if on else prior
            peak, r_floor, var_i, spec = periodogram_look(y[k + 1 - W:k + 1], dt, ref, opts.band, zeta)
            ok = np.isfinite(peak)
            seen_now = ok & visible(var_i, r_floor, ref, opts.band, dt)
            w_now = np.where(ok, peak, ref) if not on else ref
            mag = np.sqrt(np.maximum(4 * zeta * var_i / (w_now * dt), 0.0))
            if single:
                if opts.fit_memory_looks > 1 or looks % opts.refit_looks == 0:
                    loss = whittle_losses(spec, w_now, zeta, dt, var_i, max(r_floor, 1e-30))
                    acc = loss if acc is None else (1 - 1 / opts.fit_memory_looks) * acc + loss
                if looks % opts.refit_looks == 0:
                    b, d, r = single_force_from_losses(acc, w_now, zeta, dt, var_i, max(r_floor, 1e-30))
                    signs = np.sign(b)
                    signs[signs == 0] = 1.0
                    direct[0] = d
                else:
                    r = max(r_floor - direct[0] ** 2, 1e-12 * r_floor)
                gains[:, 0] = np.where(mag > 0, signs * mag, gains[:, 0])
            else:
                gains[np.arange(m), np.arange(m)] = np.where(mag > 0, mag, gains[np.arange(m), np.arange(m)])
                r = max(r_floor, 1e-30)
            looks += 1
            if not on:
                x[iw] = w_now
                for i in range(m):
                    _restart(x, P, iw[i], ia[i] if trend else None, w_now[i], resolution, rate_var)
                on = True
                k_on = k
            else:
                d_log = np.log(peak / ref)
                for i, _ in modes_to_restart(np.flatnonzero(ok), peak - ref, ref, resolution, d_log, strikes,
                                             hist_d, opts):
                    _restart(x, P, iw[i], ia[i] if trend else None, peak[i] / g1, resolution / g1, rate_var)
                    n_restarts += 1
                order = np.argsort(x[iw], kind="stable")
                if slosh and np.any(order != np.arange(m)):
                    # two modes crossed (a close pair moved by the modulation): the labels follow the prior's
                    # order, so the crossed modes' states, gains and restart records swap back
                    idx = np.arange(ns)
                    for block_i in (iq, iv, iw) + ((iu,) if not single else ()):
                        idx[block_i] = block_i[order]
                    x, P = x[idx], P[np.ix_(idx, idx)]
                    if single:
                        gains[:, 0] = gains[order, 0]
                    else:
                        gains[np.arange(m), np.arange(m)] = np.diag(gains)[order]
                    strikes = strikes[order]
                    hist_d = [hist_d[i] for i in order]
                    n_swaps += 1
                if slosh and k - k_on >= first_look:
                    # the modulation from the tracks' own history: its frequency and intensity (covariance
                    # matching), the oscillator's stationary variance q/(4ζΩ³) set to the detected a²/2
                    hist = freq[max(k_on, k - memory):k]
                    nb = hist.shape[0] // block
                    logw = np.log(hist[hist.shape[0] - nb * block:]).reshape(nb, block, m).mean(axis=1)
                    f_pk, v_s = slosh_look(logw, 1.0 / np.maximum(var[k - 1] / freq[k - 1] ** 2, 1e-30),
                                           block * dt, f_band, opts.slosh_gate)
                    if np.isfinite(f_pk):
                        if 2 * math.pi * f_pk != omega_s:
                            omega_s = 2 * math.pi * f_pk
                            phi_s = modal_transition(np.array([omega_s]), zeta_s, dt)[0][0]
                        q_s = 4 * zeta_s * omega_s ** 3 * v_s
                        if P[i_s, i_s] == 0.0:
                            P[i_s, i_s], P[i_sd, i_sd] = v_s, omega_s ** 2 * v_s
                    else:
                        q_s = 0.0
        started[k] = on
        seen[k] = seen_now
        if slosh:                           # ωᵢ = ω̄ᵢ(1 + s): its variance through the Jacobian [1 + s, ω̄ᵢ]
            g1, wb = 1.0 + x[i_s], x[iw]
            freq[k] = wb * g1
            var[k] = g1 * g1 * np.diag(P)[iw] + 2 * g1 * wb * P[iw, i_s] + wb * wb * P[i_s, i_s]
        else:
            freq[k] = x[iw]
            var[k] = np.diag(P)[iw]
    return _Run(freq, var, started, n_restarts, n_pulses, seen, n_swaps)


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    opts = make_options(Options, options, name)
    out = ambient_filter(y, dt, prior, opts)
    k = np.flatnonzero(out.started)
    std = np.sqrt(np.clip(out.var[k], 0.0, None))
    return Track(k * dt, out.freq[k], std, out.seen[k] & (std <= DETERMINED_REL_STD * out.freq[k]),
                 message=f"{name}: {out.n_restarts} restarts, {out.n_pulses} pulse samples"
                         + (f", {out.n_swaps} swaps" if out.n_swaps else ""),
                 extra={"n_restarts": out.n_restarts, "n_pulses": out.n_pulses, "n_swaps": out.n_swaps})
