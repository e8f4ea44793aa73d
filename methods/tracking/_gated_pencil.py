"""``gated_pencil``: a matrix pencil on the Hankel columns that no thruster pulse crosses, on a sliding window,
then the trend stage.

Why. Under attitude-thruster pulses the response is, between two pulses, a free decay; each pulse kicks every
mode to a new amplitude and phase. A window estimator that fits one free decay (pem's output error, ERA,
NExT-ERA, the FFT peak) reads the phase jumps as frequency: a jump Δφ inside a window of length T moves the
estimate by ~Δφ/T, a few % of the 3.2 rad/s mode and ~1 % of the others on 10 s windows — measured, the
same error pattern for every windowed tracker, at 100 and at 1000 µg (noise is not what limits them).

What. On each window of W samples (every H samples):

1. **Pulse detector**: a least-squares AR(``ar_order``) one-step predictor of the window, re-weighted three
   times with Tukey's biweight (scale 1.4826·MAD of the residual, cut-off ``outlier_cut``·scale); the samples
   whose weight is zero are where the free-decay recursion breaks — the pulses (and the odd noise outlier).
2. **Gated Hankel pencil**: the columns c_k = [y(k) … y(k + L)] (L = ``rows``) with no flagged sample in
   k + 1 … k + L — a column that straddles a pulse is dropped; on the kept columns Y₀ = c_k[0 … L − 1],
   Y₁ = c_k[1 … L] satisfy Y₁ = A Y₀ exactly for a free decay, whatever the amplitude and phase of each
   segment. A is estimated in the span of the r = 2m + ``extra_order`` leading left singular vectors of Y₀
   (Hua & Sarkar's matrix pencil / ERA's realisation step, the truncation filtering the noise):
   Â = U_rᵀ Y₁ V_r Σ_r⁻¹; its eigenvalues z give s = log z / Δt. When fewer than 2L columns survive, the
   window determines no mode (the trend stage only predicts); so does a window whose largest singular value
   is under ``detect_ratio`` (3) × their median — a flat spectrum, noise (white noise: 1.2–1.6; the
   thruster records: 16–19 in the median window). L is W/8, grown up to W/3 − 1 while ≥ 2L columns survive
   (:func:`widest_rows`); with ``shrink_rows`` (on by default) it also shrinks, down to the five-period
   window's rows, where the pulse detector's own flags leave fewer than 2L columns and they are isolated pulses
   (their mean pulse-free run at least two slowest periods, the shortest window trusted after a restart): a
   window made long for a close pair of the prior under pulses a few periods apart then determines its modes
   (:func:`shrunk_rows`; under a white force the kick test's splits, not the detector, leave the columns
   short: the rule is silent). With ``capped_rows`` (on by default), where the prior's closest pair asks for
   more than the window's cap (:func:`pair_capped`: a pair the capped window does not resolve, so rows scaled
   from it buy no resolution) and the detector's flags leave fewer than 2L columns, L starts at the
   five-period window's rows and grows from there (pulses too close for ``shrink_rows`` left no columns).
3. **Modes**: the poles with ω_d > 0 and damping in [−0.02, ``max_damping``] are assigned to the modes by
   ``linear_sum_assignment`` on |log ω − log ω_ref| within ``band``, ω_ref the last estimate of each mode
   (the prior at first); a mode without a pole in its band is not determined in that window.
4. **Segment fit** (``refine``, on by default; :mod:`methods.tracking._segments`,
   :func:`methods.pem.separable_fit`): the window cut at the flagged samples into pulse-free runs of ≥
   ``min_segment`` samples (a run whose own basis is near-singular at the start — much shorter than the slowest
   period — is left out, :func:`_fittable`); m damped sinusoids with (ω, ζ) shared by every run and amplitudes,
   phases and offset per run (projected out), fitted by least squares from the pencil's poles (a mode the
   pencil missed: from its last refined value) — the maximum-likelihood fit of the piecewise free decay under
   white noise — with the std of ω from the reduced Jacobian. A refined mode counts when it is within ``band``
   of its last estimate, lightly damped, its std × the window span is under ``max_phase_std`` rad (an energy
   test alike for every frequency: a mode that died away between sparse pulses fails it) — or, within the
   window's resolution 2π/span of another mode, its pole is distinct from every other at 3 combined std
   (``close_pairs``, on by default: the pair's near-collinear basis inflates each member's std) — and it is
   not another mode's pole (:func:`_labelled`).
   **Kicks the detector missed** (``split_kicks``, on by default): a pulse at the noise level (at
   Δt = 0.1 s a 100 N·m pulse is 2–3 × the AR residual's scale) leaves a run that straddles it, whose phase
   jump the shared poles read as frequency. With the poles of that fit fixed (and their first-order
   corrections in both hypotheses, so that a pole error is not read as a kick), each run is tested for one more
   change of its amplitudes and offset (a Chow/sup-F test over every split, family-wise level ``split_level`` per run,
   Bonferroni; binary segmentation ``split_rounds`` deep; :func:`methods.tracking._segments.split_kicks`);
   where a kick is found the runs are split there and the fit repeated. The samples flagged or split in
   earlier windows stay flagged, and a run inside one an earlier window tested clean is not tested again.
   A run whose pieces still reject the free decay after ``split_rounds`` rounds is a continuing force, not
   missed pulses: it stays whole (under a white force every sample is a kick).
5. **Trend stage** (``trend``, on by default; :mod:`methods.tracking._trend`): each window's estimate put at
   the window's centre and carried to the present by a local-linear-trend Kalman filter per mode; with the
   segment fit, a window weighs by its own std: R = ``overlap_inflation``·(W/H)·std² + (``trend_meas_rel``·ω)²
   (consecutive windows share W − H samples; the floor is the model error of a constant-frequency fit), and
   its gate tests the window against its own std, √(std² + (``trend_meas_rel``·ω)²) (``gate_std``). What a
   restart does with the rate is ``trend_restart_rate`` ("keep", as every trend stage; "freeze", an option:
   after the first window the gate refuses, or a re-level after a gap, the windows that may straddle the change
   update the level only and the rate goes back to the one before it — :mod:`methods.tracking._trend`).
   ``trend_memory`` (window spans k, 1 by default; a ``trend_rate_noise`` given wins, None: the other windowed
   trackers' rule from the slowest period): the rate noise that gives the trend filter a time constant of k
   window spans, ``trend_meas_rel``/(k·(W − 1)Δt)² (:func:`methods.tracking._defaults.trend_rate_noise_memory`)
   — a filter that forgets faster than a window follows the overlapping windows' shared errors as a rate.
   ``trend_span_relevel`` (on by default): a window whose span differs from the last used
   window's by more than a factor 2 (``window_from_estimates`` collapsing a capped window) sets the mode's
   level and keeps its rate (:mod:`methods.tracking._trend`, "A change of span").

**The window from the estimates** (``window_from_estimates``, on by default): where the prior's window
(:func:`methods.tracking._defaults.window_s`: five periods of the slowest mode, two beats of the closest pair,
capped at 20 periods) is set by its closest pair, every mode has been determined, and the modes' last estimates
put their closest pair at least ``PAIR_RATIO`` (2) times farther apart than the prior's, the window is two beats
of the estimates' pair, never under five periods of the prior's slowest mode (:func:`estimates_window_s`);
else the prior's. The trend filter's memory (``trend_memory`` window spans) follows it. Why: the prior is a
guess (±5 % on the benchmarks' records), and two prior frequencies that happen to lie close ask for two beats of
a pair that the record does not have — up to 20 periods of the slowest mode — and a window that long straddles
a step for most of its span. Not from the estimates' slowest period: a window shortened by a slowest mode
estimated a few % high only adds noise (a 0.1 s one-mode record, six modes at 1 ms). Causal: window j's length
depends on windows 0 … j − 1 only. ``capped_either`` (on by default): where the prior's closest pair is capped
(:func:`pair_capped`), the pair counts as determined once either of its modes is, and the estimates' closest pair
is taken over the determined modes (:func:`capped_determined`): the capped window does not resolve a pair that
close, the record's pair may lie where the prior's other member is never found, and "every mode determined"
would keep the window at the cap.

**Both window options act only on a pulsed record**: a pulse flagged in at least half the windows so far. Under a
continuing force (a white body force: nothing flagged in 86–100 % of the windows) the window fits one forced
response, which the prior's longer window averages, the estimates of a pair wander (a shorter window there
never converged), and no ring dies away (a short window's "change" is the force).

**A mode's own window** (``own_windows``, an option, off by default: its error rises more than 10 % on 8 of 40
design replicates of its own cell, a level offset after a change and false changes on weak rings): the window is
sized for the slowest mode (five of its periods, ~90 periods of a mode 18 times faster), so after a step with no
pulse after it a fast mode's ring dies away (decay time 1/(ζω)) inside windows whose older part, before the step,
dominates: they hold its old frequency, then determine nothing until the next pulse. Each mode i whose own window —
the window rule for it alone, max(five of its periods, two beats of its nearest neighbour (capped at 20 of its
periods)), never shorter than the model's minimum (:func:`own_window_samples`) — is at most half the window, and
whose decay time 1/(ζω) at its last estimates is under half the window span, is also fitted on the most recent
window of that length (:func:`_own_estimate`: the gated pencil for the start, the segment fit on the short window's
pulse-free runs). Where the short window is one free decay (no pulse flagged in it, by its own detector or by the
long windows': where a pulse follows the change the long window sees it, and a short run between pulses biases the
short fit beyond its std) and its estimate lies more than ``OWN_CHANGE_STD`` (3) combined std from the trend
stage's last output (carried by its rate: a drift is not read as a change; the long window's estimate before the
trend has one), the mode has changed: its level in the trend stage is re-set there (its rate kept, as after a gap:
a rate fitted to a few short windows would carry the level away once the ring has died), and it is fed from its own
window until the long window's start has passed the change (W samples later) — the level only, the rate kept
(``TrendBank.step``'s ``level_only``) — and the first long window that determines the mode after that re-sets its
level (fed short windows, the trend stage would follow the long ones only over its memory, learning the lag as a
rate: 0.1 % off for tens of seconds). Where the mode is only watched for a change, the segment fit is skipped when
the short window's gated-pencil pole (its start) lies within ``OWN_SCREEN_STD`` (1) combined std of the trend's
last output — the std of the mode's last short fit and the trend's: a change needs the fit ``OWN_CHANGE_STD`` (3)
std away, and a fit moves its start by well under two (the tracks identical on every record measured; the option's
extra CPU per sample on the thruster benchmark +49 % → +3–12 %). Causal: both windows end at the present sample.

**The newest ring** (``ring_start``, an option, off by default: near-neutral on the design sets, not better on every
one): the window's Hankel rows are sized for the slowest mode (W/8 or more, ~12 periods of a mode 18 times faster),
so a fast mode whose frequency stepped while its ring was dead is determined again only some hops after the pulse
that rings it: the pencil needs 3(L + 1) samples of the new ring for 2L columns of its own, and the window's fit of a
short ring fails the phase-std test over the whole window (an energy test for a mode that rings throughout). The
window's newest ring — its last pulse-free run, after the last sample the pulse detector flagged, when shorter than
3(L + 1) — holds a mode when it spans ``RING_PERIODS`` (5) of the mode's periods and two beats of its nearest other
mode (:func:`ring_run`), and the mode has not been determined for more than half a window span (the trend stage's
gap: after a step with no ring, or before its first ring). For a held mode, :func:`ring_search` fits the ring alone
(ω of that mode by a 1-D search over its band, every other mode at its last estimate, the amplitudes projected out;
its std from the reduced Jacobian): where the pencil gave the mode no pole that is the segment fit's start (the
default start where that fit is ill-posed), and where the window's fit fails the phase-std test over the window it
passes when the window's std and the ring's own both pass it over the ring's span and the two estimates lie within 3
combined std. Band, labels and trend stage are the default's. Causal: the ring is the window's own last samples.

Under a continuing white force (no pulses) every sample is an input: nothing is flagged and the pencil fits
one free decay to a forced response, as the other window estimators do. Causal: a window's estimate uses its
own samples; the trend stage uses earlier windows only.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from methods import pem
from methods.estimate import flat_record, make_options
from methods.tracking import _defaults, _memory, _segments, _trend
from methods.tracking._track import Track, usable_prior, window_ends

MIN_DAMPING = -0.02
OWN_SCREEN_STD = 1.0        # own_windows: no segment fit where the pencil's pole is this near the trend
OWN_CHANGE_STD = 3.0        # own_windows: a change is a short estimate this many combined std from the trend's
PAIR_RATIO = 2.0            # window_from_estimates: the estimates' closest pair this many times the prior's gap
RING_PERIODS = 5.0          # ring_start: the newest ring holds this many periods of the mode


def estimates_window_s(prior: np.ndarray, ref: np.ndarray, determined: np.ndarray,
                       capped_either: bool = False) -> float:
    """``window_from_estimates``' window span in s: the window rule (:func:`methods.tracking._defaults.window_s`)
    at the prior, unless that window is set by the prior's closest pair (two beats, over ``PERIODS`` periods of
    its slowest mode), every mode has been ``determined`` once, and the estimates ``ref`` put their closest pair
    at least ``PAIR_RATIO`` times farther apart than the prior's — the prior's pair is not the record's; then
    two beats of the estimates' closest pair (capped at ``GAP_CAP_PERIODS`` periods), never under ``PERIODS``
    periods of the prior's slowest mode. Where the window is set by the slowest period (one mode, or no close
    pair in the prior) it is the prior's: the estimates' slowest period is not a better guess than the prior's
    by more than the prior's error, and a shorter window only adds noise.

    ``capped_either`` (:func:`capped_determined`): a capped prior pair counts as determined when either of its
    modes is, and the estimates' closest pair is taken over the determined modes only (the other member's
    reference is still the prior's guess, which the determined one has shown wrong or right)."""
    prior = np.sort(np.asarray(prior, dtype=float))
    span = _defaults.window_s(prior)
    T = _defaults.slowest_period_s(prior)
    base = _defaults.PERIODS * T
    determined = np.asarray(determined, dtype=bool)
    counted = capped_determined(prior, determined) if capped_either else determined
    if prior.size < 2 or span <= base * (1 + 1e-9) or not np.all(counted):
        return span
    est = np.sort(np.asarray(ref, dtype=float)[determined])
    if est.size < 2:
        return span
    gap_prior, gap_est = float(np.min(np.diff(prior))), float(np.min(np.diff(est)))
    if not gap_est >= PAIR_RATIO * gap_prior:
        return span
    beats = min(_defaults.GAP_CYCLES * 2.0 * np.pi / gap_est, _defaults.GAP_CAP_PERIODS * T)
    return min(span, max(base, beats))


