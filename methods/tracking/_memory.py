"""The automatic memory of the windowed trackers: a change detector that restarts the window after a jump.

Why this one. A window tracker trusts the last W samples; W must be long for a noisy or slowly resolved mode
and short for a frequency that jumps. Three ways to let the tracker choose were open: a window
that shortens while the frequencies drift, an IMM over a few memory lengths, or a change detector that
restarts the window after a jump. Under a drift the trend stage (:mod:`methods.tracking._trend`) already
removes the lag of a long window (a straight line is followed with no lag once its rate is learnt), so a
shorter window buys nothing there but noise; what a long window cannot do is forget a step: every window
that straddles it mixes the two frequencies (the shared-frequency segment fit of ``gated_pencil``, one pole
per mode) and is gated out by the trend stage until the window has passed the step, W/2 + 2H samples after
it. An IMM over memory lengths would run every window length at every hop (the cost of the costliest times
the number of models) to learn what one test on the innovations already says. So: a **two-sided CUSUM**
(Page 1954; Basseville & Nikiforov, *Detection of Abrupt Changes*, 1993, §2.2) per mode on the trend
filter's normalised innovations ν̃ = ν/√S of the window estimates,

    g⁺(j) = max(0, g⁺(j−1) + ν̃(j) − κ),   g⁻(j) = max(0, g⁻(j−1) − ν̃(j) − κ),   alarm: max(g⁺, g⁻) > h,

(κ = ``change_drift``, h = ``change_threshold``, both in units of the innovation's std: dimensionless, the
same at every Δt and frequency). A drift is followed by the trend filter, so its innovations stay centred and
the sums stay near 0 (no false restart); a step makes them all one sign, and the alarm comes within a few
hops of the first window that carries it. On an alarm the window restarts just after the end of the last
window whose sums were both 0 (the last window that showed no change): later windows hold only the samples
from there on, y[max(e − W + 1, start) … e], and determine nothing until they hold
``_defaults.restart_samples`` (the model's minimum, at least two periods of the slowest mode), growing back
to W; the alarmed modes' trend filters start again at their first new estimate. Written by hand: the CUSUM
recursion is two lines, and the restart must reach into the tracker's window loop (no kept library does it).
"""

from __future__ import annotations

import numpy as np

DEFAULTS = {"memory": False, "change_threshold": 5.0, "change_drift": 0.5}
FIELDS = tuple(DEFAULTS)


def check(opts, tracker: str) -> None:
    """``ValueError`` (one line, naming the option) for an impossible memory option."""
    if not isinstance(opts.memory, bool):
        raise ValueError(f"{tracker}: memory = {opts.memory!r} must be true or false")
    for key in ("change_threshold", "change_drift"):
        value = getattr(opts, key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0):
            raise ValueError(f"{tracker}: {key} = {value!r} must be a finite number > 0")


class Cusum:
    """Two-sided CUSUM per mode on normalised innovations (module docstring)."""

    def __init__(self, m: int, threshold: float, drift: float):
        self.h, self.k = threshold, drift
        self.up = np.zeros(m)
        self.down = np.zeros(m)
        self.clean_end = np.full(m, -1)

    def update(self, nu_norm: np.ndarray, end_sample: int) -> np.ndarray:
        """Feed window estimates' normalised innovations (NaN: no update for that mode); return the modes in
        alarm. ``end_sample``: the window's last sample, remembered while both sums are 0."""
        ok = np.isfinite(nu_norm)
        x = np.where(ok, nu_norm, 0.0)
        self.up = np.where(ok, np.maximum(0.0, self.up + x - self.k), self.up)
        self.down = np.where(ok, np.maximum(0.0, self.down - x - self.k), self.down)
        self.clean_end = np.where((self.up == 0) & (self.down == 0), end_sample, self.clean_end)
        return (self.up > self.h) | (self.down > self.h)

    def restart_sample(self, alarm: np.ndarray) -> int:
        """First sample of the restarted window: after the last clean window of the alarmed modes."""
        return int(np.min(self.clean_end[alarm])) + 1

    def reset(self, end_sample: int) -> None:
        self.up[:] = 0.0
        self.down[:] = 0.0
        self.clean_end[:] = end_sample
