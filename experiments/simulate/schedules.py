"""Schedules of the modal frequencies over a record: fuel burn, drift, a step, sloshing (the tracking truth).

A schedule gives the instantaneous natural frequency of every mode at every sample,

    ωᵢ(t) = ωᵢ⁰(m(t)) · (1 + dᵢ s(t)) · (1 + jᵢ H(t − t_step)) · (1 + aᵢ sin(2π f_slosh t + φ_slosh)),

each factor optional (a schedule with none of them is the constant, frozen plant):

* ``propellant_kg`` (**fuel**): the rigid body's mass falls linearly by this much between ``burn_start_s``
  and ``burn_end_s`` (default: the whole record); ωᵢ⁰(m) are the coupled eigenfrequencies of the 20-state
  plant (``experiments.simulate.plant``) with that body mass and the calibrated beam stiffness, so the drift
  is derived from the plant's mass. Here it is small: halving the 270 kg body raises mode 1 by 2.6 % and the
  others by < 0.6 % (the body is 50× the beam).
* ``drift`` (**the paper's 20–30 %**): a documented per-mode scaling dᵢ, reached along the ramp
  s(t) = clip((t − ramp_start_s)/(ramp_end_s − ramp_start_s), 0, 1). The paper expects frequencies "to vary
  as much as 20–30 %, due to splashing and consumption of rocket fuel" (§1) without a model of it; a mass
  on the body cannot give that much here, so the figure is imposed per mode.
* ``step`` (**a latch or a deployment**): the factor (1 + jᵢ) from ``step_time_s`` on.
* ``slosh`` (**sloshing**): a modulation of relative amplitude aᵢ (a few %) at ``slosh_hz``.

The mode shapes (tip and input gains) stay those of the nominal plant: the frequencies change, the way the
modes are seen and driven does not (see ``experiments.simulate.timevarying``). A schedule that makes two
modes cross or meet, or puts a mode at or above Nyquist π/Δt, is refused (``ValueError``, one line).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from experiments.simulate.plant import Plant, PlantConfig, build_plant

__all__ = ["MASS_GRID_POINTS", "ScheduleConfig", "body_mass_kg", "check_frequencies", "events", "frequencies",
           "mass_frequencies", "per_mode", "step_time"]

MASS_GRID_POINTS = 33      # eigenfrequencies of the plant at this many body masses, interpolated between


@dataclass
class ScheduleConfig:
    """One frequency schedule. Per-mode values are a number (every mode) or one value per mode; units in names."""

    propellant_kg: float = 0.0
    burn_start_s: float = 0.0
    burn_end_s: float | None = None            # None: the end of the record
    drift: float | list[float] | None = None
    ramp_start_s: float = 0.0
    ramp_end_s: float | None = None            # None: the end of the record
    step: float | list[float] | None = None
    step_time_s: float | None = None           # None: the middle of the record
    slosh: float | list[float] | None = None
    slosh_hz: float = 0.05
    slosh_phase_rad: float = 0.0


def per_mode(value, m: int, name: str) -> np.ndarray:
    """A per-mode setting as m numbers; ``None`` is 0 for every mode."""
    if value is None:
        return np.zeros(m)
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.size == 1:
        return np.full(m, float(arr[0]))
    if arr.size != m:
        raise ValueError(f"schedule.{name} = {list(arr)} has {arr.size} entries; the plant has {m} modes")
    return arr


def body_mass_kg(cfg: ScheduleConfig, plant_cfg: PlantConfig, t_s: np.ndarray) -> np.ndarray:
    """m(t): the body's mass, falling linearly by ``propellant_kg`` over the burn."""
    end = float(t_s[-1]) if cfg.burn_end_s is None else float(cfg.burn_end_s)
    start = float(cfg.burn_start_s)
    burnt = np.clip((t_s - start) / max(end - start, 1e-300), 0.0, 1.0) if end > start else (t_s >= start) * 1.0
    return plant_cfg.body_mass_kg - cfg.propellant_kg * burnt


def mass_frequencies(plant: Plant, masses_kg: np.ndarray) -> np.ndarray:
    """ωᵢ⁰(m) (rad/s), shape (len(masses), m): the plant's coupled eigenfrequencies at each body mass, its
    beam stiffness held (the calibrated one). Exact at ``MASS_GRID_POINTS`` masses and a cubic spline between
    (scipy.interpolate; the spline's error is < 1e-9 relative over a halving of the mass)."""

    lo, hi = float(np.min(masses_kg)), float(np.max(masses_kg))
    if hi - lo < 1e-12 * hi:
        return np.broadcast_to(_frequencies_at_mass(plant, hi), (masses_kg.size, plant.freq_rad_s.size)).copy()
    grid = np.linspace(lo, hi, MASS_GRID_POINTS)
    table = np.array([_frequencies_at_mass(plant, m) for m in grid])
    return CubicSpline(grid, table, axis=0)(masses_kg)


def _frequencies_at_mass(plant: Plant, mass_kg: float) -> np.ndarray:
    cfg = dataclasses.replace(plant.cfg, body_mass_kg=float(mass_kg), calibrate=False)
    return Plant(cfg, plant.cantilever_freq_rad_s).freq_rad_s


