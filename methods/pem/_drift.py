"""Does the record have one frequency per mode? Successive segments fitted alone, and their agreement.

A structure whose stiffness depends on its amplitude (a clamp, a joint, a Duffing spring) or changes over
time has no single "frequency": a fit to the whole record averages it, and its white-noise std describes
the noise only. :func:`segment_drift` fits K successive, disjoint segments with :func:`methods.pem.identify`
(from the whole record's answer) and tests, per mode, whether their frequencies ω̂ₖ agree within their
robust std sₖ (``extra["residual_check"]["robust_std_rad_s"]``, or the white-noise std of a segment whose
residual is white):

    ω̄ = Σ ω̂ₖ/sₖ² / Σ 1/sₖ²,   χ² = Σₖ (ω̂ₖ − ω̄)²/sₖ²  ~  χ²_{K−1}  when the frequency is constant.

With K ≥ 3 segments the amplitude line's slope β_a (below) is tested too, against its std from the sₖ
(one dof: the power against a monotone drift that the χ² on K − 1 dof spreads thin; a half-record of the
softening beam whose mode 2 drifted by 16 of its std between halves passed the χ² alone), each test at α/2.
When the p-value is below α the mode drifts: the report gives ω̂ against the segments' mid-times and
envelope amplitudes âₖ (the mode's fitted amplitude aᵢe^{−ζωt} at the segment's middle, m/s²), the
weighted lines ω = ω₀ + β_t t and ω = ω₀ + β_a a² (the Duffing backbone's form for small shifts,
ω(a) ≈ ω₀(1 + 3εa²/(8ω₀²)); ω₀ is then the small-amplitude frequency), by ``numpy.polyfit`` with weights 1/sₖ
and its unscaled covariance (the slopes' std from the sₖ alone), and the amplitude and time the whole record's
frequency corresponds to: a_ref = √((ω̂ − ω₀)/β_a), t_ref where the segments' log-envelope line reaches it.

The spread between segments beyond their own std, τ² = max(0, (χ² − (K − 1))/(Σwₖ − Σwₖ²/Σwₖ)),
wₖ = 1/sₖ² (the DerSimonian–Laird between-segment variance), is how far "the frequency" of a drifting
mode moves over the record: :func:`attach` adds it to the reported std of a drifting mode,
σ² = σ²_robust + τ², and says which amplitude the frequency refers to.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import scipy.special

from methods.pem import _chirp
from methods.pem.predictor import modal_basis

MIN_SEGMENT_SAMPLES = 64
REPORTS = ("small_amplitude", "record")   # what a drifting mode reports (Options.drift_frequency)
DRIFT_ALPHA = 0.05       # level of the per-mode drift test (a false alarm widens one std by τ)
INFO_DECAYS = 5.0        # the drift test and the backbone fit read the record up to 5/(ζω) of its most slowly
                         # decaying mode: beyond it lies 0.28 % of any mode's frequency information
                         # (∫_T^∞ t²e^{−2σt}dt / ∫_0^∞ = e^{−x}(1 + x + x²/2), x = 2σT = 10), and fitting
                         # segments of noise alone made a long record's test 30× the fit's cost
MAX_INFLATION = 5.0      # ω₀ of the backbone fit is reported where its std is at most this × the record's
LACK_OF_FIT_ALPHA = 0.05  # the amplitude line is "not straight within its errors" below this p (_backbone_check)
SCATTER_ALPHA = 0.05     # the segments scatter about the backbone fit beyond their std below this p (chirp_scatter)
NONLINEAR_ALPHA = 0.01   # the record shows a backbone (some mode's κ ≠ 0) below this p, Bonferroni over the modes


@dataclass
class DriftReport:
    """Per-segment frequencies and the per-mode drift test of :func:`segment_drift` (arrays K × m or m)."""

    t_mid_s: np.ndarray                 # (K,) segment mid-times from the record's start
    frequencies: np.ndarray             # (K, m) ω̂ₖ, rad/s (NaN where the segment did not determine the mode)
    std: np.ndarray                     # (K, m) robust std sₖ, rad/s
    amplitude_m_s2: np.ndarray          # (K, m) envelope amplitude at the segment's middle
    chi2: np.ndarray                    # (m,)
    p_value: np.ndarray                 # (m,) the test's p: 2·min(χ²'s, the slope's) (Bonferroni), K ≥ 3
    drifting: np.ndarray                # (m,) bool: p < alpha
    slope_per_s: np.ndarray             # (m,) β_t, rad/s per s
    slope_per_s_std: np.ndarray
    slope_per_amp2: np.ndarray          # (m,) β_a, rad/s per (m/s²)²
    slope_per_amp2_std: np.ndarray
    small_amplitude_rad_s: np.ndarray   # (m,) ω₀ of the amplitude line: the frequency as a → 0
    small_amplitude_std: np.ndarray     # the line's std, times √(χ²_line/(K − 2)) when the line is
                                        # rejected at 5 % (Birge's ratio; never narrowed)
    tau_rad_s: np.ndarray               # (m,) between-segment spread τ (0 when the segments agree)
    whole_record: np.ndarray            # (m,) the whole record's frequencies
    reference_amplitude_m_s2: np.ndarray  # (m,) where the whole-record frequency sits on the amplitude line
    reference_time_s: np.ndarray        # (m,) and on the time line
    slope_p_value: np.ndarray           # (m,) two-sided p of the amplitude line's slope (its WLS std)
    lack_of_fit_p: np.ndarray           # (m,) the amplitude line's lack-of-fit test (:func:`_backbone_check`)
    line_std_at_zero: np.ndarray        # (m,) its weighted-least-squares std at a = 0, scaled by the reduced χ²
    small_amplitude_model_error: np.ndarray  # (m,) δ: ω₀'s change to a bent backbone where the line is
                                        # rejected, else 0
    notes: list[str] = field(default_factory=list)

    def summary(self) -> list[str]:
        """One line per mode: constant (and the test), or drifting with its trend and reference point."""
        return list(self.notes)


def segment_drift(y, dt: float, prior, n_segments: int = 4, alpha: float = DRIFT_ALPHA,
                  whole=None, *, fit, **options) -> DriftReport:
    """Fit ``n_segments`` disjoint successive segments of ``y`` and test each mode's frequency for drift.

    Parameters
    ----------
    y : array_like, shape (N,)
        Tip acceleration, m/s².
    dt : float
        Sample interval, s.
    prior : array_like, shape (m,)
        A-priori frequencies, rad/s (for the whole-record fit).
    n_segments : int
        K ≥ 2; every segment needs at least :data:`MIN_SEGMENT_SAMPLES` samples.
    alpha : float
        Level of the χ² agreement test per mode.
    whole : Estimate, optional
        The whole record's pem estimate, if already computed with the same options.
    fit : callable
        pem's fit, ``fit(y, dt, prior, **options) -> Estimate`` (:func:`methods.pem.identify`). The fit calls
        this test and this test calls the fit: it is handed down by its caller (``methods.pem._fit``, whose
        :func:`~methods.pem._fit.segment_drift` is the public one) rather than imported back.
    **options
        :class:`methods.pem.Options` fields, for every fit.

    Returns
    -------
    DriftReport
    """
    identify = fit
    y = np.asarray(y, float)
    k_seg = int(n_segments)
    if k_seg < 2:
        raise ValueError(f"n_segments = {n_segments} must be at least 2")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha = {alpha} must be in (0, 1)")
    seg = y.size // k_seg
    if seg < MIN_SEGMENT_SAMPLES:
        raise ValueError(f"n_segments = {n_segments} leaves {seg} samples per segment of a {y.size}-sample "
                         f"record; at least {MIN_SEGMENT_SAMPLES} are needed")
    prior = np.asarray(prior, float)
    options = {**options, "drift_segments": 0}     # each fit is of one frequency per mode: no drift test in it
    whole = identify(y, dt, prior, **options) if whole is None else whole
    start = np.where(whole.converged_per_mode, whole.frequencies, prior)
    if not np.all(np.diff(start) > 0):
        start = prior
    m = prior.size
    freq, std, amp = (np.full((k_seg, m), np.nan) for _ in range(3))
    t_mid = (np.arange(k_seg) * seg + seg / 2) * dt
    for k in range(k_seg):
        part = y[k * seg:(k + 1) * seg]
        est = identify(part, dt, start, **options)
        check = est.extra.get("residual_check")
        ok = est.converged_per_mode & np.isfinite(est.frequencies)
        if check is None or not ok.any():
            continue
        s = np.asarray(check.get("robust_std_rad_s", est.std), float)     # a white segment: its std
        freq[k] = np.where(ok, est.frequencies, np.nan)
        std[k] = np.where(ok & (s > 0), s, np.nan)
        amp[k] = _envelope(part, dt, est.frequencies, est.extra["damping"])
    # a segment that starts after a mode's informative part (INFO_DECAYS/σᵢ, σᵢ from the whole record) holds
    # < 0.3 % of its frequency information: a "detection" there is noise (a long record in AR(1) noise gave
    # mode 2 at 15.8 rad/s, 10⁵ of its std from 20.24, and a false drift)
    horizon = _horizons(whole)
    late = (np.arange(k_seg)[:, None] * seg * dt) >= horizon[None, :]
    freq[late], std[late], amp[late] = np.nan, np.nan, np.nan
    return _report(t_mid, freq, std, amp, whole.frequencies, alpha)


def _envelope(part: np.ndarray, dt: float, w: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Each mode's envelope at the segment's middle, √(Aᵢ² + Bᵢ²)·e^{−ζᵢωᵢt_mid}: the amplitudes by linear
    least squares on the modal basis at the fitted (ω, ζ) (:func:`methods.pem.predictor.modal_basis`)."""
    n = part.size
    ok = np.isfinite(w) & np.isfinite(z)
    out = np.full(w.size, np.nan)
    if not ok.any():
        return out
    phi = modal_basis(w[ok], z[ok], dt, n)
    c = np.linalg.lstsq(phi, part, rcond=None)[0]
    a = np.hypot(c[0:-1:2], c[1:-1:2]) * np.exp(-z[ok] * w[ok] * dt * n / 2)
    out[ok] = a
    return out


