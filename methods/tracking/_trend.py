"""The trend stage of a sliding-window tracker: window estimates put at the window's centre, carried to the
present by a local-linear-trend Kalman filter per mode (``trend=True`` on every windowed tracker).

A window of W samples ending at sample e estimates (to first order, for a frequency linear in time) the
frequency at its centre, t_c = (e − (W − 1)/2)Δt, not at its end: stamped at its end it lags a drift of rate
ω̇ by (W − 1)Δt/2 · ω̇ (0.5 % of ω for W = 512, Δt = 0.02 s, ω̇/ω = 0.1 %/s). Here, per mode, the state
x = [ω, ω̇] at the window centres follows the local linear trend

    x(t + τ) = F(τ) x(t) + w,  F(τ) = [[1, τ], [0, 1]],  E wwᵀ = (ω₀ ``trend_rate_noise``)² [[τ³/3, τ²/2], [τ²/2, τ]]

(a white-noise acceleration of ω; filterpy's ``Q_discrete_white_noise``), measured by the window's estimate
z = ω(t_c) + v, E v² = (``trend_meas_rel`` · ω)². The estimate reported at the window's end is the filter's
state carried forward by half a window, ω(t_e) = ω + ω̇ (W − 1)Δt/2, and its std √(F P Fᵀ)₀₀: a linear drift
is followed with no lag once ω̇ is learnt.

**Gate and restart.** A window estimate whose normalised innovation ν²/S exceeds ``trend_gate`` (χ², one
degree of freedom) is not used; after ``trend_restart_after`` such windows in a row the mode is restarted at
the last window's estimate: a step of the frequency is taken as a new level in about W/2 +
``trend_restart_after``·H samples, and a single outlier (a window that mislabels a mode) is ignored.
**The rate at a restart** (``TrendBank``'s ``restart_rate``). While the windows slide over a step their
estimates move from the old frequency to the new one over a window's span: a ramp that the filter may learn
as a rate, which a rate kept at the restart carries past the new level. "keep" (the default) keeps the rate
and its variance; "reset" sets the rate to 0 ± ``trend_rate0`` · ω; "hold" also lets every later window that
still holds a sample from before the end of the first gated window — one that may straddle the change —
re-initialise the mode at its own estimate (level variance R, rate 0) instead of updating it, until the first
window wholly after that point. The hold removes a ramp's overshoot but is not the default: it slowed the
re-convergence on six-mode and short-dwell records (likely because its windows are not gated;
docs/measured/tracking_gated_pencil.md, "The trend stage after a step"). "freeze" (an option of ``gated_pencil``,
``trend_restart_rate``; not its default, same page) keeps the gate: the first window the gate refuses, ending
at t_f, holds the change somewhere in its span, so the windows that ended before its start are the last wholly
before it; the rate (and its variance) goes back to the one after the last of them (what the ramp taught since
is forgotten), and every window that starts before t_f — one that may straddle the change — is still gated but
updates the level only (the rate's cross-covariance set to 0 before the update: a sample of the level, not of
the rate); a gap re-level (below) starts the same hold at its window's end. The first window that starts after
t_f closes the hold: a level-only update, or the level itself where the gate refuses it (its jump from the
straddling windows' level is the rest of the step). A rate learnt before the change (a drift) is kept
throughout.
**The gate's std.** A tracker that weighs its
windows by their own std inflated for their overlap (``gated_pencil``: R = (W/H)·std², consecutive windows
sharing W − H samples) gives the window's own std too (``gate_std``): the gate tests ν against √(P₀₀ + std² +
(``trend_meas_rel``·ω)²), the one window's error, while the update weighs it by the inflated R — tested against
the inflated R, a window 4 % off after a step with a std of 1 % passes the gate (√10 × 1 %) and the level
follows the step as a ramp, learning a rate that then overshoots.
**A gap.** When no window has determined a mode for
more than half a window's span (the windows over a step that rang the modes often fail the fit's tests), the
prediction's variance has grown by the rate's, (τ·σ_ω̇)², and the first window after the gap passes the
gate however far the frequency jumped; an update would spread the jump over the gap as a rate, which then
overshoots. So a window after such a gap whose innovation fails the gate against the variance the level had
before the gap, ν² > ``trend_gate`` · (P₀₀ at the last update + R) (R with the gate's std), sets the level
(variance R) and keeps
the rate held before the gap: a step is a new level, a drift keeps its learnt rate, and a window that agrees
with the prediction updates the filter as any other (``relevel_gap``, on).
**A change of span** (``TrendBank``'s ``span_relevel``, ``gated_pencil``'s ``trend_span_relevel``,
on by default). A window estimate is stamped at its window's centre and averages the frequency over its span;
when the span changes (``window_from_estimates`` shortening a capped 40 s window to 10 s at once), the new
window's stamp moves by half the difference of the spans and it forgets what the longer one averaged, so the
step from the last long window's estimate to the first short one's is no sample of a rate. Where the span of a
mode's window differs from the span of the last window that updated it by more than a factor 2 — the stamp
moving by more than the new window's half-span — that window sets the level and keeps the rate and its
variance, as after a gap; the level's variance is the window's own (the gate's std, not the overlap-inflated R,
which would open the gate to the windows after it), and every later window that starts before that window's
end — one that still shares samples with it — is gated as any other but updates the level only (the rate's
cross-covariance set to 0, as ``freeze``'s straddling windows): without this hold the short windows that slide
over a step just after the collapse teach the rate their ramp (on the capped design records this doubled the
replicates over 10 periods). The windows after the hold update the filter as any other.
A mode starts at its first window estimate the method calls determined (``converged_per_mode``), rate 0
with std ``trend_rate0`` · ω per second; windows it does not determine are skipped (the filter only
predicts). Reported ``converged``: the mode is started and its last determined window passed the gate.

Causal: the output at window j uses windows 0 … j only.
"""