def frequencies(cfg: ScheduleConfig, plant_cfg: PlantConfig, t_s: np.ndarray, *, check: bool = True,
                dt_s: float | None = None) -> np.ndarray:
    """ωᵢ(t_k) (rad/s), shape (K, m): the schedule's instantaneous natural frequencies at the times ``t_s``.

    Parameters
    ----------
    cfg : ScheduleConfig
    plant_cfg : PlantConfig
        The nominal plant (its calibrated eigenfrequencies are ω⁰ at the full mass).
    t_s : ndarray, shape (K,)
    check : bool
        Refuse a schedule that crosses two modes or reaches Nyquist π/``dt_s`` (see :func:`check_frequencies`).
    """
    t_s = np.asarray(t_s, dtype=float)
    plant = build_plant(plant_cfg)
    m = plant.freq_rad_s.size
    if cfg.propellant_kg < 0 or cfg.propellant_kg >= plant_cfg.body_mass_kg:
        raise ValueError(f"schedule.propellant_kg = {cfg.propellant_kg:g} must be in [0, body mass "
                         f"{plant_cfg.body_mass_kg:g} kg)")
    if cfg.propellant_kg > 0:
        w = mass_frequencies(plant, body_mass_kg(cfg, plant_cfg, t_s))
    else:
        w = np.broadcast_to(plant.freq_rad_s, (t_s.size, m)).copy()
    t_end = float(t_s[-1]) if t_s.size else 0.0
    if cfg.drift is not None:
        end = t_end if cfg.ramp_end_s is None else float(cfg.ramp_end_s)
        span = end - float(cfg.ramp_start_s)
        s = np.clip((t_s - cfg.ramp_start_s) / span, 0.0, 1.0) if span > 0 else (t_s >= end) * 1.0
        w = w * (1.0 + per_mode(cfg.drift, m, "drift")[None, :] * s[:, None])
    if cfg.step is not None:
        t_step = step_time(cfg, t_end)
        w = w * (1.0 + per_mode(cfg.step, m, "step")[None, :] * (t_s >= t_step)[:, None])
    if cfg.slosh is not None:
        if not cfg.slosh_hz > 0:
            raise ValueError(f"schedule.slosh_hz = {cfg.slosh_hz:g} must be positive")
        wave = np.sin(2 * np.pi * cfg.slosh_hz * t_s + cfg.slosh_phase_rad)
        w = w * (1.0 + per_mode(cfg.slosh, m, "slosh")[None, :] * wave[:, None])
    if check:
        check_frequencies(w, t_s, dt_s)
    return w


def step_time(cfg: ScheduleConfig, t_end_s: float) -> float | None:
    """The instant of the step (s), or None for a schedule without one."""
    if cfg.step is None:
        return None
    return 0.5 * t_end_s if cfg.step_time_s is None else float(cfg.step_time_s)


def check_frequencies(w: np.ndarray, t_s: np.ndarray, dt_s: float | None) -> None:
    """Raise ``ValueError`` (one line naming the time and the modes) if a frequency is not positive, two
    modes cross or meet, or a mode reaches Nyquist π/``dt_s``."""
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        k = int(np.flatnonzero(~(np.isfinite(w).all(axis=1) & (w > 0).all(axis=1)))[0])
        raise ValueError(f"the schedule gives a frequency ≤ 0 or not finite at t = {t_s[k]:.4g} s: {w[k]}")
    gaps = np.diff(w, axis=1)
    if gaps.size and np.any(gaps <= 0):
        k, i = (int(v[0]) for v in np.nonzero(gaps <= 0))
        raise ValueError(f"the schedule crosses modes {i + 1} and {i + 2} at t = {t_s[k]:.4g} s "
                         f"({w[k, i]:.6g} ≥ {w[k, i + 1]:.6g} rad/s)")
    if dt_s is not None:
        nyquist = math.pi / float(dt_s)
        top = float(w.max())
        if top >= nyquist:
            k = int(np.argmax(w.max(axis=1)))
            raise ValueError(f"the schedule reaches {top:.4g} rad/s at t = {t_s[k]:.4g} s, at or above "
                             f"Nyquist {nyquist:.4g} rad/s (dt_s = {dt_s:g} s)")


def events(cfg: ScheduleConfig, t_s: np.ndarray) -> dict:
    """Where the scoring looks: the step's instant and the drifting span (s), None when absent."""
    t_end = float(t_s[-1])
    out: dict = {"step_time_s": step_time(cfg, t_end), "drift_span_s": None}
    if cfg.drift is not None or cfg.propellant_kg > 0:
        if cfg.drift is not None:
            lo, hi = float(cfg.ramp_start_s), t_end if cfg.ramp_end_s is None else float(cfg.ramp_end_s)
        else:
            lo, hi = float(cfg.burn_start_s), t_end if cfg.burn_end_s is None else float(cfg.burn_end_s)
        out["drift_span_s"] = [lo, min(hi, t_end)]
    return out