def _line(x: np.ndarray, f: np.ndarray, s: np.ndarray) -> tuple[float, float, float, float]:
    """(slope, its std, intercept, its std) of the weighted line f = intercept + slope·x (weights 1/s).

    The std is the larger of two: the weighted least-squares one from the sₖ alone, times Birge's ratio
    √(χ²/(K − 2)) when the K points scatter about the line more than their sₖ allow (χ² beyond its 95 %
    point on K − 2 dof), and the delete-one-segment jackknife's, √((K − 1)/K · Σⱼ(θ̂₍ⱼ₎ − θ̄)²) with θ̂₍ⱼ₎
    the line without segment j (K ≥ 3; Efron & Stein 1981). The first trusts the sₖ; the jackknife does not:
    it sees a segment that pulls the line beyond its sₖ (a close pair of modes beating inside a segment,
    coloured noise the segment's robust std underrates), which moved ω₀ of the softening beam's mode 3 by
    2–3 of the first's std (docs/uncertainty.md)."""
    coef, cov = np.polyfit(x, f, 1, w=1.0 / s, cov="unscaled")
    k = x.size
    dof = k - 2
    chi2 = float(np.sum(((f - np.polyval(coef, x)) / s) ** 2))
    birge = np.sqrt(chi2 / dof) if dof > 0 and chi2 > scipy.special.chdtri(dof, 0.05) else 1.0
    var = np.diag(cov) * birge ** 2
    if k >= 3:
        loo = np.array([np.polyfit(np.delete(x, j), np.delete(f, j), 1, w=1.0 / np.delete(s, j))
                        for j in range(k)])
        var = np.fmax(var, (k - 1) / k * np.sum((loo - loo.mean(axis=0)) ** 2, axis=0))
    return float(coef[0]), float(np.sqrt(var[0])), float(coef[1]), float(np.sqrt(var[1]))


