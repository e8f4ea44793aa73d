"""From a model's poles to the m physical modes: the step every peer identifier shares.

A subspace, ERA, LSCE or DMD fit returns the poles of a model of some order: the structural modes, the
sensor offset (a real pole at s = 0), and poles that only fit the noise. A practitioner picks the physical
ones by eye on a stabilisation diagram: oscillatory, stable, lightly damped, below Nyquist, carrying the
signal's energy, near where the modes were expected. :func:`pick_modes` writes that judgement down once, so
that every peer is scored on the same rule and the library alone decides the poles:

1. **Physical poles.** Continuous-time poles sₖ = σₖ + iωdₖ (a discrete pole z becomes s = log(z)/Δt).
   Kept: oscillatory (ωd > 0; conjugates are one mode, the one with ωd > 0 is kept), below Nyquist
   (|s| < π/Δt), damping ζ = −σ/|s| within ``damping_bounds``. The lower bound is slightly negative
   (−0.02 by default): the modes here have ζ = 0.005, and on a short noisy record an estimate of such a
   lightly damped mode straddles zero; a clearly growing pole is not physical.
2. **Energy.** The record is fitted by least squares with the candidates' damped sinusoids and a constant
   (the offset): y(tₖ) ≈ c + Σⱼ Re(aⱼ e^{sⱼ tₖ}); the energy of pole j is Σₖ |Re(aⱼ e^{sⱼ tₖ})|², its
   share of the record. Noise poles carry little; the modes carry most (scipy.linalg.lstsq).
3. **Detection.** A candidate counts only if its energy stands out of the noise: Eⱼ/σ̂² > 2 ln(N/2α) with
   σ̂² the residual variance of that least-squares fit and α = 1 %. For white noise alone the largest of
   the N/2 independent (cos, sin) projections has energy/σ² ~ χ²₂, so P(max > x) ≈ (N/2) e^{−x/2}: the
   threshold is the level pure noise exceeds with probability α (the fft's peak test, the same rule). A
   record without a mode — all zero, a constant, white noise — yields no candidate, hence no mode.
4. **Assignment.** The ``m`` most energetic candidates within the search band of some prior
   (|log(ω/priorᵢ)| ≤ log(1 + band)) get prior entries by :func:`methods.labels.assign`: in frequency
   order (labels never cross; with all m found, the sorted answer), the slots of missing modes told by the
   common scale factor of the found ones. A candidate whose slot is uncertain or out of band is not
   placed; a prior mode with no placed candidate gets NaN and ``converged_per_mode`` False ("too few
   physical poles"). (A nearest-prior matching, ``linear_sum_assignment`` on |log ω − log prior|, crossed
   labels in about 5 % of the trials of ``experiments.benchmarks.basin`` under a common prior error.)
5. **Confirmation by the record** (``confirm``, on by default). A library's pole can be placed and still be wrong:
   an SSI or LSCE model of a heavily damped mode, or of a mode a spare pole shares, puts it 1–50 % away. The record
   says where the pole belongs: its maximum-likelihood fit by damped sinusoids and a constant (pem's variable
   projection, :func:`methods.pem.separable_fit`, ≤ 30 evaluations per fit), with σ each mode's std(ω) at the
   optimum. That model (:func:`reference_fit`) is the fewest components that explain the record: the placed poles,
   then, while the residual fails pem's whiteness check (:func:`methods.pem.residual_check`), the library's other
   detected poles one at a time by energy, then at most ``CONFIRM_LINES`` lines at the residual's periodogram peak
   (a mode the library missed, which would otherwise pull its neighbours). A placed mode counts as determined only
   when (a) that model explains the record — its residual is white; (b) the record locates it — σ ≤ 1 % of ω,
   pem's "determined by the data"; (c) the library's pole lies within a few of the record's σ of the record's
   frequency, σ from the ML fit's own Fisher information: |ω_library − ω_record| ≤ max(3σ, 0.5 % ω − 3σ)
   (:func:`confirm_tolerance`; the threshold follows what the record says, the second term is the success rule's
   0.5 % floor less the record's own 3σ); and (d) it holds its slot. The slots stand when the record agrees
   with every placed pole — (a), (c) and its fitted component above the noise by step 3's test, however large
   its σ — and needed no other component within a prior's band; otherwise the confirmed modes and those other
   in-band components are assigned again (:func:`same_slots`) and each confirmed mode must keep its slot — a
   spare pole can crowd a true mode out of the m most energetic and shift the labels above it by one slot,
   where the record confirms a right frequency in the wrong slot. The frequency returned stays the library's; a
   mode that fails keeps its number with ``converged_per_mode`` False, and ``Estimate.extra`` carries the
   record's fit beside it (``record_fit_rad_s``, ``record_fit_std_rad_s``, ``confirmed``,
   ``record_other_components_rad_s``). On the random structures of ``experiments.benchmarks.basin`` this keeps
   "called determined but wrong" ≤ 1 % of structures for every peer (docs/measured/peers.md).

Frequencies returned are the undamped natural frequencies |sⱼ| (what the benchmark scores: |λ| of the
plant's eigenvalues), with ζⱼ = −Re sⱼ/|sⱼ|.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from methods import labels, pem
from methods.estimate import Estimate, check_inputs, failed, flat_record, make_options
from methods.pem.search import IDENTIFIED_REL_STD


@dataclass(frozen=True)
class Picked:
    """The physical modes picked from a model's poles, in prior order.

    Attributes
    ----------
    frequencies, damping : ndarray, shape (m,)
        Natural frequency |s| (rad/s) and damping ratio of the pole assigned to each prior mode; NaN where
        none was.
    found : ndarray of bool, shape (m,)
        Whether a physical pole was assigned to each prior mode.
    n_candidates : int
        How many poles passed steps 1 and 3 (physical, and standing out of the noise).
    energy : ndarray, shape (m,)
        The least-squares energy (m²/s⁴ summed over samples) of each assigned pole; NaN where none was.
    """

    frequencies: np.ndarray
    damping: np.ndarray
    found: np.ndarray
    n_candidates: int
    energy: np.ndarray = field(default_factory=lambda: np.array([]))
    confirmed: np.ndarray | None = None
    record_fit: np.ndarray | None = None
    record_fit_std: np.ndarray | None = None
    record_white: bool | None = None
    record_others: np.ndarray | None = None

    @property
    def determined(self) -> np.ndarray:
        """Per mode: found, and confirmed by the record where the check ran (step 5)."""
        return self.found if self.confirmed is None else self.found & self.confirmed

    @property
    def message(self) -> str:
        missing = int((~self.found).sum())
        if missing == 0:
            text = f"{self.found.size} modes picked from {self.n_candidates} physical poles"
        else:
            text = (f"too few physical poles: {missing} of {self.found.size} modes missing "
                    f"({self.n_candidates} candidates)")
        unconfirmed = np.flatnonzero(self.found & ~self.determined)
        if unconfirmed.size:
            text += (f"; mode{'s' if unconfirmed.size > 1 else ''} {', '.join(str(i + 1) for i in unconfirmed)} "
                     f"not confirmed by the record's maximum-likelihood fit"
                     + (" (its residual is not white: the record holds what the poles do not)"
                        if self.record_white is False else ""))
        return text


def continuous_poles(z, dt: float) -> np.ndarray:
    """Continuous-time poles s = log(z)/Δt of discrete-time poles z (z = 0 has none and is dropped)."""
    z = np.asarray(z, dtype=complex).reshape(-1)
    z = z[np.abs(z) > 0]
    return np.log(z) / dt


def physical(s, dt: float, damping_bounds=(-0.02, 0.2)) -> np.ndarray:
    """The oscillatory, stable-enough poles below Nyquist of continuous-time poles ``s``, one per conjugate
    pair (the one with positive imaginary part), sorted by frequency.

    A pole given only with a negative imaginary part (its conjugate missing) still counts once.
    """
    s = np.asarray(s, dtype=complex).reshape(-1)
    s = s[np.isfinite(s)]
    s = s.real + 1j * np.abs(s.imag)                   # a conjugate pair folds onto one pole
    w = np.abs(s)
    keep = (s.imag > 0) & (w < np.pi / dt)
    s, w = s[keep], w[keep]
    zeta = -s.real / w
    s = s[(zeta >= damping_bounds[0]) & (zeta <= damping_bounds[1])]
    s = np.sort_complex(s)
    # fold conjugate duplicates: after |Im|, a pair is two equal entries
    if s.size > 1:
        dup = np.r_[False, np.abs(np.diff(s)) <= 1e-9 * np.abs(s[1:])]
        s = s[~dup]
    return s


FALSE_ALARM = 0.01      # α of the detection test (step 3)
# step 5 (confirm_tolerance): the library's pole within 3σ of the record's ML frequency, σ from the fit's Fisher
# information; where the success rule's 0.5 % floor (experiments.report.success) exceeds 6σ, within the floor less
# 3σ for the record's own error
CONFIRM_SIGMAS, CONFIRM_REL_FLOOR, CONFIRM_MARGIN = 3.0, 0.005, 3.0
CONFIRM_EVALUATIONS = 30
CONFIRM_LINES = 2       # the residual's lines the record's fit may add beyond the library's poles
LINE_DAMPING = 0.01     # an added line's starting damping ratio
EXPLAINED = 1e-6        # a residual below this share of the record's rms is rounding, not an unmodelled mode


def energies(s, y, dt: float) -> np.ndarray:
    """Energy of each pole's least-squares component in the record (step 2 of the module docstring)."""
    return _least_squares_components(s, y, dt)[0]


