"""Records the identification model does not describe exactly: the mismatch axes of the honesty grid.

Every method's model is "m damped sinusoids in white noise". A practitioner's record is never that; these
axes put one departure at a time into the truth plant's record, so that a method's reported std can be
scored where it can fail. They are scenario axes (``experiments.simulate.scenarios``) applied by
``experiments.simulate.datasets.make_cell``; ``configs/grid/mismatch.yaml`` sweeps them and
``experiments.benchmarks.mismatch`` scores the stds on them.

- ``ar1`` = φ in (−1, 1): the measurement noise is AR(1), nₖ = φnₖ₋₁ + √(1 − φ²)σwₖ (same variance σ²);
- ``unmodelled_mode`` = r ≥ 0: a fifth mode at ``UNMODELLED_RAD_S`` (cantilever mode 4, above the prior's
  band) of r × mode 4's amplitude;
- ``duffing`` = δ: every mode a Duffing oscillator ẍ + 2ζωẋ + ω²x + εx³ = 0 with the backbone
  ω(A) = ω√(1 + 2δA²), A = 1 at release (frequency ≈ (1 + δ)ω there; δ < 0 softening);
- ``saturation`` = s in (0, 1]: the sensor clips at s × the largest clean |sample|;
- ``quantisation`` = q > 0: the sensor rounds to a step of q × σ (after the noise), on a grid offset by its
  own fraction of a step in each record (:func:`sensor`).

The truth that scores a cell is the generating model's small-amplitude eigenfrequencies (the plant's), for
the Duffing axis too: the frequency a linear model of the structure would have. A method that averages a
drifting frequency over the record is biased against it, which is what the drift test
(``methods.pem.segment_drift``) reports.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["UNMODELLED_RAD_S", "UNMODELLED_DAMPING", "AXES", "ar1_noise", "duffing_modes", "backbone_rad_s",
           "RANGES", "check_axes", "present", "mismatched_signal", "noise", "sensor"]

UNMODELLED_RAD_S = 111.068       # cantilever mode 4 (docs: PHYSICS.md §1): the beam's next mode
UNMODELLED_DAMPING = 0.005
AXES = ("ar1", "unmodelled_mode", "duffing", "saturation", "quantisation")


def ar1_noise(rng: np.random.Generator, n: int, sigma: float, phi: float) -> np.ndarray:
    """Stationary AR(1) noise of std σ: nₖ = φnₖ₋₁ + √(1 − φ²)σwₖ, n₀ ~ N(0, σ²) (scipy.signal.lfilter)."""
    import scipy.signal  # only a mismatch cell needs it; at module level every job paid its ~0.7 s import

    if not -1 < phi < 1:
        raise ValueError(f"ar1 = {phi} must be inside (-1, 1)")
    w = sigma * rng.standard_normal(n)
    out = np.empty(n)
    out[0] = w[0]                                   # started in the stationary law N(0, σ²)
    out[1:], _ = scipy.signal.lfilter([math.sqrt(1.0 - phi * phi)], [1.0, -phi], w[1:], zi=[phi * w[0]])
    return out


def duffing_modes(t: np.ndarray, freq_rad_s, damping, amplitude, phase, delta: float) -> np.ndarray:
    """Σᵢ aᵢxᵢ(t), each xᵢ a Duffing oscillator ẍ + 2ζωẋ + ω²x + εx³ = 0, ε = 8ω²δ/3 (so the backbone is
    ω(A) = ω√(1 + 3εA²/(4ω²)) = ω√(1 + 2δA²)), started where the linear mode aᵢe^{−ζωt}cos(ω_d t + φᵢ)
    starts (x(0) = cos φ, ẋ(0) = −ω_d sin φ − ζω cos φ). scipy.integrate.solve_ivp (DOP853, rtol 1e-10)."""
    import scipy.integrate  # only a Duffing cell needs it (start-up time of every other job)

    out = np.zeros(t.size)
    for w, z, a, ph in zip(freq_rad_s, damping, amplitude, phase, strict=True):
        eps = 8.0 * w * w * delta / 3.0
        wd = w * math.sqrt(1.0 - z * z)

        def rhs(_, s, w=w, z=z, eps=eps):
            return [s[1], -2 * z * w * s[1] - w * w * s[0] - eps * s[0] ** 3]

        x0 = [math.cos(ph), -wd * math.sin(ph) - z * w * math.cos(ph)]
        sol = scipy.integrate.solve_ivp(rhs, (0.0, float(t[-1])), x0, method="DOP853", t_eval=t,
                                        rtol=1e-10, atol=1e-12)
        if not sol.success:
            raise ValueError(f"duffing = {delta}: the oscillator at {w:.4g} rad/s did not integrate ({sol.message})")
        out += a * sol.y[0]
    return out


def backbone_rad_s(freq_rad_s: float, amplitude, delta: float) -> np.ndarray:
    """ω(A) = ω√(1 + 2δA²): the Duffing oscillator's frequency at (normalised) amplitude A."""
    return freq_rad_s * np.sqrt(1.0 + 2.0 * delta * np.asarray(amplitude, float) ** 2)