def _backbone_check(x: np.ndarray, f: np.ndarray, s: np.ndarray,
                    alpha: float = LACK_OF_FIT_ALPHA) -> tuple[float, float, float]:
    """Is the backbone straight in x = a² within the points' errors, and what does it cost at a = 0 if not?

    Returns (p, σ₀, δ) for the K ≥ 3 points (xₖ, fₖ ± sₖ), all NaN with fewer:

    - p: the lack-of-fit test of the weighted line, χ² = Σ((fₖ − f̂ₖ)/sₖ)² on K − 2 dof;
    - σ₀: the line's std at x = 0 from ``numpy.polyfit(..., cov=True)``'s weighted least squares,
      √[(XᵀWX)⁻¹]₀₀ — its leverage at zero amplitude — scaled by the reduced χ²/(K − 2) where that exceeds 1
      (the points' scatter about the line, not only their stated sₖ);
    - δ: where the test rejects at ``alpha``, the change of ω₀ from the straight backbone to a bent one,
      the larger of two: the quadratic in a² (the next term of a Duffing spring's backbone,
      ω(a) ≈ ω₀(1 + 3εa²/(8ω₀²)) to first order) and the line in a (a stiffness ∝ |x|x, a loose clamp:
      frequency shift ∝ a). 0 where the line fits.

    The straight backbone's ω₀ moves by δ when the backbone bends the way either physical form says; the
    points cannot tell which, and the line they reject is no better. On a beam whose shift is ∝ a, two
    2.5 s windows' ω₀ differed by 28 of their stds without δ (experiments.benchmarks.windows)."""
    if x.size < 3:
        return np.nan, np.nan, np.nan
    w = 1.0 / s
    lin, cov = np.polyfit(x, f, 1, w=w, cov="unscaled")
    dof = x.size - 2
    chi2 = float(np.sum(((f - np.polyval(lin, x)) / s) ** 2))
    p = float(scipy.special.chdtrc(dof, chi2))
    std0 = float(np.sqrt(cov[1, 1] * max(1.0, chi2 / dof)))
    if p >= alpha:
        return p, std0, 0.0
    quad = np.polyfit(x, f, 2, w=w)
    in_a = np.polyfit(np.sqrt(x), f, 1, w=w)
    return p, std0, float(max(abs(quad[-1] - lin[-1]), abs(in_a[-1] - lin[-1])))