def detected(s, y, dt: float, alpha: float = FALSE_ALARM) -> tuple[np.ndarray, np.ndarray]:
    """Energies of the poles ``s`` in the record and whether each stands out of the noise (step 3)."""
    e, sigma2 = _least_squares_components(s, y, dt)
    threshold = 2.0 * np.log(np.size(y) / (2.0 * alpha))
    return e, (e > 0) & (e > threshold * sigma2)


def _least_squares_components(s, y, dt: float) -> tuple[np.ndarray, float]:
    """Columns e^{σt}cos(ωd t), e^{σt}sin(ωd t) per pole and a constant, fitted by least squares: the
    energy ‖Vⱼ cⱼ‖² of each pole's component, and the residual variance RSS/(N − p)."""
    s = np.asarray(s, dtype=complex)
    y = np.asarray(y, dtype=float)
    if s.size == 0:
        return np.zeros(0), float(np.var(y))
    t = np.arange(y.size) * dt
    env = np.exp(np.outer(t, s.real))
    cols = [np.ones((y.size, 1)), env * np.cos(np.outer(t, s.imag)), env * np.sin(np.outer(t, s.imag))]
    V = np.hstack(cols)
    coef = scipy.linalg.lstsq(V, y, lapack_driver="gelsd")[0]
    k = s.size
    comp = V[:, 1:1 + k] * coef[1:1 + k] + V[:, 1 + k:] * coef[1 + k:]
    rss = float(np.sum((y - V @ coef) ** 2))
    return np.sum(comp**2, axis=0), rss / max(y.size - V.shape[1], 1)