def capped_determined(prior, determined: np.ndarray) -> np.ndarray:
    """``capped_either``: ``determined`` with the prior's closest pair counted as determined when either of its
    two modes is, where that pair is capped (:func:`pair_capped`). The capped window does not resolve a pair the
    prior puts that close, so which of the two the record's pole is labelled is the prior's guess; one of them
    determined already shows whether the prior's pair is the record's (``estimates_window_s``' test)."""
    determined = np.asarray(determined, dtype=bool).copy()
    prior = np.asarray(prior, dtype=float)
    if not pair_capped(prior):
        return determined
    i = int(np.argmin(np.diff(prior)))          # the prior is increasing (usable_prior)
    either = determined[i] | determined[i + 1]
    determined[i] = determined[i + 1] = either
    return determined


def pair_capped(prior) -> bool:
    """``capped_rows``: whether the prior's closest pair asks for more than the window rule's cap — two beats
    (``GAP_CYCLES``) of it over ``GAP_CAP_PERIODS`` periods of the slowest mode, a pair closer than a tenth of
    the slowest frequency — so that the window is at the cap and does not resolve the pair."""
    prior = np.sort(np.asarray(prior, dtype=float))
    if prior.size < 2:
        return False
    gap = float(np.min(np.diff(prior)))
    beats = _defaults.GAP_CYCLES * 2.0 * np.pi / gap if gap > 0 else np.inf
    return beats > _defaults.GAP_CAP_PERIODS * _defaults.slowest_period_s(prior)