def _report(t_mid, freq, std, amp, whole, alpha) -> DriftReport:
    m = freq.shape[1]
    keys = ("chi2", "p", "p_slope", "bt", "bt_s", "ba", "ba_s", "w0", "w0_s", "tau", "a_ref", "t_ref", "lof_p",
            "w0_s0", "w0_model")
    out = {key: np.full(m, np.nan) for key in keys}
    drifting = np.zeros(m, bool)
    notes = []
    for i in range(m):
        ok = np.isfinite(freq[:, i]) & np.isfinite(std[:, i]) & np.isfinite(amp[:, i])
        if ok.sum() < 2:
            notes.append(f"mode {i + 1}: fewer than two segments determine it; no drift test")
            continue
        f, s, t, a = freq[ok, i], std[ok, i], t_mid[ok], amp[ok, i]
        w = 1.0 / s ** 2
        wbar = np.sum(w * f) / np.sum(w)
        chi2 = float(np.sum(w * (f - wbar) ** 2))
        p = float(scipy.special.chdtrc(ok.sum() - 1, chi2))     # χ² survival, as scipy.stats.chi2.sf
        out["chi2"][i], out["p"][i] = chi2, p
        out["tau"][i] = np.sqrt(max(0.0, (chi2 - (ok.sum() - 1)) / (w.sum() - (w ** 2).sum() / w.sum())))
        if ok.sum() >= 3:
            out["bt"][i], out["bt_s"][i], _, _ = _line(t, f, s)
            if np.ptp(a) > 0:
                out["ba"][i], out["ba_s"][i], out["w0"][i], out["w0_s"][i] = _line(a ** 2, f, s)
                out["lof_p"][i], out["w0_s0"][i], out["w0_model"][i] = _backbone_check(a ** 2, f, s)
                a2 = (whole[i] - out["w0"][i]) / out["ba"][i] if out["ba"][i] != 0 else np.nan
                if a2 > 0 and np.all(a > 0):
                    out["a_ref"][i] = np.sqrt(a2)
                    decay, log_a0 = np.polyfit(t, np.log(a), 1)
                    out["t_ref"][i] = (np.log(out["a_ref"][i]) - log_a0) / decay if decay != 0 else np.nan
        if ok.sum() >= 3 and np.ptp(a) > 0:
            # the amplitude line's slope against its weighted-least-squares std (sₖ alone): one dof, the
            # test with the power against a monotone drift; with the χ² on K − 1 dof, each at α/2
            coef, cov = np.polyfit(a ** 2, f, 1, w=1.0 / s, cov="unscaled")
            out["p_slope"][i] = float(scipy.special.erfc(abs(coef[0]) / np.sqrt(2 * cov[0, 0])))
            p = min(1.0, 2 * min(p, out["p_slope"][i]))
            out["p"][i] = p
        if p >= alpha:
            notes.append(f"mode {i + 1}: one frequency over the record ({ok.sum()} segments agree: "
                         f"chi2 = {chi2:.3g}, p = {p:.2g})")
            continue
        drifting[i] = True
        note = (f"mode {i + 1}: the frequency drifts (segments disagree: chi2 = {chi2:.3g} on {ok.sum() - 1} "
                f"dof, p = {p:.2g}): {', '.join(f'{x:.6g}' for x in f)} rad/s at "
                f"{', '.join(f'{x:.3g}' for x in t)} s")
        if np.isfinite(out["ba"][i]):
            note += (f", amplitudes {', '.join(f'{x:.3g}' for x in a)} m/s²; omega = {out['w0'][i]:.6g} "
                     f"± {out['w0_s'][i]:.2g} + ({out['ba'][i]:.3g} ± {out['ba_s'][i]:.2g})·a² rad/s")
        if np.isfinite(out["a_ref"][i]):
            note += (f"; the whole record's {whole[i]:.6g} rad/s is the frequency at an amplitude of about "
                     f"{out['a_ref'][i]:.3g} m/s² (t ≈ {out['t_ref'][i]:.3g} s)")
        notes.append(note)
    return DriftReport(t_mid, freq, std, amp, out["chi2"], out["p"], drifting, out["bt"], out["bt_s"],
                       out["ba"], out["ba_s"], out["w0"], out["w0_s"], out["tau"], np.asarray(whole, float),
                       out["a_ref"], out["t_ref"], out["p_slope"], out["lof_p"], out["w0_s0"],
                       out["w0_model"], notes)


