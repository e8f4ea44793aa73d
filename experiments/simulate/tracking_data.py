"""Tracking records: one ``.npz`` per (schedule, excitation, noise, duration) cell, all replicates.

The truth side of the tracking benchmark; it knows nothing of the methods. A cell's records are the tip
acceleration of the spacecraft whose frequencies follow a schedule (``experiments.simulate.schedules``)
under an excitation, simulated exactly (``experiments.simulate.timevarying``), plus seeded white noise.

**Excitation** (:class:`ExcitationConfig`; any combination):

* ``release``: the paper's initial displacement (Table 2) scaled by this factor (0: none);
* ``thruster_torque_n_m``: attitude-thruster pulses, a torque ±T about z on the body held for
  ``pulse_samples`` samples; at every ``thruster_period_s`` (periodic) or, with the period None, at random
  times (a Bernoulli draw per sample, mean rate ``thruster_rate_hz``), the sign random either way;
* ``disturbance_force_n``: a white force along y, 1σ per sample, held over each sample, on the body's
  centre (``disturbance_at: body``, the environment's and the thrusters' noise) or on the tip (``tip``:
  then its direct term, c M⁻¹ c ≈ 3 m/s² per N, is a white signal far above the modes' response).

The random parts (pulse times and signs, the disturbance, the noise) of replicate r are drawn from
``numpy.random.default_rng([seed, noise_ng, N, r, stream])`` with one stream each, so the same config gives
the same bytes and R = 5 is a prefix of R = 20.

File schema (plain arrays, ``experiments.io.read_npz`` verifies the checksum):

| key | shape | meaning |
|---|---|---|
| ``t_s`` | (N,) | sample times t_k = k·Δt |
| ``accel_m_s2`` | (R, N) | measured tip acceleration |
| ``accel_clean_m_s2`` | (R, N) | the same without noise |
| ``truth_freq_rad_s`` | (N, m) | the instantaneous eigenfrequencies ωᵢ(t_k) (the truth) |
| ``truth_damping`` | (m,) | ζᵢ |
| ``modal_state`` | (R, N, m, 2) float32 | [ξᵢ, ξ̇ᵢ] of the truth model (for the bound) |
| ``inputs`` | (R, N, 3) float32 | torque about z (N·m), tip force, body force (N) held over each sample |
| ``prior_rad_s`` | (R, m) | the prior the harness gives every tracker |
| ``pcrb_std_rad_s`` | (R, N, m) | the **genie** posterior Cramér–Rao bound: every input known (``pcrb.cell_pcrb``) |
| ``pcrb_unknown_force_std_rad_s`` | (R, N, m) | the **unknown-force** PCRB: white force unknown, pulses known |
| ``pcrb_unknown_rate_std_rad_s`` | (R, N, m) | the **unknown-rate** PCRB, only where every frequency is a line |
| ``window_bound_std_rad_s`` | (N, m) | the best sliding window's bound, NaN between its evaluation times |
| ``dt_s``, ``noise_ug``, ``noise_std_m_s2``, ``seed`` | () | settings |
| ``step_time_s`` | () | the step's instant, NaN without one |
| ``drift_span_s`` | (2,) | the drifting span, NaN without one |
| ``config_json`` | () str | the cell's config (schedule, excitation, plant) and the seed scheme |
| ``checksum_sha256`` | () str | SHA-256 of the other entries |

The unknown-rate bound (a drift over the whole record, or a constant) is the unknown-force one with each rate
an unknown constant, prior N(0, (``RATE_PRIOR_REL_PER_S``·ω)²) per s, instead of the schedule's walk.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from experiments.io import write_npz
from experiments.simulate import pcrb, pcrb_force, schedules
from experiments.simulate.plant import PlantConfig, build_plant
from experiments.simulate.schedules import ScheduleConfig
from experiments.simulate.timevarying import INPUTS, modal_model, simulate

UG = 9.80665e-6
STREAMS = {"noise": 0, "pulse_times": 1, "pulse_signs": 2, "disturbance": 3, "prior": 4}
MIN_SAMPLES = 64
RATE_PRIOR_REL_PER_S = 1e-3   # the unknown-rate bound's prior rate, 0.1 %/s of ω (the ambient trackers' stated rate)


@dataclass
class ExcitationConfig:
    """What keeps the modes ringing (module docstring). Zero means absent."""

    release: float = 0.0
    thruster_torque_n_m: float = 0.0
    thruster_period_s: float | None = None
    thruster_rate_hz: float = 0.2
    pulse_samples: int = 1
    disturbance_force_n: float = 0.0
    disturbance_at: str = "body"


@dataclass
class TrackingCellConfig:
    """One tracking cell. Units in names."""

    schedule: ScheduleConfig = field(default_factory=ScheduleConfig)
    excitation: ExcitationConfig = field(default_factory=ExcitationConfig)
    noise_ug: float = 1000.0
    duration_s: float = 60.0
    dt_s: float = 0.02
    replicates: int = 5
    seed: int = 20261121
    prior_spread: float = 0.05        # prior ωᵢ(0)·(1 + s·uᵢ), uᵢ ~ U(−1, 1) per replicate and mode
    pcrb_rw_rel: float | None = None  # the bound's random-walk std per √s, relative to ω (None: from the schedule)
    plant: PlantConfig = field(default_factory=PlantConfig)

    def __post_init__(self):
        if isinstance(self.schedule, dict):
            self.schedule = ScheduleConfig(**self.schedule)
        if isinstance(self.excitation, dict):
            self.excitation = ExcitationConfig(**self.excitation)
        if isinstance(self.plant, dict):
            self.plant = PlantConfig(**self.plant)

    @property
    def n_samples(self) -> int:
        return int(round(self.duration_s / self.dt_s))


def check_replicates(cfg, samples_at: str) -> None:
    """``ValueError`` (one line naming the value) for a cell's noise, length, replicates or prior spread that
    cannot be simulated; ``cfg``: a spacecraft or a laboratory cell's config (``noise_ug``, ``duration_s``,
    ``n_samples``, ``replicates``, ``prior_spread``); ``samples_at`` says at which rate N is counted."""
    if not cfg.noise_ug > 0:
        raise ValueError(f"noise_ug = {cfg.noise_ug} must be positive (the 1σ noise level in µg)")
    if not (cfg.duration_s > 0 and cfg.n_samples >= MIN_SAMPLES):
        raise ValueError(f"duration_s = {cfg.duration_s} gives {cfg.n_samples} samples {samples_at}; "
                         f"at least {MIN_SAMPLES}")
    if cfg.replicates < 1:
        raise ValueError(f"replicates = {cfg.replicates} must be at least 1")
    if not 0 <= cfg.prior_spread < 1:
        raise ValueError(f"prior_spread = {cfg.prior_spread} must be in [0, 1)")


def check_cell_config(cfg: TrackingCellConfig) -> np.ndarray:
    """Raise ``ValueError`` (one line naming the value) for an impossible cell; return its schedule ω(t)."""
    if not cfg.dt_s > 0:
        raise ValueError(f"dt_s = {cfg.dt_s} must be positive")
    check_replicates(cfg, f"at dt_s = {cfg.dt_s}")
    ex = cfg.excitation
    for name in ("release", "thruster_torque_n_m", "disturbance_force_n"):
        value = getattr(ex, name)
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"excitation.{name} = {value} must be a finite number ≥ 0")
    if ex.release == 0 and ex.thruster_torque_n_m == 0 and ex.disturbance_force_n == 0:
        raise ValueError("the excitation is empty: set release, thruster_torque_n_m or disturbance_force_n")
    if ex.thruster_torque_n_m > 0:
        if ex.thruster_period_s is not None and not ex.thruster_period_s >= cfg.dt_s:
            raise ValueError(f"excitation.thruster_period_s = {ex.thruster_period_s} must be at least dt_s")
        if ex.thruster_period_s is None and not 0 < ex.thruster_rate_hz * cfg.dt_s <= 1:
            raise ValueError(f"excitation.thruster_rate_hz = {ex.thruster_rate_hz} must be in (0, 1/dt_s]")
        if not (isinstance(ex.pulse_samples, int) and ex.pulse_samples >= 1):
            raise ValueError(f"excitation.pulse_samples = {ex.pulse_samples!r} must be an integer ≥ 1")
    if ex.disturbance_at not in ("body", "tip"):
        raise ValueError(f"excitation.disturbance_at = {ex.disturbance_at!r} must be 'body' or 'tip'")
    t = np.arange(cfg.n_samples) * cfg.dt_s
    w = schedules.frequencies(cfg.schedule, cfg.plant, t, dt_s=cfg.dt_s)
    top = float(w[0].max()) * (1 + cfg.prior_spread)
    if top >= math.pi / cfg.dt_s:
        raise ValueError(f"prior_spread = {cfg.prior_spread} allows a prior of {top:.4g} rad/s, at or above "
                         f"Nyquist {math.pi / cfg.dt_s:.4g} rad/s")
    return w


def cell_rng(cfg, replicate: int, stream: int) -> np.random.Generator:
    """Replicate ``replicate``'s random stream number ``stream`` of a cell (a spacecraft or a laboratory cell):
    ``numpy.random.default_rng([seed, round(noise_ug*1000), N, replicate, stream])``, so that a cell's records
    do not depend on the other cells of its grid."""
    return np.random.default_rng([int(cfg.seed), int(round(cfg.noise_ug * 1000)), cfg.n_samples, replicate,
                                  stream])


def replicate_priors(cfg, w0_rad_s: np.ndarray, prior_rng) -> np.ndarray:
    """Each replicate's prior, shape (R, m): ωᵢ(0)·(1 + s·uᵢ), uᵢ ~ U(−1, 1) from ``prior_rng(r)`` (the
    replicate's prior stream), s = ``cfg.prior_spread``, sorted."""
    u_prior = np.stack([prior_rng(r).uniform(-1.0, 1.0, w0_rad_s.size) for r in range(cfg.replicates)])
    return np.sort(w0_rad_s[None, :] * (1.0 + cfg.prior_spread * u_prior), axis=1)