from __future__ import annotations

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

from methods.tracking import _defaults

# what a gate restart does with the rate (module docstring): "keep" keeps the rate learnt before; "reset" sets
# it to 0 ± trend_rate0; "hold" also re-initialises the mode from the windows that may straddle the change;
# "freeze" restores the rate from before the change and lets those windows (gated) update the level only
RESTART_RATES = ("hold", "reset", "keep", "freeze")
RESTART_RATE = "keep"
# span_relevel: a window whose span differs from the last used window's by more than this factor sets the level
# (its stamp, the centre, moves by more than its own half-span)
SPAN_FACTOR = 2.0
TREND_FIELDS = ("trend", "trend_rate_noise", "trend_meas_rel", "trend_gate", "trend_restart_after", "trend_rate0")
# trend_rate_noise (s^-1.5) and trend_rate0 (s^-1): None = from the prior's slowest period
# (:func:`methods.tracking._defaults.trend_noises`; 1e-4 and 0.002 on the tracking grid's records).
DEFAULTS = {"trend": False, "trend_rate_noise": None, "trend_meas_rel": 0.005, "trend_gate": 9.0,
            "trend_restart_after": 2, "trend_rate0": None}
TYPES = {"trend": bool, "trend_rate_noise": float | None, "trend_meas_rel": float, "trend_gate": float,
         "trend_restart_after": int, "trend_rate0": float | None}


def check(opts, tracker: str) -> None:
    """``ValueError`` (one line, naming the option) for an impossible trend option of ``opts``."""
    if not isinstance(opts.trend, bool):
        raise ValueError(f"{tracker}: trend = {opts.trend!r} must be true or false")
    for name in ("trend_rate_noise", "trend_rate0"):
        value = getattr(opts, name)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value >= 0):
            raise ValueError(f"{tracker}: {name} = {value!r} must be a finite number ≥ 0")
    for name in ("trend_meas_rel", "trend_gate"):
        value = getattr(opts, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0):
            raise ValueError(f"{tracker}: {name} = {value!r} must be a finite number > 0")
    n = opts.trend_restart_after
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"{tracker}: trend_restart_after = {n!r} must be an integer ≥ 1")


def settings(opts, prior) -> dict:
    """The keywords of :class:`TrendBank` from ``opts``' ``trend_*`` options, the noises left None taken from
    the prior (:func:`methods.tracking._defaults.trend_noises`)."""
    noises = _defaults.trend_noises(prior)
    return {"rate_noise": noises["trend_rate_noise"] if opts.trend_rate_noise is None else opts.trend_rate_noise,
            "meas_rel": opts.trend_meas_rel, "gate": opts.trend_gate, "restart_after": opts.trend_restart_after,
            "rate0": noises["trend_rate0"] if opts.trend_rate0 is None else opts.trend_rate0}