def attach(est, y: np.ndarray, dt: float, prior: np.ndarray, opts, fit):
    """The estimate with the drift test when its residual is not white (``extra["residual_check"]``):
    :func:`segment_drift` with ``opts.drift_segments`` segments, its report in ``extra["drift"]``. A mode
    whose segments disagree reports, by ``opts.drift_frequency``:

    - ``"small_amplitude"`` (when its amplitude line is determined): ω₀ ± its std, the frequency of the
      linear structure (a → 0), which is what a model or a prior describes; the whole record's average stays
      in ``extra["drift"]["whole_record"]``, with the amplitude it refers to;
    - ``"record"``, or a line that is not determined: the whole record's average, σ = √(σ² + τ²).

    ``extra["drift_reported"]`` says which, per mode ("" for a mode whose segments agree: the frequency at
    the amplitude the record holds), and so does the message. A white residual, ``drift_segments = 0`` or a
    record too short for the segments: the estimate unchanged. ``fit``: pem's fit (see :func:`segment_drift`)."""

    check = est.extra.get("residual_check")
    k = int(opts.drift_segments)
    if k < 2 or check is None or check["white"] or y.size // k < MIN_SEGMENT_SAMPLES:
        return est
    n_info = informative_samples(y.size, dt, est)
    cut = n_info < y.size and n_info // k >= MIN_SEGMENT_SAMPLES
    if cut:
        y = y[:n_info]
        est = dataclasses.replace(est, message=est.message + f"; drift test on the first {n_info * dt:.4g} s "
                                  f"({n_info} samples: the modes have decayed into the noise after it)")
    options = {**dataclasses.asdict(opts), "drift_segments": 0}
    report = segment_drift(y, dt, prior, k, whole=est, fit=fit, **options)
    extra = {**est.extra, "drift": dataclasses.asdict(report)}
    # Only the modes whose segments disagree at level DRIFT_ALPHA change (a stationary record keeps its
    # answer in 19 modes of 20; τ for every mode made the std of coloured-noise records 15 points too wide).
    drifting = report.drifting & est.converged_per_mode & np.isfinite(est.std)
    if opts.drift_frequency == "small_amplitude":
        return _small_amplitude(est, y, dt, extra, report, drifting)
    if not drifting.any():
        return dataclasses.replace(est, extra=extra)
    tau = np.where(np.isfinite(report.tau_rad_s), report.tau_rad_s, 0.0)
    widened = drifting & (tau > 0)
    std = np.where(widened, np.hypot(est.std, tau), est.std)
    notes = [report.notes[i] for i in np.flatnonzero(drifting)]
    if widened.any():
        notes.append("the std includes the spread between segments (modes "
                     + ", ".join(str(i + 1) for i in np.flatnonzero(widened)) + ")")
    extra["drift_reported"] = np.where(drifting, "record", "").tolist()
    return dataclasses.replace(est, std=std, extra=extra, message="; ".join([est.message, *notes]))