def _rng(cfg: TrackingCellConfig, replicate: int, stream: str) -> np.random.Generator:
    return cell_rng(cfg, replicate, STREAMS[stream])


def inputs(cfg: TrackingCellConfig) -> np.ndarray:
    """The held inputs of every replicate, shape (R, N, len(INPUTS)) (``timevarying.INPUTS``)."""
    ex, n = cfg.excitation, cfg.n_samples
    u = np.zeros((cfg.replicates, n, len(INPUTS)))
    for r in range(cfg.replicates):
        if ex.thruster_torque_n_m > 0:
            if ex.thruster_period_s is not None:
                starts = np.arange(0.0, n * cfg.dt_s, ex.thruster_period_s)
                starts = np.unique(np.round(starts / cfg.dt_s).astype(int))
            else:
                starts = np.flatnonzero(_rng(cfg, r, "pulse_times").random(n) < ex.thruster_rate_hz * cfg.dt_s)
            signs = _rng(cfg, r, "pulse_signs").choice([-1.0, 1.0], size=starts.size)
            for k0, sign in zip(starts, signs, strict=True):
                u[r, k0:k0 + ex.pulse_samples, 0] = sign * ex.thruster_torque_n_m
        if ex.disturbance_force_n > 0:
            column = INPUTS.index("force_body_y" if ex.disturbance_at == "body" else "force_tip")
            u[r, :, column] = ex.disturbance_force_n * _rng(cfg, r, "disturbance").standard_normal(n)
    return u