def own_window_samples(ref: np.ndarray, dt: float, minimum: int) -> np.ndarray:
    """Each mode's own window in samples: the window rule (:func:`methods.tracking._defaults.window_s`) for
    that mode alone — max(``PERIODS`` of its periods, ``GAP_CYCLES`` beats of its nearest neighbour capped at
    ``GAP_CAP_PERIODS`` of its periods) — never under ``minimum`` samples."""
    ref = np.asarray(ref, dtype=float)
    T = 2.0 * np.pi / ref
    span = _defaults.PERIODS * T
    if ref.size > 1:
        gap = np.abs(ref[:, None] - ref[None, :]) + np.diag(np.full(ref.size, np.inf))
        beats = _defaults.GAP_CYCLES * 2.0 * np.pi / np.maximum(gap.min(axis=1), 1e-300)
        span = np.maximum(span, np.minimum(beats, _defaults.GAP_CAP_PERIODS * T))
    return np.maximum(minimum, np.round(span / dt)).astype(int)


@dataclass
class Options:
    """Options of ``gated_pencil`` (module docstring). None: from Δt and the prior, or scaled to the window
    (methods/tracking/_defaults.py): W = 5 periods of the slowest mode (≥ two beats of the closest pair),
    H = W/10, spare poles ``extra_order`` clip(⌊W/4⌋ − 1 − 2m, 2, 8), L = W/8 (grown to W/3 where the pulses
    leave the columns, shrunk to 5/8 of the slowest period where isolated pulses leave too few), AR order
    W/20 within [2m + 2, 2m + 16], min segment max(2(2m + 1), W/25).
    ``split_kicks``: the kick test on the pulse-free runs (module docstring, step 4), at family-wise level
    ``split_level`` per run, ``split_rounds`` rounds of binary segmentation. ``close_pairs``: a resolved pair
    within the window's resolution passes without the phase-std test (step 4, :func:`_labelled`).
    ``window_from_estimates`` (on by default): where the prior's window is two beats of its closest pair and
    the estimates put that pair at least twice as far apart, the window is two beats of the estimates' pair,
    never under five periods of the prior's slowest mode (:func:`estimates_window_s`) — a prior whose two
    modes are nearly equal asks for up to 20 periods of the slowest mode (two beats of a pair that is not
    there), and a window that long needs most of its span to forget a step; the hop, rows, AR order and min
    segment stay the prior's, scaled down with the window (a window the user gives is kept).
    ``shrink_rows`` (on by default): L also shrinks, down to the five-period window's rows (5/8 of the
    slowest period), to the most that leave 2L columns where the pulse detector's isolated pulses (mean run ≥
    two slowest periods) leave fewer (:func:`shrunk_rows`). ``capped_rows`` (on by default): where the prior's
    pair asks for more than the capped window (:func:`pair_capped`) and the detector's flags leave fewer than
    2L columns, L starts at the five-period window's rows and grows where the columns allow.
    ``own_windows`` (off by default: its CPU): each mode whose ring dies within half the window and whose own window
    (:func:`own_window_samples`) is at most half the window is also fitted on that most recent short window; a
    pulse-free short estimate beyond ``OWN_CHANGE_STD`` combined std of the trend's last output is a change:
    the mode's level is re-set in the trend stage, then fed from its own window until the long window no
    longer holds the change (module docstring). The two window options act only on a pulsed record (a pulse
    flagged in at least half the windows so far). ``ring_start`` (off by default): a fast mode undetermined for
    half a window span, from the window's newest ring (after its last pulse, shorter than the pencil's 3(L + 1))
    — the segment fit's start where the pencil gave it no pole, and the phase-std test over the ring's span where
    the ring alone passes it and agrees with the window's fit (module docstring, "The newest ring")."""

    window_samples: int | None = None
    hop_samples: int | None = None
    window_s: float | None = None
    hop_s: float | None = None
    hop_fraction: float | None = None
    rows: int | None = None
    shrink_rows: bool = True
    extra_order: int | None = None
    ar_order: int | None = None
    outlier_cut: float = 4.0
    detect_ratio: float = 3.0
    band: float = 0.3
    max_damping: float = 0.05
    refine: bool = True
    refine_steps: int = 10
    min_segment: int | None = None
    max_phase_std: float = 0.5
    close_pairs: bool = True
    split_kicks: bool = True
    split_level: float = 0.01
    split_rounds: int = 3
    overlap_inflation: float = 1.0
    trend: bool = True
    trend_rate_noise: float | None = _trend.DEFAULTS["trend_rate_noise"]
    trend_meas_rel: float = _trend.DEFAULTS["trend_meas_rel"]
    trend_gate: float = _trend.DEFAULTS["trend_gate"]
    trend_restart_after: int = _trend.DEFAULTS["trend_restart_after"]
    trend_rate0: float | None = _trend.DEFAULTS["trend_rate0"]
    trend_restart_rate: str = _trend.RESTART_RATE
    trend_memory: float | None = 1.0
    trend_span_relevel: bool = True
    memory: bool = _memory.DEFAULTS["memory"]
    window_from_estimates: bool = True
    own_windows: bool = False
    ring_start: bool = False
    capped_rows: bool = True
    capped_either: bool = True
    change_threshold: float = _memory.DEFAULTS["change_threshold"]
    change_drift: float = _memory.DEFAULTS["change_drift"]