def _horizons(est) -> np.ndarray:
    """Per mode, the end of its informative part, :data:`INFO_DECAYS`/σᵢ (σᵢ = ζᵢωᵢ of ``est``), s; inf where
    σᵢ is not positive and finite."""
    z = np.asarray(est.extra.get("damping", np.full(est.frequencies.size, np.nan)), float)
    sigma = z * np.asarray(est.frequencies, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(sigma) & (sigma > 0), INFO_DECAYS / sigma, np.inf)


def informative_samples(n: int, dt: float, est) -> int:
    """Samples up to the longest horizon (:func:`_horizons`) of the converged modes of ``est``, at most ``n``;
    ``n`` when none converged or a converged mode's decay rate is not positive and finite (no cut)."""
    h = _horizons(est)[est.converged_per_mode]
    if h.size == 0 or not np.all(np.isfinite(h)):
        return int(n)
    return int(min(n, np.ceil(h.max() / dt)))


def chirp_segment_frequencies(omega0, kappa, zeta, n_segments: int, n_per_segment: int, dt: float) -> np.ndarray:
    """(K, m): the frequency a constant-frequency fit of each of K successive segments of ``n_per_segment``
    samples returns when the record is the backbone chirp ω(t) = ω₀ + κe^{−2σt}, σ = ζω₀ (:mod:`_chirp`).

    Such a fit weighs the phase error by the envelope², w(t) = e^{−2σt}, so its frequency is the weighted
    regression slope of the phase θ(t) = ∫ω on t; by parts that is the kernel mean

        ω̄ₖ = ∫ ω(t) K(t) dt / ∫ K(t) dt,   K(t) = ∫_t^{t₁} w(s)(s − t̄) ds ≥ 0 over the segment [t₀, t₁),

    t̄ the w-weighted mean time (a parabola peaking mid-segment for w = 1), here on the segment's samples."""
    omega0, kappa, zeta = (np.atleast_1d(np.asarray(v, float)) for v in (omega0, kappa, zeta))
    sigma = zeta * omega0
    # the kernel mean of e^{−2σt} over a segment is e^{−2σt₀} times that over [0, n·dt) (K is shift-
    # invariant): :func:`methods.pem._chirp.record_weight`; an envelope that grows without bound (ζ < 0 at
    # the fit's bound) gives a non-finite prediction, which chirp_scatter leaves out
    weight = _chirp.record_weight(sigma, int(n_per_segment), dt)
    k = np.arange(int(n_segments), dtype=float)[:, None]            # segment k starts at t₀ = k·n·Δt
    with np.errstate(over="ignore", invalid="ignore"):
        return omega0 + kappa * np.exp(-2.0 * sigma * dt * k * n_per_segment) * weight