def make_cell(cfg: TrackingCellConfig, *, bounds: bool = True) -> dict[str, np.ndarray]:
    """Simulate one cell (module docstring); ``bounds`` also computes the yardsticks: the genie PCRB (every
    input known, ``pcrb.cell_pcrb``), the unknown-force PCRB (the white disturbance unknown, the pulses known,
    ``pcrb_force.unknown_force_pcrb``) and the best window's bound."""
    w = check_cell_config(cfg)
    n = cfg.n_samples
    t = np.arange(n) * cfg.dt_s
    model = modal_model(build_plant(cfg.plant))
    u = inputs(cfg)
    xi0 = cfg.excitation.release * model.xi0 if cfg.excitation.release > 0 else None
    clean, states = simulate(model, w, cfg.dt_s, u, xi0=xi0)
    sigma = cfg.noise_ug * UG
    noisy = np.stack([clean[r] + sigma * _rng(cfg, r, "noise").standard_normal(n) for r in range(cfg.replicates)])
    prior = replicate_priors(cfg, w[0], lambda r: _rng(cfg, r, "prior"))
    ev = schedules.events(cfg.schedule, t)
    out = {
        "t_s": t, "accel_m_s2": noisy, "accel_clean_m_s2": clean, "truth_freq_rad_s": w,
        "truth_damping": model.damping.copy(), "modal_state": states.astype(np.float32),
        "inputs": u.astype(np.float32), "prior_rad_s": prior,
        "dt_s": np.float64(cfg.dt_s), "noise_ug": np.float64(cfg.noise_ug), "noise_std_m_s2": np.float64(sigma),
        "seed": np.int64(cfg.seed),
        "step_time_s": np.float64(np.nan if ev["step_time_s"] is None else ev["step_time_s"]),
        "drift_span_s": np.array(ev["drift_span_s"] if ev["drift_span_s"] else [np.nan, np.nan], dtype=float),
        "config_json": np.array(json.dumps({
            "config": asdict(cfg), "streams": STREAMS,
            "rng": "numpy.random.default_rng([seed, round(noise_ug*1000), N, replicate, stream])",
            "discretisation": "frozen system per sample (frequencies at t_k), inputs zero-order held"},
            sort_keys=True, default=float)),
    }
    if bounds:
        out["pcrb_std_rad_s"] = pcrb.cell_pcrb(model, w, states, cfg.dt_s, sigma, prior,
                                               rw_rel=cfg.pcrb_rw_rel, u=u)
        # the white force unknown (none: pulses only, known to both bounds, and this is the genie's bound)
        unknown = {"force_std_n": cfg.excitation.disturbance_force_n, "u": u,
                   "force_input": "force_body_y" if cfg.excitation.disturbance_at == "body" else "force_tip"}
        out["pcrb_unknown_force_std_rad_s"] = pcrb_force.unknown_force_pcrb(model, w, states, cfg.dt_s, sigma,
                                                                            prior, **unknown)
        if is_line(w):         # and each frequency a line of unknown rate, not the schedule's walk
            out["pcrb_unknown_rate_std_rad_s"] = pcrb_force.unknown_force_pcrb(
                model, w, states, cfg.dt_s, sigma, prior, rate_std=RATE_PRIOR_REL_PER_S * w[0], **unknown)
        out["window_bound_std_rad_s"] = pcrb.cell_window_bound(model, w, states, cfg.dt_s, sigma)
    return out