class TrendBank:
    """The local-linear-trend filters of m modes, fed one window at a time (module docstring).

    :meth:`step` takes window j's centre time and half-span (per mode, or one for all), estimates,
    determined flags, (optional) stds that weigh the update and (optional) the windows' own stds that the
    gate tests against (module docstring); it returns the estimates carried to the window's end, their std,
    the converged flags and each mode's normalised innovation ν/√S (NaN where the mode was not updated or
    not started), which a change detector reads; ``level_only`` (per mode, optional): the mode's window, if the
    gate takes it, updates the level only and leaves the rate (``gated_pencil``'s ``own_windows`` feed: a rate
    from a few short windows would carry the level away). :meth:`restart` forgets a mode: it starts again at its
    next determined estimate.
    """

    def __init__(self, m: int, *, rate_noise: float, meas_rel: float, gate: float, restart_after: int,
                 rate0: float, restart_rate: str = RESTART_RATE, relevel_gap: bool = True,
                 span_relevel: bool = False):
        if restart_rate not in RESTART_RATES:
            raise ValueError(f"restart_rate = {restart_rate!r} must be one of {', '.join(RESTART_RATES)}")
        self.m, self.rate_noise, self.meas_rel = m, rate_noise, meas_rel
        self.gate, self.restart_after, self.rate0 = gate, restart_after, rate0
        self.restart_rate, self.relevel_gap, self.span_relevel = restart_rate, relevel_gap, span_relevel
        self.span_update = np.full(m, np.nan)       # span (s) of the mode's last used window
        self.span_hold_until = np.full(m, -np.inf)  # span_relevel: windows starting before this update the level
        self.kf: list = [None] * m
        self.t_last = np.zeros(m)
        self.w0 = np.zeros(m)
        self.misses = np.zeros(m, dtype=int)
        self.ok = np.zeros(m, dtype=bool)
        self.restarts = np.zeros(m, dtype=int)
        self.first_miss_end = np.full(m, -np.inf)   # end time of the first gated window of the current run
        self.hold_until = np.full(m, -np.inf)       # after a restart: windows starting before this re-initialise
        self.t_update = np.full(m, -np.inf)         # centre time of the mode's last used window
        self.p_update = np.zeros(m)                 # the level's variance after it
        self.relevels = np.zeros(m, dtype=int)
        self.history: list[list] = [[] for _ in range(m)]   # "freeze": (window end, rate, its variance) per update

    def restart(self, i: int) -> None:
        self.kf[i] = None
        self.misses[i] = 0
        self.ok[i] = False
        self.hold_until[i] = -np.inf

    def relevel(self, i: int, t_c: float, zi: float, r_var: float) -> None:
        """Mode i's level set to ``zi`` (variance ``r_var``) at time ``t_c``, its rate kept: a change another
        test found (``gated_pencil``'s ``own_windows``); a mode not started starts at its next estimate."""
        kf = self.kf[i]
        if kf is None:
            return
        self.t_last[i], self.hold_until[i] = t_c, -np.inf
        self._set_level(i, kf, t_c, zi, r_var)

    def _set_level(self, i: int, kf, t_c: float, zi: float, r_var: float) -> None:
        """Mode i's level set to ``zi`` with variance ``r_var`` by the window at ``t_c``, its rate and the rate's
        variance kept (a re-level: counted in ``relevels``)."""
        kf.x = np.array([zi, kf.x[1]])
        kf.P = np.diag([r_var, kf.P[1, 1]])
        self.misses[i], self.ok[i] = 0, True
        self.t_update[i], self.p_update[i] = t_c, r_var
        self.relevels[i] += 1

    def _level(self, kf, zi: float, r_var: float) -> None:
        """Re-initialise a filter at the window estimate ``zi``: level variance R, rate 0 ± ``rate0``·ω."""
        kf.x = np.array([zi, 0.0])
        kf.P = np.diag([r_var, (self.rate0 * zi) ** 2])

    def _remember(self, i: int, kf, t_end: float, span: float) -> None:
        """Keep the rate after an update of the window ending at ``t_end`` (two spans back, and one older)."""
        h = self.history[i]
        h.append((t_end, float(kf.x[1]), float(kf.P[1, 1])))
        old = [k for k, entry in enumerate(h) if entry[0] < t_end - 2 * span]
        if len(old) > 1:
            del h[:old[-1]]

    def _freeze(self, i: int, kf, t_end: float, span: float) -> None:
        """The first window the gate refuses (ending at ``t_end``) holds a change somewhere in its span: the
        windows that ended before its start are the last wholly before the change, so the rate (and its
        variance) goes back to the one after the last of them, and the windows that may straddle the change
        (starting before ``t_end``) update the level only (``step``)."""
        before = [entry for entry in self.history[i] if entry[0] <= t_end - span]
        if before:
            _, rate, var = before[-1]
            kf.x = np.array([kf.x[0], rate])
            kf.P = np.diag([kf.P[0, 0], var])
        self.hold_until[i] = t_end

    def step(self, t_c: float, lead: float, z: np.ndarray, determined: np.ndarray, meas_std=None, gate_std=None,
             level_only=None):
        out = np.full(self.m, np.nan)
        std = np.full(self.m, np.nan)
        nu_norm = np.full(self.m, np.nan)
        t_c = np.broadcast_to(np.asarray(t_c, dtype=float), (self.m,))
        lead = np.broadcast_to(np.asarray(lead, dtype=float), (self.m,))
        for i in range(self.m):
            ahead = np.array([[1.0, lead[i]], [0.0, 1.0]])
            zi = z[i]
            good = bool(determined[i]) and np.isfinite(zi) and zi > 0
            r_std = self.meas_rel * zi
            if meas_std is not None and np.isfinite(meas_std[i]):
                r_std = float(np.hypot(meas_std[i], r_std))
            g_std = r_std                   # the gate's: the window's own std, where given (docstring)
            if gate_std is not None and np.isfinite(gate_std[i]):
                g_std = float(np.hypot(gate_std[i], self.meas_rel * zi))
            kf = self.kf[i]
            if kf is None:
                if not good:
                    continue
                kf = self.kf[i] = KalmanFilter(dim_x=2, dim_z=1)
                kf.H = np.array([[1.0, 0.0]])
                self._level(kf, zi, r_std ** 2)
                self.t_last[i], self.w0[i], self.ok[i], self.t_update[i] = t_c[i], zi, True, t_c[i]
                self.p_update[i] = kf.P[0, 0]
            else:
                tau = t_c[i] - self.t_last[i]
                self.t_last[i] = t_c[i]
                kf.F = np.array([[1.0, tau], [0.0, 1.0]])
                kf.Q = Q_discrete_white_noise(dim=2, dt=tau, var=(self.rate_noise * self.w0[i]) ** 2)
                kf.predict()
                straddles = t_c[i] - lead[i] <= self.hold_until[i]
                closing = (good and self.restart_rate == "freeze" and not straddles
                           and np.isfinite(self.hold_until[i]))
                if closing:
                    # the first window wholly after the change closes the hold: a sample of the level only, and
                    # the level itself where the gate refuses it (its jump from the straddling windows' level
                    # is the rest of the step, not a rate)
                    straddles, self.hold_until[i] = True, -np.inf
                if good and straddles and self.restart_rate == "hold":
                    # after a restart, a window that still holds samples from before the first gated
                    # window's end mixes the old and the new frequency: its estimate is the level, no rate
                    self._level(kf, zi, r_std ** 2)
                    self.ok[i] = True
                    self.t_update[i], self.p_update[i] = t_c[i], kf.P[0, 0]
                elif (good and self.span_relevel and np.isfinite(self.span_update[i]) and self.span_update[i] > 0
                      and lead[i] > 0 and abs(np.log(2 * lead[i] / self.span_update[i])) > np.log(SPAN_FACTOR)):
                    # the window's span changed by more than SPAN_FACTOR: its stamp and memory moved, the jump
                    # from the last window's level is no rate (docstring, "A change of span"); the level's
                    # variance is the window's own (the gate's), so windows that straddle a later change fail
                    self._set_level(i, kf, t_c[i], zi, g_std ** 2)
                    self.span_hold_until[i] = t_c[i] + lead[i]
                elif (good and self.relevel_gap and t_c[i] - self.t_update[i] > lead[i]
                      and (zi - kf.x[0]) ** 2 > self.gate * (self.p_update[i] + g_std ** 2)):
                    # no window determined the mode for more than half a window's span: the level is the
                    # window's, the rate the one held before the gap (spreading a jump over the gap as a rate
                    # overshoots)
                    self._set_level(i, kf, t_c[i], zi, r_std ** 2)
                    if self.restart_rate == "freeze" and not straddles:
                        self.hold_until[i] = t_c[i] + lead[i]      # the change lies before this window's end
                elif good:
                    kf.R = np.array([[r_std ** 2]])
                    nu = zi - kf.x[0]
                    s = kf.P[0, 0] + kf.R[0, 0]
                    nu_norm[i] = nu / np.sqrt(s)
                    if nu * nu / (kf.P[0, 0] + g_std ** 2) <= self.gate:
                        if ((straddles and self.restart_rate == "freeze") or (level_only is not None and level_only[i])
                                or t_c[i] - lead[i] <= self.span_hold_until[i]):
                            # a window that may straddle the change: a sample of the level, not of the rate
                            # (the ramp of such windows is the window sliding over a step, not a drift)
                            kf.P[0, 1] = kf.P[1, 0] = 0.0
                        kf.update(np.array([zi]))
                        self.misses[i], self.ok[i] = 0, True
                        self.t_update[i], self.p_update[i] = t_c[i], kf.P[0, 0]
                    elif closing:
                        self._set_level(i, kf, t_c[i], zi, r_std ** 2)
                    else:
                        if self.misses[i] == 0:
                            self.first_miss_end[i] = t_c[i] + lead[i]
                            if self.restart_rate == "freeze" and not straddles:
                                self._freeze(i, kf, t_c[i] + lead[i], 2 * lead[i])
                        self.misses[i] += 1
                        self.ok[i] = False
                        if self.misses[i] >= self.restart_after:
                            if self.restart_rate in ("keep", "freeze"):
                                kf.x = np.array([zi, kf.x[1]])
                                kf.P = np.diag([kf.R[0, 0], kf.P[1, 1]])
                                if self.restart_rate == "freeze" and not straddles:
                                    self.hold_until[i] = self.first_miss_end[i]
                            else:
                                self._level(kf, zi, kf.R[0, 0])
                                if self.restart_rate == "hold":
                                    self.hold_until[i] = self.first_miss_end[i]
                            self.misses[i], self.ok[i] = 0, True
                            self.restarts[i] += 1
                            self.t_update[i], self.p_update[i] = t_c[i], kf.P[0, 0]
            if self.t_update[i] == t_c[i]:
                self.span_update[i] = 2 * lead[i]
            if self.restart_rate == "freeze" and self.t_update[i] == t_c[i]:
                self._remember(i, kf, t_c[i] + lead[i], 2 * lead[i])
            x = ahead @ kf.x
            P = ahead @ kf.P @ ahead.T
            out[i] = x[0]
            std[i] = np.sqrt(max(P[0, 0], 0.0))
        return out, std, self.ok & np.array([k is not None for k in self.kf]), nu_norm