def chirp_scatter(fit: dict, report: DriftReport, n_per_segment: int, dt: float) -> tuple[np.ndarray, ...]:
    """(χ², K, p) per mode: do the segments' frequencies scatter about the backbone fit's prediction
    (:func:`chirp_segment_frequencies`) no more than their robust std sₖ allow?

        χ² = Σₖ ((ω̂ₖ − ω̄ₖ)/sₖ)²  ~  χ²_K  when the backbone fit describes the record,

    over the K ≥ 2 segments that count for the mode (NaN with fewer). The fit's ω₀ is far more precise than
    any segment, so its own error is left out (the test is then slightly conservative)."""
    f, s = np.asarray(report.frequencies, float), np.asarray(report.std, float)
    k_seg, m = f.shape
    pred = chirp_segment_frequencies(fit["frequencies"], fit["kappa"], fit["damping"], k_seg, n_per_segment, dt)
    ok = np.isfinite(f) & np.isfinite(s) & (s > 0) & np.isfinite(pred)
    chi2 = np.where(ok, ((f - pred) / np.where(ok, s, 1.0)) ** 2, 0.0).sum(axis=0)
    dof = ok.sum(axis=0)
    p = np.where(dof >= 2, scipy.special.chdtrc(np.maximum(dof, 1), chi2), np.nan)
    return np.where(dof >= 2, chi2, np.nan), dof, p


def extrapolation_std(chirp_std, report: DriftReport, scatter=None) -> np.ndarray:
    """The std of a reported small-amplitude frequency ω₀, per mode:

        σ² = σ_x² + δ²,   σ_x = σ_c, or max(σ_c, σ₀) where the amplitude line's lack of fit rejects it,
        σ_c = σ_chirp · √(χ²_s/K) where the segments scatter about the backbone fit (p_s < 0.05), else σ_chirp,

    σ_chirp the backbone fit's robust std: the extrapolation's own (κ is free, so the leverage of zero
    amplitude is in it, and the sandwich reads the residual's colour). ``scatter`` = (χ²_s, K, p_s) of
    :func:`chirp_scatter` (None: not scaled): the segments, each fitted alone, against the frequencies the
    fit's backbone says they should have; beyond their std (p_s < :data:`SCATTER_ALPHA`) the backbone does
    not describe how the frequency moves, and σ_chirp is scaled by Birge's ratio √(χ²_s/K), the segments'
    scatter about it rather than their formal std. σ₀ is the segments' amplitude line's std at a = 0 scaled
    by their scatter about it, and δ the change of ω₀ to a bent backbone (:func:`_backbone_check`), both
    where the segments say the straight backbone the chirp assumes is wrong (p < :data:`LACK_OF_FIT_ALPHA`).
    Taking max(σ_chirp, σ₀) everywhere made every AR(1) and Duffing mode's coverage 98–100 % (mismatch grid,
    seed 777): the segments' line is 3–6× less precise than the one fit of the whole record. A mode whose
    segments do not determine the line (fewer than 3 of them) keeps σ_c."""
    s = np.asarray(chirp_std, float)
    if scatter is not None:
        chi2, dof, p = (np.asarray(v, float) for v in scatter)
        scaled = (p < SCATTER_ALPHA) & (dof > 0)                                   # NaN p: not scaled
        s = np.where(scaled, s * np.sqrt(np.fmax(1.0, np.where(scaled, chi2, 0.0) / np.maximum(dof, 1))), s)
    rejected = np.asarray(report.lack_of_fit_p, float) < LACK_OF_FIT_ALPHA         # NaN: not rejected
    line = np.asarray(report.line_std_at_zero, float)
    model = np.nan_to_num(np.asarray(report.small_amplitude_model_error, float), nan=0.0)
    return np.hypot(np.where(rejected & np.isfinite(line), np.fmax(s, line), s), np.where(rejected, model, 0.0))