def confirm_tolerance(w_rad_s, std_rad_s) -> np.ndarray:
    """How far a library's pole may lie from the record's maximum-likelihood frequency and be confirmed:

        tol = max(3σ, 0.005ω − 3σ),

    σ the ML fit's std from its own Fisher information, σ̂√diag((JᵀJ)⁻¹) (the record's information, about
    the CRLB). The first term is a test of "the same mode": the library's estimate and the ML one differ by
    their errors, which an estimator within ~2× the bound keeps below 3σ (measured per peer:
    methods/peers/README.md); it grows as the record says less. The second keeps a high-SNR mode (0.5 % ω
    beyond 6σ) whose library bias is many σ but inside the success rule's 0.5 % floor: a pole that far from
    the ML frequency, whose own error is below 3σ, is still within the floor of the truth."""
    w, s = np.asarray(w_rad_s, float), np.asarray(std_rad_s, float)
    return np.maximum(CONFIRM_SIGMAS * s, CONFIRM_REL_FLOOR * w - CONFIRM_MARGIN * s)


def confirm(cand, chosen, y, dt: float, energy=None):
    """Step 5 for the candidates ``cand[chosen]``: per chosen pole whether the record confirms it and whether
    it agrees with it (the fit white, the fitted component above the noise by step 3's test, and the pole
    within :func:`confirm_tolerance`, however large σ), the
    record's ω and its std; whether the fit's residual is white (None: no fit); and the frequencies of the
    fit's other components (rad/s: the library's spare poles and the residual's lines it needed).

    ``cand`` are every detected candidate's poles, ``energy`` their least-squares energies (step 2); the
    record's model is :func:`reference_fit`'s. Where the fit is impossible (fewer samples than unknowns, a
    singular basis) nothing is confirmed.
    """
    y = np.asarray(y, float)
    chosen = np.asarray(chosen, int)
    fitted = reference_fit(cand, chosen, y, dt, energy)
    if fitted is None:
        nan, no = np.full(len(chosen), np.nan), np.zeros(len(chosen), bool)
        return no, no, nan, nan, None, np.zeros(0)
    w_fit, std, white, others, held = fitted
    w_lib = np.abs(cand[chosen])
    agree = white & held & np.isfinite(std) & (np.abs(w_lib - w_fit) <= confirm_tolerance(w_lib, std))
    return agree & (std <= IDENTIFIED_REL_STD * w_lib), agree, w_fit, std, white, others