def is_line(w: np.ndarray, rel: float = 1e-9) -> bool:
    """Whether every frequency of ``w`` (N, m) is a line in time (within ``rel`` of ω): a drift over the whole
    record or a constant, not a step, a slosh, a fuel burn or a drift that ends inside the record."""
    w = np.asarray(w, dtype=float)
    line = w[:1] + (w[-1:] - w[:1]) * np.linspace(0.0, 1.0, w.shape[0])[:, None]
    return bool(np.all(np.abs(w - line) <= rel * np.abs(w[:1])))


def write_cell(cfg: TrackingCellConfig, path) -> None:
    write_npz(path, make_cell(cfg))


def cell_name(schedule: str, excitation: str, noise_ug: float, duration_s: float) -> str:
    """``<schedule>_<excitation>_noise{x}ug_{T}s``, e.g. ``drift_thrusters_noise1000ug_120s``."""
    for label in (schedule, excitation):
        if not label.replace("-", "").replace("_", "").isalnum():
            raise ValueError(f"name {label!r} must be letters, digits, - and _")
    return f"{schedule}_{excitation}_noise{float(noise_ug):g}ug_{float(duration_s):g}s"


__all__ = ["ExcitationConfig", "ScheduleConfig", "TrackingCellConfig", "cell_name", "cell_rng", "check_cell_config",
           "check_replicates", "inputs", "is_line", "make_cell", "replicate_priors", "write_cell",
           "RATE_PRIOR_REL_PER_S"]