def _small_amplitude(est, y, dt, extra, report, drifting):
    """``drift_frequency="small_amplitude"``: every mode whose small-amplitude frequency the record
    determines reports it, ω₀ of the backbone-chirp fit (:func:`methods.pem._chirp.fit`, in
    ``extra["backbone"]``) ± :func:`extrapolation_std` (``extra["backbone"]["reported_std"]``), whether or
    not its segments disagree. "Determines": the fit's own std of ω₀ at most :data:`MAX_INFLATION` × the
    constant-frequency fit's robust std; beyond that the envelope hardly decays over the record, amplitude
    and time are one direction, and the mode keeps the record's average and its std, widened by the spread
    τ between its segments where they disagree (its frequency at the amplitude the record holds).
    Reporting ω₀ for the drifting modes only mixed
    two quantities: a window whose drift test missed a drift answered its own average, many of its std
    from the other window's ω₀ (docs/uncertainty.md §5)."""


    fit = _chirp.fit(y, dt, est.frequencies, np.asarray(est.extra["damping"], float))
    extra["backbone"] = fit
    s = fit["std"]
    determined = est.converged_per_mode & np.isfinite(fit["frequencies"]) & np.isfinite(s) & (s > 0)
    # A record whose backbone fit finds a shift κ in some mode (|κ|/std beyond the two-sided NONLINEAR_ALPHA
    # level, Bonferroni over the modes) shows a structure whose frequencies follow the amplitude: then every
    # mode answers ω₀, however wide, since a record average refers to this record's amplitude only. A slow
    # mode's average moves between two windows by more than its own spread (mismatch grid mode 1: halves
    # 0.0016 rad/s apart, 4σ of an honest record-average std; docs/uncertainty.md §4).
    z = np.abs(np.asarray(fit["kappa"], float)) / np.asarray(fit["kappa_std"], float)
    limit = scipy.special.ndtri(1.0 - NONLINEAR_ALPHA / (2.0 * max(z.size, 1)))
    nonlinear = bool(np.any(determined & np.isfinite(z) & (z > limit)))
    fit["nonlinear"] = nonlinear
    use = determined & (nonlinear | (s <= MAX_INFLATION * est.std))
    scatter = chirp_scatter(fit, report, y.size // report.t_mid_s.size, dt)
    fit["scatter_chi2"], fit["scatter_segments"], fit["scatter_p"] = scatter
    s = fit["reported_std"] = extrapolation_std(s, report, scatter)
    # a drifting mode that keeps its record average carries the spread between its segments, as with "record"
    tau = np.where(drifting & ~use & np.isfinite(report.tau_rad_s), report.tau_rad_s, 0.0)
    # a kept mode answers its record average from the same fit, ω + k̄κ (the frequency a constant-frequency
    # fit of it alone returns), not the constant-frequency fit's: there every other drifting mode's misfit
    # stays in the residual, leaks into the mode's frequency (mode 1 of the mismatch grid's Duffing cells:
    # 0.0004 rad/s, 1.6 × its spread, on the noise-free record) and swells its Newey–West std (~4×)
    average = np.asarray(fit["record_average"], float)
    average_std = np.asarray(fit["record_average_std"], float)
    own = np.isfinite(average) & np.isfinite(average_std) & (average_std > 0)
    fit["record_average_used"] = (~use & own & est.converged_per_mode).tolist()
    freq = np.where(use, fit["frequencies"], np.where(own, average, est.frequencies))
    std = np.where(use, s, np.hypot(np.where(own, average_std, est.std), tau))
    notes = [report.notes[i] for i in np.flatnonzero(drifting)]
    if use.any():
        notes.append("reported at small amplitude (ω₀ of the backbone fit ω(t) = ω₀ + κ·exp(−2ζωt), its std "
                     "with the extrapolation's and a bent backbone's) for mode" + ("s " if use.sum() > 1 else " ")
                     + ", ".join(str(i + 1) for i in np.flatnonzero(use)))
    kept = est.converged_per_mode & ~use
    if kept.any():
        notes.append("the record does not determine the small-amplitude frequency of mode"
                     + ("s " if kept.sum() > 1 else " ") + ", ".join(str(i + 1) for i in np.flatnonzero(kept))
                     + ": its record average is reported")
    extra["drift_reported"] = np.where(use, "small_amplitude", np.where(drifting, "record", "")).tolist()
    return dataclasses.replace(est, frequencies=freq, std=std, extra=extra,
                               message="; ".join([est.message, *notes]))