def reference_fit(cand, chosen, y, dt: float, energy=None):
    """The record's maximum-likelihood fit that judges the chosen poles: (ω, std of ω) of each chosen pole,
    whether the residual is white, and the frequencies of the fit's other components; None where no fit
    is possible.

    The model starts with the chosen poles alone. While its residual is not white
    (:func:`methods.pem.residual_check`) it grows by one damped sinusoid, each fit started at the last one's
    optimum: first the library's other detected poles, most energetic first, then (at most
    ``CONFIRM_LINES``) the residual's strongest periodogram line — a mode the library missed. The model that
    explains the record with the fewest components is the one to judge by: every spare pole of an
    over-sized model adds four unknowns, and the fit of all of them (57 unknowns in 64 samples for an LSCE
    model) fits the noise, its residual no test of anything; and a mode the library missed pulls its
    neighbours in a fit without it."""
    w, z = np.abs(cand), -cand.real / np.abs(cand)
    order = np.argsort(-energy, kind="stable") if energy is not None else np.arange(cand.size)
    spare = [int(j) for j in order if j not in set(chosen.tolist())]
    w0, z0 = w[chosen], z[chosen]
    lines = 0
    centred = y - y.mean()
    while True:
        fitted = None if y.size < 10 else pem.separable_fit(y, dt, [(0, y.size)], w0, z0, CONFIRM_EVALUATIONS,
                                                            residual=True)
        if fitted is None:
            return None
        w_all, z_all, std_all, e, basis = fitted
        # a residual at rounding level (a noise-free record) leaves nothing to explain: white by definition
        check = None if float(e @ e) <= EXPLAINED**2 * float(centred @ centred) else pem.residual_check(
            e, dt, basis=basis)
        white = check is None or check["white"]
        if white or (not spare and lines == CONFIRM_LINES):
            # which chosen poles the fitted model holds above the noise (step 3's test on its components)
            s_fit = w_all * (-z_all + 1j * np.sqrt(np.clip(1.0 - z_all**2, 0.0, None)))
            held = detected(s_fit, y, dt)[1][:chosen.size]
            return w_all[:chosen.size], std_all[:chosen.size], bool(white), w_all[chosen.size:], held
        if spare:
            j = spare.pop(0)
            w0, z0 = np.r_[w_all, w[j]], np.r_[z_all, z[j]]
        else:
            lines += 1
            w0, z0 = np.r_[w_all, check["peak_rad_s"]], np.r_[z_all, LINE_DAMPING]