def _int(value, name: str, low: int, tracker: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{tracker}: {name} = {value!r} must be an integer ≥ {low}")


def resolve(opts: Options, name: str, prior, dt: float, n_samples: int | None = None) -> Options:
    """``opts`` with every size in samples: the window and hop (the user's, in s or samples, or the rule's),
    then rows, AR order and min segment scaled to that window unless given (:mod:`methods.tracking._defaults`).
    A window is refused only when shorter than 3(n + 1) samples, n = 2m + ``extra_order`` (the smallest
    default ``extra_order``, 2, when none is given)."""
    if opts.extra_order is not None:
        _int(opts.extra_order, "extra_order", 0, name)
    m = int(np.size(prior))
    order = 2 * m + (_defaults.EXTRA_ORDER_MIN if opts.extra_order is None else opts.extra_order)
    W, H = _defaults.window_hop(name, prior, dt, window_s_=opts.window_s, window_samples=opts.window_samples,
                                hop_s=opts.hop_s, hop_samples=opts.hop_samples, hop_fraction=opts.hop_fraction,
                                n_samples=n_samples,
                                minimum=_defaults.min_window_samples(m, order))
    for key, low in (("rows", 4), ("ar_order", 2), ("min_segment", 4)):
        if getattr(opts, key) is not None:
            _int(getattr(opts, key), key, low, name)
    extra = _defaults.pencil_extra_order(W, m) if opts.extra_order is None else opts.extra_order
    order = 2 * m + extra
    rows, ar_order, min_segment = _defaults.pencil_sizes(W, m, order, opts.rows, opts.ar_order, opts.min_segment)
    memory = opts.trend_memory
    if memory is not None and (isinstance(memory, bool) or not isinstance(memory, (int, float))
                               or not (np.isfinite(memory) and memory > 0)):
        raise ValueError(f"{name}: trend_memory = {memory!r} must be a finite number > 0 (window spans)")
    rate_noise = opts.trend_rate_noise
    if memory is not None and rate_noise is None and isinstance(opts.trend_meas_rel, (int, float)):
        # the trend filter's time constant in window spans (_defaults.trend_rate_noise_memory); a rate noise
        # the user gives wins
        rate_noise = _defaults.trend_rate_noise_memory(opts.trend_meas_rel, (W - 1) * dt, memory)
    return dataclasses.replace(opts, extra_order=extra, window_samples=W, hop_samples=H, window_s=None, hop_s=None,
                               hop_fraction=None, rows=rows, trend_rate_noise=rate_noise,
                               ar_order=ar_order, min_segment=min_segment)


def check_options(name: str, prior, dt: float, options: dict, n_samples: int | None = None) -> Options:
    opts = resolve(make_options(Options, options, name), name, prior, dt, n_samples)
    for key in ("refine", "split_kicks", "close_pairs", "window_from_estimates", "own_windows", "ring_start",
                "shrink_rows", "capped_rows", "capped_either", "trend_span_relevel"):
        if not isinstance(getattr(opts, key), bool):
            raise ValueError(f"{name}: {key} = {getattr(opts, key)!r} must be true or false")
    _int(opts.refine_steps, "refine_steps", 1, name)
    _int(opts.split_rounds, "split_rounds", 1, name)
    level = opts.split_level
    if isinstance(level, bool) or not isinstance(level, (int, float)) or not 0 < level < 1:
        raise ValueError(f"{name}: split_level = {level!r} must be a number in (0, 1) (the kick test's "
                         "family-wise false-alarm probability per pulse-free run)")
    for key in ("outlier_cut", "detect_ratio", "band", "max_damping", "max_phase_std", "overlap_inflation"):
        value = getattr(opts, key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: {key} = {value!r} must be a finite number > 0")
    order = 2 * np.size(prior) + opts.extra_order
    if opts.rows < order:
        raise ValueError(f"{name}: rows = {opts.rows} must be at least the pencil's order 2m + extra_order = {order}")
    if opts.window_samples < 3 * (opts.rows + 1) or opts.window_samples <= 2 * opts.ar_order:
        raise ValueError(f"{name}: window_samples = {opts.window_samples} is too short for rows = {opts.rows} "
                         f"and ar_order = {opts.ar_order} (needs ≥ 3 (rows + 1) and > 2 ar_order)")
    _trend.check(opts, name)
    if opts.trend_restart_rate not in _trend.RESTART_RATES:
        raise ValueError(f"{name}: trend_restart_rate = {opts.trend_restart_rate!r} must be one of "
                         f"{', '.join(_trend.RESTART_RATES)}")
    _memory.check(opts, name)
    return opts


def pulse_flags(seg: np.ndarray, ar_order: int, cut: float, iterations: int = 3) -> np.ndarray:
    """Samples where a robust AR(``ar_order``) one-step predictor of ``seg`` fails (Tukey weight 0)."""
    X = np.lib.stride_tricks.sliding_window_view(seg, ar_order + 1)
    A, b = X[:, :ar_order], X[:, ar_order]
    w = np.ones(b.size)
    for _ in range(iterations):
        sw = np.sqrt(w)
        coef = np.linalg.lstsq(A * sw[:, None], b * sw, rcond=None)[0]
        r = b - A @ coef
        scale = 1.4826 * np.median(np.abs(r))
        if not scale > 0:
            break
        u = np.abs(r) / (cut * scale)
        w = np.where(u < 1, (1 - u * u) ** 2, 0.0)
    flags = np.zeros(seg.size, dtype=bool)
    flags[ar_order:] = w == 0
    return flags


def widest_rows(flags: np.ndarray, rows: int, candidates: int = 6) -> int:
    """The most Hankel rows L, from ``rows`` (the rule's W/8) up to W/3 − 1 in ``candidates`` steps, that
    leaves ≥ 2L pulse-free columns in a window with pulse ``flags``.

    A pencil resolves two modes about 2π/L rad per sample apart: the rule's W/8 rows (chosen so that a column
    seldom straddles a pulse) merge modes a few % apart when the window holds six modes over a decade, while a
    window with few pulses has the columns for W/3 (Hua & Sarkar's best noise performance lies at L between
    N/3 and N/2). So the rows grow with the pulse-free columns there are; a window full of pulses keeps W/8."""
    n = flags.size
    top = n // 3 - 1
    if top <= rows:
        return rows
    cum = _flag_sums(flags)
    best = rows
    for L in np.unique(np.linspace(rows, top, candidates).round().astype(int)):
        if _free_columns(cum, n, int(L)) >= 2 * L:
            best = int(L)
    return best


def _flag_sums(flags: np.ndarray) -> np.ndarray:
    """The flags' prefix sums, 0 first: the flags in samples a … b − 1 are ``cum[b] − cum[a]``."""
    return np.concatenate(([0], np.cumsum(flags)))


def _free_mask(cum: np.ndarray, n: int, L: int) -> np.ndarray:
    """Per Hankel column k of L + 1 samples: no flagged sample in k + 1 … k + L (``cum``: :func:`_flag_sums`)."""
    k = np.arange(n - L)
    return cum[k + L + 1] - cum[k + 1] == 0


def _free_columns(cum: np.ndarray, n: int, L: int) -> int:
    """The number of :func:`_free_mask`'s free columns."""
    return int(np.count_nonzero(_free_mask(cum, n, L)))


def _events(flags: np.ndarray, merge: int) -> int:
    """Flagged events: runs of flags, those less than ``merge`` samples apart one event (a pulse spoils the
    AR(p) predictor's next p residuals, which may cross zero in between)."""
    at = np.flatnonzero(flags)
    return 0 if at.size == 0 else 1 + int(np.count_nonzero(np.diff(at) >= merge))


def shrunk_rows(flags: np.ndarray, pulses: np.ndarray, rows: int, floor: int, min_run: float, merge: int) -> int:
    """``shrink_rows``: where ``rows`` leaves fewer than 2L Hankel columns free of ``flags`` because of the
    pulse detector's own flags (``pulses``: they alone leave fewer than 2L), and those pulses are isolated —
    their mean pulse-free run, the window's unflagged samples over the events (:func:`_events`, flags less than
    ``merge`` samples apart one event) + 1, at least ``min_run`` samples — the most rows down to ``floor`` that
    leave 2L columns free of ``flags``; otherwise (or when even ``floor`` leaves fewer) ``rows``.

    Why: a window made long for a close pair of the prior (up to 20 periods of the slowest mode, so W/8 = 2.5
    of them) under pulses a few periods apart keeps too few columns of W/8 rows for the pencil, and determines
    nothing, though each pulse-free run is a free decay longer than a column needs. Under a white force the
    pulse detector flags next to nothing and the kick test's splits (a continuing force read as kicks, about a
    slowest period apart) are what leave too few columns: there short-row estimates from the scraps between
    them pull the trend away (docs/measured/tracking_gated_pencil.md), so the rule stays silent; so it does where the
    pulses lie closer than ``min_run`` on average."""
    n = flags.size
    cum = _flag_sums(flags)
    if floor >= rows or _free_columns(cum, n, rows) >= 2 * rows:
        return rows
    if _free_columns(_flag_sums(pulses), n, rows) >= 2 * rows:
        return rows                                   # the kick test's flags, not pulses: silent
    if (n - int(np.count_nonzero(pulses))) / (_events(pulses, merge) + 1) < min_run:
        return rows                                   # pulses everywhere, not isolated: silent
    if _free_columns(cum, n, floor) < 2 * floor:
        return rows
    # the columns fall and 2L rises with L: the largest L that leaves 2L, by bisection on [floor, rows)
    lo, hi = floor, rows                              # lo leaves 2L, hi does not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if _free_columns(cum, n, mid) >= 2 * mid else (lo, mid)
    return lo


def shrink_sizes(prior, dt: float, order: int) -> tuple[int, float]:
    """``shrink_rows``' (floor, min_run) in samples: the fewest rows, those of the five-period window
    (``ROWS_FRACTION`` · ``PERIODS`` periods of the prior's slowest mode, at least the pencil's order), and the
    mean pulse-free run that makes the pulses isolated: the shortest window the tracker trusts after a restart,
    ``RESTART_PERIODS`` (2) periods of the prior's slowest mode — runs shorter than that give estimates worse
    than the trend stage's prediction over a window that determines nothing."""
    period = _defaults.slowest_period_s(prior) / dt
    return (max(order, int(round(_defaults.ROWS_FRACTION * _defaults.PERIODS * period))),
            _defaults.RESTART_PERIODS * period)


def window_poles(seg: np.ndarray, dt: float, order: int, rows: int, ar_order: int, cut: float,
                 detect_ratio: float, flags: np.ndarray | None = None):
    """(continuous poles s of the gated pencil, share of Hankel columns kept) for one window."""
    seg = seg - seg.mean()
    n = seg.size
    if flags is None:
        flags = pulse_flags(seg, ar_order, cut)
    cols = np.lib.stride_tricks.sliding_window_view(seg, rows + 1)          # (n − L, L + 1)
    keep = _free_mask(_flag_sums(flags), n, rows)
    if keep.sum() < 2 * rows:                      # pulses everywhere: this window determines nothing
        return np.empty(0, dtype=complex), float(keep.mean())
    y0, y1 = cols[keep, :rows].T, cols[keep, 1:].T
    # Y₀'s left singular vectors and values from the eigendecomposition of Y₀Y₀ᵀ (L × L; λ = σ²): a third of
    # the SVD's CPU at L ≈ W/3; only the r ≪ L leading vectors are used, and with V_rᵀ = Σ_r⁻¹U_rᵀY₀,
    # Â = U_rᵀY₁V_rΣ_r⁻¹ = U_rᵀY₁Y₀ᵀU_rΣ_r⁻². The squared spectrum resolves σ down to ~1e-8·σ₁ (not 1e-16):
    # the rank cut is 1e-7·σ₁, far under any noise floor, and the median below is unaffected.
    lam, u = np.linalg.eigh(y0 @ y0.T)
    lam, u = lam[::-1], u[:, ::-1]
    sv = np.sqrt(np.clip(lam, 0.0, None))
    if not sv[0] >= detect_ratio * np.median(sv):   # a flat singular spectrum: noise, no mode to find
        return np.empty(0, dtype=complex), float(keep.mean())
    r = min(order, int(np.sum(sv > sv[0] * 1e-7)))
    ur = u[:, :r]
    a = ((ur.T @ y1) @ (y0.T @ ur)) / lam[None, :r]
    z = np.linalg.eigvals(a)
    z = z[np.abs(z) > 0]
    return np.log(z.astype(complex)) / dt, float(keep.mean())


def _labelled(w: np.ndarray, zeta: np.ndarray, std: np.ndarray, ref: np.ndarray, limit: float, max_std_rad_s: float,
              max_damping: float, resolution_rad_s: float | None = None) -> np.ndarray:
    """Which refined modes count as determined, and as the mode their label says.

    A mode counts when it is within ``limit`` (log) of its last estimate ``ref``, lightly damped, and its std
    is under ``max_std_rad_s`` (the window's phase-std test). A mode that lies nearer another mode's last
    estimate than its own counts only if that other mode is itself determined at a distinct pole (more than
    3 combined std away): else it is that mode's pole picked up by a component whose own mode has died away.
    Of two modes on one pole (within 3 combined std) only the one nearer its own last estimate counts. When
    every mode passes and no two share a pole, all count (their labels then follow their ranks).

    ``resolution_rad_s`` (the window's Fourier resolution 2π/span; ``close_pairs``): a mode whose nearest
    other mode lies within it may pass with a std over ``max_std_rad_s`` when the pair is resolved — its pole
    distinct from every other mode's by more than 3 combined std. Within the resolution each member's std is
    inflated by the pair's near-collinear basis (the pair's mean stays sharp), so the phase-std test refuses a
    pair it has resolved; a mode that died away has no pole of its own to be distinct at."""
    dist = np.abs(np.log(w)[:, None] - np.log(ref)[None, :])
    own = np.diag(dist)
    apart = np.abs(w[:, None] - w[None, :]) > 3 * np.hypot(std[:, None], std[None, :])
    sharp = std <= max_std_rad_s
    if resolution_rad_s is not None and w.size > 1:
        gap = np.abs(w[:, None] - w[None, :]) + np.diag(np.full(w.size, np.inf))   # to the nearest other mode
        distinct = (apart | np.eye(w.size, dtype=bool)).all(axis=1)                # apart from every other mode
        sharp |= (gap.min(axis=1) < resolution_rad_s) & distinct
    ok = (own <= limit) & np.isfinite(std) & sharp & (zeta <= max_damping)
    if ok.all() and apart[np.triu_indices(w.size, 1)].all():
        # every mode determined at a pole of its own: the m poles are the m modes, labelled by rank
        # (_in_order) — after a step larger than the gap between two modes a mode's new pole may lie nearer
        # a neighbour's last estimate than its own, which the test below would refuse
        return ok
    good = ok.copy()
    for i in np.flatnonzero(ok):
        k = int(np.argmin(dist[i]))
        if k != i and not (ok[k] and apart[i, k]):
            good[i] = False
    for i, k in zip(*np.nonzero(np.triu(~apart, 1)), strict=True):
        if good[i] and good[k]:
            good[i if own[i] > own[k] else k] = False
    return good


def _in_order(w: np.ndarray, zeta: np.ndarray, std: np.ndarray, good: np.ndarray):
    """The determined modes' refined (ω, ζ, std) relabelled by rank: the i-th smallest determined ω to the
    i-th determined mode in prior order. The fit starts each component at its mode's last estimate, but after
    a step it may converge on a neighbour's pole and the neighbour on its own (two crossed labels, each within
    ``band`` of its reference); the modes keep their order (the references are increasing,
    ``usable_prior``), so the ranks are the labels."""
    idx = np.flatnonzero(good)
    order = idx[np.argsort(w[idx], kind="stable")]
    if np.array_equal(order, idx):
        return w, zeta, std
    w, zeta, std = w.copy(), zeta.copy(), std.copy()
    w[idx], zeta[idx], std[idx] = w[order], zeta[order], std[order]
    return w, zeta, std


def run(name: str, y: np.ndarray, dt: float, prior: np.ndarray, options: dict) -> Track:
    given = make_options(Options, options, name)
    opts = resolve(given, name, prior, dt)
    W, H = opts.window_samples, opts.hop_samples
    ends = window_ends(y.size, W, H)
    m = prior.size
    order = 2 * m + opts.extra_order
    # after a restart: the model's minimum window, at least two periods of the slowest mode
    w_restart = min(W, _defaults.restart_samples(prior, dt, _defaults.min_window_samples(m, order)))
    # window_from_estimates: the window rule at the last estimates, never longer than at the prior (a window
    # the user gives is kept)
    adapt = opts.window_from_estimates and given.window_samples is None and given.window_s is None
    w_low = _defaults.min_window_samples(m, order)
    # capped_rows: the window is at its cap for a pair it cannot resolve; in a window where the pulse detector's
    # flags leave fewer than 2L columns the rows start at the five-period window's (shrink_sizes' floor) and
    # grow where the pulse-free columns allow (widest_rows; _window)
    capped_rows = (min(opts.rows, shrink_sizes(prior, dt, order)[0])
                   if (opts.capped_rows and given.rows is None and given.window_samples is None
                       and given.window_s is None and pair_capped(prior)) else None)
    memory_rate = (opts.trend_memory is not None and given.trend_rate_noise is None
                   and isinstance(opts.trend_meas_rel, (int, float)))
    nyquist = np.pi / dt
    freq = np.full((ends.size, m), np.nan)
    found = np.zeros((ends.size, m), dtype=bool)
    kept = np.full(ends.size, np.nan)
    wstd = np.full((ends.size, m), np.nan)
    span = np.full(ends.size, np.nan)
    state = {"last_w": np.full(m, np.nan), "last_z": np.full(m, np.nan), "ref": prior.copy(), "flags": None,
             "rows_free": given.rows is None, "shrink": shrink_sizes(prior, dt, order),
             "seg_start": 0, "kicks": set(), "clean": [], "pulses": set(), "own_changes": [],
             "own_std": np.full(m, np.nan), "own_screened": 0, "capped_rows": capped_rows,
             "found_at": np.full(m, -np.inf)}
    limit = np.log1p(opts.band)
    bank = (_trend.TrendBank(m, **_trend.settings(opts, prior), restart_rate=opts.trend_restart_rate,
                             span_relevel=opts.trend_span_relevel)
            if (opts.trend or opts.memory) else None)
    cusum = _memory.Cusum(m, opts.change_threshold, opts.change_drift) if opts.memory else None
    out = np.full((ends.size, m), np.nan)
    out_std = np.full((ends.size, m), np.nan)
    out_conv = np.zeros((ends.size, m), dtype=bool)
    start = 0
    restart_at: list[int] = []
    fresh = np.zeros(m, dtype=bool)           # modes restarted by the change detector, until the window is full
    own_until = np.full(m, -1)                # own_windows: a mode fed from its own window until this sample
    last_pulse = -1                           # the last sample the pulse detector flagged
    windows_seen = windows_pulsed = 0         # window_from_estimates: windows with a pulse flagged, of those fitted
    for j, e in enumerate(ends.tolist()):
        Wj = W
        # both window options act only where the record is pulsed (a pulse flagged in at least half the windows
        # so far: free decays between inputs); under a continuing force the window fits one forced response,
        # which the prior's longer window averages, and no ring dies away
        pulsed = windows_seen > 0 and 2 * windows_pulsed >= windows_seen
        if adapt and pulsed:
            Wj = min(W, max(w_low, int(round(estimates_window_s(prior, state["ref"], np.isfinite(state["last_w"]),
                                                                opts.capped_either) / dt))))
        if adapt and bank is not None and memory_rate:
            bank.rate_noise = _defaults.trend_rate_noise_memory(opts.trend_meas_rel, (Wj - 1) * dt,
                                                                opts.trend_memory)
        a = max(e - Wj + 1, start)
        n_j = e - a + 1
        span[j] = (n_j - 1) * dt
        full = (opts.rows, opts.ar_order, opts.min_segment) if Wj == W else _shorter(Wj, m, order, opts)
        if n_j == Wj:
            fresh[:] = False
        if n_j == Wj or (n_j >= w_restart and not fresh.any()):
            state["seg_start"] = a
            kept[j] = _window(y[a: e + 1], dt, full if n_j == Wj else _shorter(n_j, m, order, opts), order, opts,
                              nyquist, limit, prior, state, freq[j], found[j], wstd[j])
        elif e + 1 >= Wj:
            state["seg_start"] = e - Wj + 1
            # after a restart: the restarted modes from the samples since the change, the others from the
            # full window as before (their frequency did not jump; a short window would only add noise)
            kept[j] = _window(y[e - Wj + 1: e + 1], dt, full, order, opts, nyquist, limit, prior, state, freq[j],
                              found[j], wstd[j])
            if n_j >= w_restart:
                f2, d2, s2 = np.full(m, np.nan), np.zeros(m, dtype=bool), np.full(m, np.nan)
                state["seg_start"] = a
                _window(y[a: e + 1], dt, _shorter(n_j, m, order, opts), order, opts, nyquist, limit, prior,
                        state, f2, d2, s2)
                freq[j] = np.where(fresh, f2, freq[j])
                found[j] = np.where(fresh, d2, found[j])
                wstd[j] = np.where(fresh, s2, wstd[j])
            else:
                freq[j, fresh], found[j, fresh], wstd[j, fresh] = np.nan, False, np.nan
        span_j = np.where(fresh, span[j], (Wj - 1) * dt)
        if np.isfinite(kept[j]) and state.get("flags") is not None:
            windows_seen += 1
            windows_pulsed += bool(state["flags"].any())
        if bank is None:
            continue
        if opts.own_windows and (pulsed or (own_until >= 0).any()):
            _own(y, e, dt, Wj, w_low, m, order, opts, nyquist, limit, prior, state, bank, fresh, own_until,
                 out[j - 1] if j else np.full(m, np.nan), out_std[j - 1] if j else np.full(m, np.nan),
                 freq[j], found[j], wstd[j], span_j)
        meas = np.sqrt(opts.overlap_inflation * np.maximum(1.0, (span_j / dt + 1) / H)) * wstd[j] if opts.refine \
            else None
        out[j], out_std[j], out_conv[j], nu = bank.step(e * dt - span_j / 2, span_j / 2, freq[j], found[j], meas,
                                                        wstd[j] if opts.refine else None,
                                                        own_until >= e)
        if state.get("flags") is not None and state["flags"].any():
            last_pulse = max(last_pulse, state["seg_start"] + int(np.flatnonzero(state["flags"])[-1]))
        if cusum is not None:
            alarm = cusum.update(nu, e)
            if alarm.any():
                clean = cusum.restart_sample(alarm)
                # a jump that rang the structure starts at its pulse: restart after the last one flagged
                # since the last clean window
                start = max(start, last_pulse + 1 if last_pulse >= clean else clean)
                restart_at.append(start)
                for i in np.flatnonzero(alarm):
                    bank.restart(int(i))
                fresh |= alarm
                cusum.reset(start - 1)
    message = (f"gated pencil (order {order}, {opts.rows} rows) on {ends.size} windows of {W} samples every {H}; "
               f"median share of Hankel columns kept {np.nanmedian(kept) if np.isfinite(kept).any() else 0:.2f}")
    extra = {"window_end_sample": ends, "columns_kept": kept, "window_std": wstd, "window_span_s": span,
             "memory_restart_samples": np.asarray(restart_at, dtype=int)}
    if opts.memory:
        message += f"; {len(restart_at)} change-detector restarts of the window"
    if opts.own_windows:
        extra["own_window_changes"] = np.asarray(state["own_changes"], dtype=int).reshape(-1, 2)
        extra["own_fits_skipped"] = state["own_screened"]
        message += (f"; {len(state['own_changes'])} changes on the modes' own windows "
                    f"({state['own_screened']} short fits skipped at the pencil's pole)")
    if not opts.trend:
        return Track(ends * dt, freq, np.nan, found, message=message, extra=extra)
    extra |= {"window_frequencies": freq, "window_converged": found, "trend_restarts": bank.restarts}
    message += f"; trend stage: {bank.restarts.tolist()} restarts"
    return Track(ends * dt, out, out_std, out_conv, message=message, extra=extra)


def _own(y, e, dt, Wj, w_low, m, order, opts, nyquist, limit, prior, state, bank, fresh, own_until, last, last_std,
         freq, found, wstd, span_j) -> None:
    """``own_windows`` (module docstring): window j's estimates (``freq``, ``found``, ``wstd``, ``span_j``,
    written in place) of the modes whose own window is at most half the window ``Wj`` — from that short window
    while the mode is fed from it (``own_until``), or after a change it shows; ``last``/``last_std``: the trend
    stage's previous output."""
    # the modes whose ring dies away within half the window (decay time 1/(ζω) at the last estimates): a change
    # with no input after it is lost on the long window for them only
    with np.errstate(divide="ignore", invalid="ignore"):
        decay = 1.0 / (state["last_z"] * state["ref"])      # NaN before a mode is determined: not eligible
    W_own = np.minimum(own_window_samples(state["ref"], dt, w_low), Wj)
    # the feed over: the first long window that determines the mode again re-sets its level (the trend
    # stage, fed short windows, would follow the long ones only over its memory and learn the lag as a rate)
    for i in np.flatnonzero((own_until >= 0) & (own_until < e) & found & np.isfinite(wstd)):
        bank.relevel(int(i), e * dt - span_j[i] / 2, freq[i], wstd[i] ** 2)
        own_until[i] = -1
        found[i] = False
    for i in np.flatnonzero((2 * W_own <= Wj) & (decay <= (Wj - 1) * dt / 2) & ~fresh):
        n = int(W_own[i])
        if e + 1 < n:
            continue
        pulse = any(k > e - n for k in state["pulses"])
        if pulse and own_until[i] < e:
            continue                          # a pulse in the short window: no change read there (below)
        watch = own_until[i] < e
        # the trend stage's last output (carried by its rate to the previous window's end: a drift is not
        # read as a change), the long window's estimate before the trend has one
        ref, ref_std = (last[i], last_std[i]) if np.isfinite(last[i]) else (freq[i], wstd[i])
        screen = None
        if watch and OWN_SCREEN_STD is not None and np.isfinite(ref):
            prev = state["own_std"][i]
            screen = (ref, OWN_SCREEN_STD * np.hypot(prev, ref_std if np.isfinite(ref_std) else 0.0))
        est = _own_estimate(y[e - n + 1: e + 1], dt, int(i), _shorter(n, m, order, opts), order, opts, nyquist,
                            limit, state, free_only=watch, screen=screen)
        f, s, free = est if est is not None else (np.nan, np.nan, False)
        free = free and not pulse
        if watch:
            if not (free and np.isfinite(ref)
                    and abs(f - ref) > OWN_CHANGE_STD * np.hypot(s, ref_std if np.isfinite(ref_std) else 0.0)):
                continue
            # a change within the mode's own window: the mode's level re-set there (its rate kept: a rate
            # from a few short windows would carry the level away once the ring has died), then fed from its
            # own window until the long window's start has passed the change
            bank.relevel(int(i), (e - (n - 1) / 2) * dt, f, s * s)
            state["own_changes"].append((e, int(i)))
            own_until[i] = e + Wj - 1
            freq[i], found[i], wstd[i], span_j[i] = np.nan, False, np.nan, (n - 1) * dt
            continue
        freq[i], found[i], wstd[i], span_j[i] = f, est is not None, s, (n - 1) * dt


def _own_estimate(seg, dt, i, sizes, order, opts, nyquist, limit, state, free_only=False, screen=None):
    """(ω, std, free) of mode ``i`` on its own (short) window ``seg``, or None; ``free``: no pulse flagged in it
    (``free_only``: None where a pulse is flagged, before any fit — only a free window can show a change).

    The modes the window cannot resolve (closer than its resolution 2π/span) are fitted as one component at
    their mean last estimate; mode i starts at the gated pencil's pole nearest its last estimate (within
    ``band``); the segment fit on the short window's own pulse-free runs (not the long windows' kicks: their
    kick test reads a change of frequency as a kick) gives its ω and std, kept when within ``band`` of its last
    estimate and nearer it than any other mode's (else it is a neighbour's pole), lightly damped and passing the
    phase-std test (std × span ≤ ``max_phase_std``)."""
    rows, ar_order, min_segment = sizes
    if flat_record(seg):
        return None
    centred = seg - seg.mean()
    flags = pulse_flags(centred, ar_order, opts.outlier_cut)
    if free_only and flags.any():
        return None
    ref = state["ref"]
    span_s = (seg.size - 1) * dt
    # the components: runs of modes closer than the window's resolution merged (ref is increasing)
    groups = [[0]]
    for k in range(1, ref.size):
        if ref[k] - ref[groups[-1][-1]] < 2 * np.pi / span_s:
            groups[-1].append(k)
        else:
            groups.append([k])
    gi = next(g for g, members in enumerate(groups) if i in members)
    if len(groups[gi]) > 1:
        return None
    last_z = state["last_z"]
    w0 = np.array([float(np.mean(ref[g])) for g in groups])
    z0 = np.array([float(np.nanmean(last_z[g])) if np.isfinite(last_z[g]).any() else 0.005 for g in groups])
    s, _ = window_poles(seg, dt, order, rows, ar_order, opts.outlier_cut, opts.detect_ratio, flags)
    w = np.abs(s)
    zeta = -s.real / np.maximum(w, 1e-300)
    ok = (s.imag > 0) & (w < nyquist) & (zeta >= MIN_DAMPING) & (zeta <= opts.max_damping)
    if ok.any():
        dist = np.abs(np.log(w[ok]) - np.log(ref[i]))
        k = int(np.argmin(dist))
        if dist[k] <= limit:
            w0[gi], z0[gi] = w[ok][k], np.clip(zeta[ok][k], 1e-4, opts.max_damping)
            if screen is not None and np.isfinite(screen[1]) and abs(w0[gi] - screen[0]) <= screen[1]:
                state["own_screened"] += 1
                return None
    z0 = np.clip(z0, 1e-4, opts.max_damping)
    runs = _fittable(centred, dt, _segments.segments(flags, min_segment), w0, z0)
    fit = pem.separable_fit(centred, dt, runs, w0, z0, opts.refine_steps) if runs else None
    if fit is None:
        return None
    wi, zi, si = fit[0][gi], fit[1][gi], fit[2][gi]
    dist = np.abs(np.log(wi / ref))
    if not (np.isfinite(si) and dist[i] <= limit and int(np.argmin(dist)) == i and zi <= opts.max_damping
            and si * span_s <= opts.max_phase_std):
        return None
    state["own_std"][i] = float(si)
    return float(wi), float(si), not flags.any()


def ring_run(pulses: np.ndarray, ref: np.ndarray, dt: float, rows: int) -> tuple[int, np.ndarray]:
    """``ring_start``: (first sample of the window's newest ring, the modes it holds) — the ring is the last
    pulse-free run, after the last sample the pulse detector flagged (``pulses``), when it is shorter than the
    3(L + 1) samples a pencil of ``rows`` L needs for 2L columns of its own (a longer ring the window's pencil
    and fit already see whole; none flagged or a longer ring: (−1, none)); a mode is held when the run spans at
    least ``RING_PERIODS`` of its periods (at ``ref``) and ``GAP_CYCLES`` (2) beats of its nearest other mode (the
    window rule's resolution, :func:`own_window_samples`)."""
    at = np.flatnonzero(pulses)
    if at.size == 0 or pulses.size - 1 - at[-1] >= 3 * (rows + 1):
        return -1, np.zeros(ref.size, dtype=bool)
    a = int(at[-1]) + 1
    span = (pulses.size - 1 - a) * dt
    held = span >= RING_PERIODS * 2.0 * np.pi / ref
    if ref.size > 1:
        gap = np.abs(ref[:, None] - ref[None, :]) + np.diag(np.full(ref.size, np.inf))
        held &= span >= _defaults.GAP_CYCLES * 2.0 * np.pi / gap.min(axis=1)
    return a, held


def ring_search(run: np.ndarray, dt: float, ref: np.ndarray, zeta: np.ndarray, i: int,
                limit: float) -> tuple[float, float]:
    """``ring_start``: (ω, std) of mode i from the ring ``run`` alone — the variable-projection fit over ω_i in
    its band (log distance ≤ ``limit`` from ``ref[i]``): the run's least-squares residual with every mode's
    damped cosine and sine (the others at ``ref``, damping ``zeta``) and an offset, minimised over ω_i on a grid
    at a quarter of the run's resolution 2π/span, then by :func:`scipy.optimize.minimize_scalar` (bounded)
    between the best grid point's neighbours; the std from the residual's variance over the projected
    derivative of the fitted mode (the reduced Jacobian of the one nonlinear parameter; written here because
    :func:`methods.pem.separable_fit` frees every mode's ω and ζ, which a ring shorter than the slow modes'
    periods cannot determine). A 1-D search needs no start: a mode that stepped by more than the run's
    resolution since it was last determined is found where the window's Hankel rows (W/8 or more: a column
    longer than the ring) see nothing of it."""
    n = run.size
    span = (n - 1) * dt
    w = np.asarray(ref, dtype=float).copy()

    def fit(wi: float):
        w[i] = wi
        X = _segments.free_decay_basis(n, dt, w, zeta)
        c = np.linalg.lstsq(X, run, rcond=None)[0]
        return X, c, float(np.sum((run - X @ c) ** 2))

    lo, hi = ref[i] * np.exp(-limit), min(ref[i] * np.exp(limit), 0.999 * np.pi / dt)
    grid = np.linspace(lo, hi, max(3, int(np.ceil((hi - lo) / (0.25 * 2.0 * np.pi / span))) + 1))
    cost = np.array([fit(g)[2] for g in grid])
    k = int(np.argmin(cost))
    best = scipy.optimize.minimize_scalar(lambda x: fit(x)[2], method="bounded",
                                          bounds=(grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]))
    wi = float(best.x) if best.success and best.fun <= cost[k] else float(grid[k])
    X, c, rss = fit(wi)
    h = 1e-6 * wi
    d = (fit(wi + h)[0] - fit(wi - h)[0]) @ c / (2 * h)
    d -= X @ np.linalg.lstsq(X, d, rcond=None)[0]
    dof = n - X.shape[1] - 1
    norm = float(np.linalg.norm(d))
    return wi, (float(np.sqrt(rss / dof)) / norm if dof > 0 and norm > 0 else np.inf)


def _fittable(y: np.ndarray, dt: float, runs: list, w0: np.ndarray, z0: np.ndarray) -> list:
    """The runs whose own basis (m damped sinusoids at the start (w0, z0) and an offset) is not near-singular.

    A run much shorter than the slowest period cannot tell that mode's cosine and sine from the offset and the
    other modes (scaled condition number over 1e12: :func:`methods.pem.predictor.scaled_lstsq`); the shared fit
    refuses a basis it cannot solve, so one such run would cost the whole window its estimate. Left out, the
    run's samples are lost to the fit (what little they hold on the slowest mode is lost anyway)."""
    m = w0.size
    return [(a, b) for a, b in runs if pem.SeparableModel(y[a:b], dt, m, True, 0.0).fit(w0, z0) is not None]


def _shorter(n: int, m: int, order: int, opts: Options) -> tuple[int, int, int]:
    """Rows, AR order and min segment for a window shortened by a restart: the rule's at n samples, never
    above the full window's."""
    rows, ar, seg = _defaults.pencil_sizes(n, m, order)
    return min(rows, opts.rows), min(ar, opts.ar_order), min(seg, opts.min_segment)


def _window(seg, dt, sizes, order, opts, nyquist, limit, prior, state, freq, found, wstd) -> float:
    """One window's estimate into ``freq``/``found``/``wstd`` (rows of the track, written in place); returns
    the share of Hankel columns kept. ``state``: the last refined ω, ζ and the assignment reference."""
    rows, ar_order, min_segment = sizes
    ref = state["ref"]
    state["flags"] = None
    if flat_record(seg):
        return np.nan
    centred = seg - seg.mean()
    flags = pulse_flags(centred, ar_order, opts.outlier_cut)
    pulses = flags.copy()                         # the detector's own flags (shrink_rows), before the kicks
    start = state["seg_start"]
    if opts.own_windows:
        # the pulses (the AR detector's, not the kick test's) of the windows so far: a mode's own window is a
        # free decay when none lies in it (_own)
        state["pulses"] = {k for k in state["pulses"] if k >= start} | set((start + np.flatnonzero(flags)).tolist())
    if opts.split_kicks:
        # the samples flagged in earlier windows (pulses and the kick test's kicks; earlier samples only:
        # causal) stay flagged: the AR predictor cannot flag the window's first ar_order samples, and a pulse
        # there biases the shared poles enough for the kick test to split clean runs
        state["kicks"] = {k for k in state["kicks"] if k >= start}
        idx = np.fromiter(state["kicks"], dtype=int, count=len(state["kicks"])) - start
        flags[idx[idx < seg.size]] = True
        state["kicks"].update((start + np.flatnonzero(flags)).tolist())
    state["flags"] = flags
    if state["rows_free"]:
        if (state["capped_rows"] is not None
                and _free_columns(_flag_sums(pulses), seg.size, rows) < 2 * rows):
            # capped_rows: the pulse detector's own flags leave fewer than 2L columns of the rule's rows (as
            # shrink_rows' first condition; under a white force they leave plenty): the rows start at the
            # five-period window's and grow where the columns allow
            rows = min(rows, state["capped_rows"])
        rows = widest_rows(flags, rows)
        if opts.shrink_rows:
            rows = shrunk_rows(flags, pulses, rows, *state["shrink"], ar_order)
    s, kept = window_poles(seg, dt, order, rows, ar_order, opts.outlier_cut, opts.detect_ratio, flags)
    w = np.abs(s)
    zeta = -s.real / np.maximum(w, 1e-300)
    ok = (s.imag > 0) & (w < nyquist) & (zeta >= MIN_DAMPING) & (zeta <= opts.max_damping)
    cand = np.log(w[ok])
    if cand.size == 0:
        return kept
    dist = np.abs(cand[:, None] - np.log(ref)[None, :])
    # squared log distance: strictly convex, so the optimal assignment keeps the modes' order (two crossed
    # pairs always cost more than the same pairs uncrossed) — after a step larger than the gap between two
    # modes the nearest reference is a neighbour's, the rank is still right
    cost = np.where(dist <= limit, dist * dist, 1e6)
    rr, cc = scipy.optimize.linear_sum_assignment(cost)
    hit = cost[rr, cc] < 1e6
    freq[cc[hit]] = np.exp(cand[rr[hit]])
    found[cc[hit]] = True
    last_w, last_z = state["last_w"], state["last_z"]
    e_now = start + seg.size - 1
    held, ring, starts = np.zeros(ref.size, dtype=bool), {}, {}
    if opts.refine and opts.ring_start:
        # the window's newest ring (after its last pulse) and the modes it holds, only a mode no window has
        # determined for more than half a window's span (the trend stage's gap: after a step with no ring, or
        # before a mode's first ring); a mode the pencil gave no pole starts from the ring alone (ring_search)
        ring_at, held = ring_run(pulses, ref, dt, rows)
        held &= e_now - state["found_at"] > (seg.size - 1) / 2
        z_ring = np.clip(np.where(np.isfinite(last_z), last_z, 0.005), 1e-4, opts.max_damping)
        ring = {int(i): ring_search(centred[ring_at:], dt, ref, z_ring, int(i), limit)
                for i in np.flatnonzero(held & ~found)}
        # the phase-std test on the ring alone (a flagged noise outlier starts no ring)
        span_r = (seg.size - 1 - ring_at) * dt
        starts = {i: v[0] for i, v in ring.items() if v[1] * span_r <= opts.max_phase_std}
    if opts.refine and (found.any() or starts):
        zc = np.clip(zeta[ok][rr[hit]], 1e-4, opts.max_damping)
        w0 = np.where(found, freq, np.where(np.isfinite(last_w), last_w, ref))
        z0 = np.where(np.isfinite(last_z), last_z, 0.005)
        z0[cc[hit]] = zc
        w_ring = w0.copy()
        for i, wi in starts.items():
            w_ring[i] = wi
        runs = _fittable(centred, dt, _segments.segments(flags, min_segment), w_ring, z0)
        refined = pem.separable_fit(centred, dt, runs, w_ring, z0, opts.refine_steps) if runs else None
        if refined is None and starts:
            # the ring's start left the fit ill-posed: the default's start
            runs = _fittable(centred, dt, _segments.segments(flags, min_segment), w0, z0)
            refined = pem.separable_fit(centred, dt, runs, w0, z0, opts.refine_steps) if runs else None
        if refined is not None and opts.split_kicks:
            # a run inside one an earlier window tested clean is not tested again (the windows overlap by
            # W − H samples: only the newest run is new); causal, and the test's cost once per run
            clean = state["clean"] = [(a, b) for a, b in state["clean"] if b > start]
            known = [(a, b) for a, b in runs if any(ca <= start + a and start + b <= cb for ca, cb in clean)]
            split, kicks = _segments.split_kicks(centred, dt, [r for r in runs if r not in known], refined[0],
                                                 refined[1], min_segment, opts.split_level, opts.split_rounds)
            clean += [(start + a, start + b) for a, b in split]
            split = sorted(split + known)
            if kicks:
                state["kicks"].update(start + k for k in kicks)
                flags[kicks] = True
                split = _fittable(centred, dt, split, refined[0], refined[1])
                again = pem.separable_fit(centred, dt, split, refined[0], refined[1], opts.refine_steps) \
                    if split else None
                refined = again if again is not None else refined
        found[:] = False
        freq[:] = np.nan
        if refined is not None:
            wr, zr, sr = refined
            span_s = (seg.size - 1) * dt
            max_std = np.full(ref.size, opts.max_phase_std / span_s)
            if held.any():
                # ring_start: a held mode that fails the phase-std test over the window passes it when it passes
                # over the ring's span, the ring alone passes it too (its own std × the ring's span) and puts the
                # mode where the window's fit does (within 3 combined std): its information is the ring's, a
                # fresh free decay after a pulse
                for i in np.flatnonzero(held & (sr > max_std) & (sr * span_r <= opts.max_phase_std)):
                    wi, si = ring[i] if i in ring else ring_search(centred[ring_at:], dt, ref, z_ring, int(i), limit)
                    if si * span_r <= opts.max_phase_std and abs(wr[i] - wi) <= 3 * np.hypot(sr[i], si):
                        max_std[i] = max(max_std[i], sr[i])
            good = _labelled(wr, zr, sr, ref, limit, max_std, opts.max_damping,
                             2 * np.pi / span_s if opts.close_pairs else None)
            wr, zr, sr = _in_order(wr, zr, sr, good)
            freq[good], wstd[good], found[good] = wr[good], sr[good], True
            state["found_at"] = np.where(good, e_now, state["found_at"])
            state["last_w"] = np.where(good, wr, last_w)
            state["last_z"] = np.where(good, zr, last_z)
    state["ref"] = usable_prior(np.where(found, freq, ref), prior, nyquist)
    return kept