def record_frequency_rad_s(freq_rad_s, damping, delta: float, n_samples: int, dt: float) -> np.ndarray:
    """The frequency a Duffing record holds, per mode: the instantaneous backbone frequency ω(A(t)) averaged
    over the record with the weight A(t)² (a constant-frequency fit weighs each sample by its amplitude
    squared), A(t) = e^{−ζωt} the normalised envelope. The truth for an answer that refers to the record's
    own amplitude (a mode whose frequency the record shows as constant); the small-amplitude one is ω."""
    w, z = np.asarray(freq_rad_s, float), np.asarray(damping, float)
    t = np.arange(int(n_samples)) * float(dt)
    a = np.exp(-np.outer(z * w, t))
    return np.sum(a ** 2 * backbone_rad_s(w[:, None], a, delta), axis=1) / np.sum(a ** 2, axis=1)


RANGES = {"ar1": (-1.0, 1.0, "inside (-1, 1)"), "unmodelled_mode": (0.0, math.inf, "at least 0"),
          "duffing": (-0.25, 1.0, "inside (-0.25, 1)"), "saturation": (0.0, 1.0, "in (0, 1]"),
          "quantisation": (0.0, math.inf, "positive")}


def check_axes(axes: dict) -> None:
    """``ValueError`` naming the first unknown axis or impossible value."""
    for key, value in axes.items():
        if key not in AXES:
            raise ValueError(f"mismatch axis '{key}' is not one of {', '.join(AXES)}")
        lo, hi, text = RANGES[key]
        v = float(value)
        ok = {"unmodelled_mode": lo <= v, "saturation": lo < v <= hi}.get(key, lo < v < hi)
        if not ok:
            raise ValueError(f"mismatch axis {key} = {value} must be {text}")


def present(axes: dict) -> dict:
    """The mismatch axes of a cell's axes (those set and not None)."""
    return {k: axes[k] for k in AXES if axes.get(k) is not None}


def mismatched_signal(truth: dict, clean: np.ndarray, dt: float, axes: dict) -> np.ndarray:
    """The noise-free record of a cell: the plant's ``clean`` record, or the Duffing modes in its place,
    plus the unmodelled mode. ``truth``: the plant's freq_rad_s, damping, amplitude_m_s2, phase_rad."""
    t = dt * np.arange(clean.size)
    signal = clean
    if axes.get("duffing"):
        signal = duffing_modes(t, truth["freq_rad_s"], truth["damping"], truth["amplitude_m_s2"],
                               truth["phase_rad"], float(axes["duffing"]))
    if axes.get("unmodelled_mode"):
        a = float(axes["unmodelled_mode"]) * float(truth["amplitude_m_s2"][-1])
        wu, zu = UNMODELLED_RAD_S, UNMODELLED_DAMPING
        signal = signal + a * np.exp(-zu * wu * t) * np.cos(wu * math.sqrt(1 - zu * zu) * t)
    return signal


def noise(rng: np.random.Generator, n: int, sigma: float, axes: dict) -> np.ndarray:
    """One replicate's measurement noise: white, or AR(1) (:func:`ar1_noise`) with the ``ar1`` axis."""
    phi = float(axes.get("ar1") or 0.0)
    return ar1_noise(rng, n, sigma, phi) if phi else sigma * rng.standard_normal(n)


def sensor(y: np.ndarray, signal: np.ndarray, sigma: float, axes: dict,
           rng: np.random.Generator | None = None) -> np.ndarray:
    """What the sensor gives for y: clipped at ``saturation`` × max|signal|, rounded to ``quantisation`` × σ.

    With ``rng`` the rounding grid is offset by u·step, u ~ U(−½, ½) drawn per record: a converter's zero
    is not the structure's, and each record's is its own. Without it every replicate of a cell (the same
    clean signal) is rounded on the same grid, so the rounding error's part that follows the signal is one
    draw shared by all of them: a coverage over the replicates then scores one rounding pattern, not the
    population of records it describes (measured: docs/uncertainty.md §5)."""
    if axes.get("saturation"):
        limit = float(axes["saturation"]) * float(np.max(np.abs(signal)))
        y = np.clip(y, -limit, limit)
    if axes.get("quantisation"):
        step = float(axes["quantisation"]) * sigma
        u = 0.0 if rng is None else float(rng.uniform(-0.5, 0.5))
        y = step * (np.round(y / step - u) + u)
    return y