def pick_modes(s, y, dt: float, prior, *, band: float = 0.5, damping_bounds=(-0.02, 0.2),
               check: bool = True) -> Picked:
    """Pick one physical pole per prior mode (module docstring: physical poles, energy, assignment).

    Parameters
    ----------
    s : array of complex
        Continuous-time poles of the identified model (rad/s); use :func:`continuous_poles` for z-poles.
    y : ndarray, shape (N,)
        The record the model was fitted to (for the poles' least-squares energies).
    dt : float
        Sample interval, s (Nyquist π/Δt).
    prior : array, shape (m,)
        A-priori frequencies, rad/s.
    band : float
        A pole may match prior ωᵢ when |log(ω/ωᵢ)| ≤ log(1 + band) (0.5: within ωᵢ·1.5^±1, the PEM's band).
    damping_bounds : (float, float)
        Accepted damping ratios ζ = −Re s/|s|.
    check : bool
        Step 5: a placed mode counts only where the record's maximum-likelihood fit confirms it.
    """
    prior = np.asarray(prior, dtype=float).reshape(-1)
    m = prior.size
    cand = physical(s, dt, damping_bounds)
    freq, zeta, energy = np.full(m, np.nan), np.full(m, np.nan), np.full(m, np.nan)
    found = np.zeros(m, dtype=bool)
    if cand.size:
        e, real = detected(cand, y, dt)
        cand, e = cand[real], e[real]
    if cand.size:
        w = np.abs(cand)
        dist = np.abs(np.log(w)[:, None] - np.log(prior)[None, :])      # candidates × prior
        in_band = np.flatnonzero((dist <= np.log1p(band)).any(axis=1))
        top = in_band[np.argsort(-e[in_band], kind="stable")[:m]]
        if top.size:
            lab = labels.assign(w[top], prior, band=band)
            chosen = np.full(m, -1)
            for j, c, ok in zip(top, lab.slot, lab.placed, strict=True):
                if ok:
                    freq[c], zeta[c], energy[c], found[c], chosen[c] = w[j], -cand[j].real / w[j], e[j], True, j
            if check and found.any():
                ok, agree, w_fit, std, white, others = confirm(cand, chosen[found], y, dt, e)
                confirmed, fit, fit_std = np.zeros(m, bool), np.full(m, np.nan), np.full(m, np.nan)
                confirmed[found], fit[found], fit_std[found] = ok, w_fit, std
                in_band = others[(np.abs(np.log(others)[:, None] - np.log(prior)[None, :])
                                  <= np.log1p(band)).any(axis=1)]
                # the slots stand where the record agrees with every placed pole and needs no other in-band
                # component; otherwise they are checked (same_slots)
                if not (agree.all() and in_band.size == 0):
                    confirmed &= same_slots(freq, confirmed, prior, band, in_band)
                return Picked(freq, zeta, found, int(cand.size), energy, confirmed, fit, fit_std, white, others)
    return Picked(freq, zeta, found, int(cand.size), energy)


def same_slots(freq, confirmed, prior, band: float, lines=()) -> np.ndarray:
    """Per slot: does the assignment of the confirmed modes alone put each in the slot it holds?

    The slots were given among the m most energetic candidates, confirmed or not. A library's spare pole can
    carry more least-squares energy than a true mode, crowd it out, and shift the labels above it by one slot:
    an LSCE model of five modes put a noise pole at 44.6 rad/s in the last slot and the true 30.5 in the
    slot of 21.2, where the record confirms 30.5 (it is a mode, only not that one). Assigned again without
    the poles the record does not confirm, such a mode goes elsewhere or is not placed: then it is not
    determined. This only withdraws determinations, never adds one."""
    keep = np.zeros(freq.size, bool)
    idx = np.flatnonzero(confirmed)
    lines = np.asarray(lines, float)
    if idx.size:
        w = np.r_[freq[idx], lines]
        by_freq = np.argsort(w, kind="stable")
        if w.size > prior.size:          # more modes than slots: the slots are not the record's to give
            return keep
        lab = labels.assign(w[by_freq], prior, band=band)
        slot, placed = np.empty(w.size, int), np.empty(w.size, bool)
        slot[by_freq], placed[by_freq] = lab.slot, lab.placed
        keep[idx] = placed[:idx.size] & (slot[:idx.size] == idx)
    return keep


def estimate_extra(picked: Picked, **more) -> dict:
    """The ``Estimate.extra`` entries every peer reports: damping, candidates."""
    checked = {} if picked.confirmed is None else {
        "confirmed": picked.confirmed.tolist(), "record_fit_rad_s": picked.record_fit.tolist(),
        "record_fit_std_rad_s": picked.record_fit_std.tolist(), "record_residual_white": picked.record_white,
        "record_other_components_rad_s": [] if picked.record_others is None else picked.record_others.tolist()}
    return {"damping": picked.damping.tolist(),
            "n_physical_poles": picked.n_candidates, **checked, **more}