def smooth(t_end_s: np.ndarray, frequencies: np.ndarray, determined: np.ndarray, window_s, *,
           rate_noise: float, meas_rel: float, gate: float, restart_after: int, rate0: float,
           meas_std: np.ndarray | None = None, restart_rate: str = RESTART_RATE):
    """Run the trend stage over a track's window estimates (module docstring; ``restart_rate``: what a
    restart does with the rate, :data:`RESTART_RATES`).

    Parameters
    ----------
    t_end_s : (K,) the windows' last sample times; ``frequencies``, ``determined`` : (K, m) their estimates
    window_s : (W − 1)Δt, the span of a window (a number, or (K,) spans of windows of varying length).

    Returns
    -------
    (frequencies, std, converged, restarts): (K, m) at the windows' ends, and the restarts per mode.
    """
    t_end_s = np.asarray(t_end_s, dtype=float)
    K, m = frequencies.shape
    lead = np.broadcast_to(np.asarray(window_s, dtype=float) / 2.0, (K,))
    bank = TrendBank(m, rate_noise=rate_noise, meas_rel=meas_rel, gate=gate, restart_after=restart_after,
                     rate0=rate0, restart_rate=restart_rate)
    out = np.full((K, m), np.nan)
    std = np.full((K, m), np.nan)
    conv = np.zeros((K, m), dtype=bool)
    for j in range(K):
        out[j], std[j], conv[j], _ = bank.step(t_end_s[j] - lead[j], lead[j], frequencies[j], determined[j],
                                               None if meas_std is None else meas_std[j])
    return out, std, conv, bank.restarts


def apply(opts, t_end_s: np.ndarray, frequencies: np.ndarray, std, determined: np.ndarray, window_s,
          extra: dict, meas_std: np.ndarray | None = None, prior=None):
    """The trend stage as a windowed tracker runs it when ``opts.trend``: the raw window estimates kept in
    ``extra`` ("window_frequencies", "window_converged", and the restarts per mode), then :func:`smooth` with
    the ``trend_*`` options. Returns (frequencies, std, determined, restarts); ``opts.trend`` false: the
    window estimates unchanged, std NaN, restarts None."""
    if not opts.trend:
        return frequencies, np.nan, determined, None
    extra |= {"window_frequencies": frequencies, "window_converged": determined}
    freq, std, found, restarts = smooth(t_end_s, frequencies, determined, window_s, meas_std=meas_std,
                                        **settings(opts, prior))
    extra["trend_restarts"] = restarts
    return freq, std, found, restarts