def order_rule(m: int, extra: int) -> int:
    """The model order a peer fits by default: one state per mode pair (2m), one for the sensor offset (a
    real pole at z = 1), and ``extra`` spare states that take up the noise (chosen per peer on a tuning
    seed; methods/peers/README.md)."""
    return 2 * m + 1 + max(int(extra), 0)


@dataclass
class PeerOptions:
    """The options every peer shares: its model order and the mode picker's settings.

    A peer's ``Options`` subclasses it, redeclares ``extra_order`` with its tuned default, adds its own
    fields (they follow these) and extends :meth:`check` with their checks.
    """

    order: int | None = None         # model order; None: 2m + 1 + extra_order (clipped to what N allows)
    extra_order: int = 0             # spare states beyond modes and offset (each peer's tuned default)
    band: float = 0.5                # mode picker: a pole matches prior ω within ω·1.5^±1
    min_damping: float = -0.02       # mode picker: accepted damping ratios
    max_damping: float = 0.2
    confirm: bool = True             # mode picker step 5: a mode counts only where the record's fit confirms it

    def check(self) -> None:
        """Validate the options (no record needed); ``ValueError`` naming the bad value."""
        if not self.band > 0:
            raise ValueError(f"band = {self.band} must be positive (relative search band around each prior)")
        if not self.min_damping < self.max_damping:
            raise ValueError(f"min_damping = {self.min_damping} must be below max_damping = {self.max_damping}")
        if self.order is not None and self.order < 1:
            raise ValueError(f"order = {self.order} must be a positive model order")
        if self.extra_order < 0:
            raise ValueError(f"extra_order = {self.extra_order} must be ≥ 0")
        if not isinstance(self.confirm, bool):
            raise ValueError(f"confirm = {self.confirm!r} must be true or false")

    def model_order(self, m: int) -> int:
        """The model order asked for m modes: ``order``, else :func:`order_rule`."""
        return self.order if self.order is not None else order_rule(m, self.extra_order)

    def estimate(self, s, y, dt: float, prior, *, order: int, std=None, **extra) -> Estimate:
        """Pick the modes from continuous-time poles ``s`` of a model of this ``order`` fitted to ``y`` and
        wrap them as an Estimate (``extra`` joins ``Estimate.extra``).

        ``std`` is NaN unless the library itself gives an uncertainty (the Cramér–Rao bound at the estimate
        is not a method's uncertainty and is never used as one).
        """
        prior = np.asarray(prior, dtype=float)
        picked = pick_modes(s, y, dt, prior, band=self.band, damping_bounds=(self.min_damping, self.max_damping),
                            check=self.confirm)
        std = np.full(prior.size, np.nan) if std is None else np.where(picked.found, std, np.nan)
        return Estimate(picked.frequencies, std, converged=bool(picked.determined.all()), iterations=0,
                        message=picked.message, converged_per_mode=picked.determined,
                        extra=estimate_extra(picked, order=int(order), **extra))


def check_peer_options(options_cls, options: dict, method: str):
    """A peer's ``check_options``: its ``options_cls`` built from the keywords (an unknown one named) and
    checked, before any work and without a record."""
    opts = make_options(options_cls, options, method)
    opts.check()
    return opts


def identify_peer(check_options, fit, y, dt, prior, options: dict) -> Estimate:
    """A peer's ``identify``: the inputs checked, the options checked by the peer's ``check_options``, no
    mode from a flat record, then ``fit(y, dt, prior, opts)`` — the library's part, which returns
    :meth:`PeerOptions.estimate` of the model's poles (or :func:`too_short`)."""
    y, dt, prior = check_inputs(y, dt, prior)
    opts = check_options(prior, dt, **options)
    if why := flat_record(y):
        return failed(prior, why)
    return fit(y, dt, prior, opts)


def too_short(prior, n: int, by: str) -> Estimate:
    """No mode: a record of ``n`` samples cannot hold a model of the m modes for the library ``by``."""
    return failed(prior, f"record of {n} samples too short for {np.size(prior)} modes by {by}")
