"""Laboratory tracking records: a beam whose frequencies a moving support steps, rung by every move.

The "laboratory" cell class of the tracking grids (docs/tracking.md §1): the kind of record a test lab
brings, unlike the spacecraft cells (:mod:`experiments.simulate.tracking_data`) in every number that a
default in samples could hide — one or two modes at 20–60 Hz, sampled at 5 kHz, dwelling 0.4–2 s.

**Schedule.** m modes (1–3) at ω₁ < ω₂ < …: mode 1 drawn in ``band_hz``, each next one ``mode_ratio`` times
the previous (drawn in its range). At random times (dwells drawn uniformly in ``dwell_s``) the support moves:
every mode's frequency is multiplied by the same factor 1 ± s, s ~ U(``step_rel``). A beam's frequencies
scale as 1/L² with its free length L, so a moving support scales every mode alike, and the modes never
cross. The sign is random unless one sign would take a mode out of ``band_hz`` (then the other: with
``mode_ratio`` ≤ 2 and steps ≤ 20 % one of them always stays inside, :func:`check_laboratory`).

**Excitation.** Each move (and the record's start) rings the beam: an impulse, a force held for one sample
of the 5 kHz record, whose modal share gives mode i a peak acceleration drawn in ``impulse_g`` (g) with a
random sign; between moves the modes ring down with ζᵢ drawn in ``damping``. Simulated exactly per sample
(:func:`experiments.simulate.timevarying.simulate`, the spacecraft cells' simulator; the frequencies are
piecewise constant, so "frozen per sample" is exact here).

**Sensor.** An accelerometer of ``sensitivity_v_per_g`` (10 V/g) with an offset ``offset_v`` and white
noise ``noise_ug`` (1σ, µg), digitised at ``fs_hz`` by a ``bits``-bit converter over ±``range_v``
(v = Δ·round(v/Δ), Δ = 2·range/2^bits, clipped to the range), then converted back to m/s² and decimated by
``decimate`` with ``scipy.signal.resample_poly`` (its anti-alias FIR, Kaiser window, zero phase) — what the
lab does before tracking. The trackers get the decimated record, offset and quantisation included.

**Truth.** ωᵢ(t) at each decimated sample (the schedule: the frozen oscillators' |λ| = ωᵢ), and the moves'
instants ``step_times_s``. No posterior bound is computed for this class (``pcrb_std_rad_s`` is absent;
the scores relative to a bound are NaN).

The random parts of replicate r come from ``numpy.random.default_rng([seed, round(noise_ug·1000), N, r,
stream])``, one stream each (:data:`STREAMS`), as the spacecraft cells'. The cell file has the schema of
:mod:`experiments.simulate.tracking_data` (``t_s``, ``accel_m_s2``, ``accel_clean_m_s2``,
``truth_freq_rad_s``, ``truth_damping``, ``prior_rad_s``, ``dt_s``, ``noise_ug``, ``noise_std_m_s2``,
``seed``, ``step_time_s`` NaN, ``drift_span_s`` NaN, ``config_json``) plus ``step_times_s`` (S,) and
``kind`` = ``laboratory``. The schedule and the damping are the cell's (every replicate shares them, as
a spacecraft cell's schedule); the impulses and the noise are each replicate's.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from experiments.simulate.timevarying import INPUTS, ModalModel, simulate
from experiments.simulate.tracking_data import UG, cell_rng, check_replicates, replicate_priors

__all__ = ["G_M_S2", "STREAMS", "LaboratoryConfig", "LaboratoryCellConfig", "LabRecord", "check_laboratory",
           "lab_record", "make_lab_cell", "schedule"]

G_M_S2 = 9.80665
STREAMS = {"noise": 0, "schedule": 1, "impulses": 2, "damping": 3, "prior": 4, "signs": 5}   # per cell: r = 0


@dataclass
class LaboratoryConfig:
    """The beam, its moves and the sensor (module docstring). Ranges are [low, high], drawn uniformly."""

    n_modes: int = 1
    band_hz: list[float] = field(default_factory=lambda: [20.0, 60.0])
    mode_ratio: list[float] = field(default_factory=lambda: [1.4, 2.0])
    step_rel: list[float] = field(default_factory=lambda: [0.05, 0.20])
    dwell_s: list[float] = field(default_factory=lambda: [0.4, 2.0])
    damping: list[float] = field(default_factory=lambda: [0.003, 0.01])
    impulse_g: list[float] = field(default_factory=lambda: [0.1, 0.4])
    fs_hz: float = 5000.0
    bits: int = 12
    range_v: float = 10.0
    sensitivity_v_per_g: float = 10.0
    offset_v: float = 0.05
    decimate: int = 20


@dataclass
class LaboratoryCellConfig:
    """One laboratory cell: the lab settings, noise, duration, replicates, seed and prior spread."""

    lab: LaboratoryConfig = field(default_factory=LaboratoryConfig)
    noise_ug: float = 300.0
    duration_s: float = 12.0
    replicates: int = 3
    seed: int = 20261121
    prior_spread: float = 0.05

    def __post_init__(self):
        if isinstance(self.lab, dict):
            self.lab = LaboratoryConfig(**self.lab)

    @property
    def dt_s(self) -> float:
        """The decimated record's sample interval, s."""
        return self.lab.decimate / self.lab.fs_hz

    @property
    def n_samples(self) -> int:
        """Samples of the decimated record."""
        return int(round(self.duration_s / self.dt_s))

    @property
    def n_raw(self) -> int:
        return self.n_samples * self.lab.decimate

    @property
    def nominal_prior_rad_s(self) -> np.ndarray:
        """A typical prior for option checks before any record exists: the band's bottom, ratio by ratio."""
        lab = self.lab
        w = 2 * np.pi * lab.band_hz[0] * np.cumprod([1.0] + [lab.mode_ratio[0]] * (lab.n_modes - 1))
        return w


LAB_KEYS = {f.name for f in fields(LaboratoryConfig)}


def _range(name: str, value, low: float = 0.0, strict: bool = True) -> None:
    ok = (isinstance(value, list | tuple) and len(value) == 2 and all(isinstance(v, int | float) for v in value)
          and all(math.isfinite(v) for v in value) and value[0] <= value[1]
          and (value[0] > low if strict else value[0] >= low))
    if not ok:
        raise ValueError(f"laboratory.{name} = {value!r} must be [low, high] with {low:g} "
                         f"{'<' if strict else '≤'} low ≤ high")


def check_laboratory(cfg: LaboratoryCellConfig) -> None:
    """``ValueError`` (one line naming the value) for a laboratory cell that cannot be simulated or tracked."""
    lab = cfg.lab
    if isinstance(lab.n_modes, bool) or not isinstance(lab.n_modes, int) or not 1 <= lab.n_modes <= len(INPUTS):
        raise ValueError(f"laboratory.n_modes = {lab.n_modes!r} must be an integer from 1 to {len(INPUTS)}")
    for name in ("band_hz", "mode_ratio", "dwell_s", "impulse_g"):
        _range(name, getattr(lab, name))
    _range("step_rel", lab.step_rel)
    _range("damping", lab.damping)
    if lab.step_rel[1] >= 1 or lab.damping[1] >= 1:
        raise ValueError(f"laboratory.step_rel = {lab.step_rel} and damping = {lab.damping} must stay below 1")
    if lab.mode_ratio[0] <= 1 and lab.n_modes > 1:
        raise ValueError(f"laboratory.mode_ratio = {lab.mode_ratio} must exceed 1 (modes in increasing order)")
    lo, hi = lab.band_hz
    top_ratio = lab.mode_ratio[1] ** (lab.n_modes - 1)
    # a move must always have a sign that keeps every mode in the band (module docstring): from anywhere in
    # [lo, hi/ratio] one of ×(1 ± s) stays inside when hi/(ratio·lo) ≥ (1 + s)/(1 − s)
    s = lab.step_rel[1]
    if hi / (top_ratio * lo) < (1 + s) / (1 - s):
        raise ValueError(f"laboratory.band_hz = {lab.band_hz} is too narrow for {lab.n_modes} modes "
                         f"{lab.mode_ratio[1]:g}× apart stepping up to {s:g}: need high/(ratio·low) ≥ "
                         f"{(1 + s) / (1 - s):.3g}")
    for name in ("fs_hz", "range_v", "sensitivity_v_per_g"):
        v = getattr(lab, name)
        if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
            raise ValueError(f"laboratory.{name} = {v!r} must be a positive number")
    if isinstance(lab.bits, bool) or not isinstance(lab.bits, int) or not 2 <= lab.bits <= 32:
        raise ValueError(f"laboratory.bits = {lab.bits!r} must be an integer from 2 to 32")
    if isinstance(lab.decimate, bool) or not isinstance(lab.decimate, int) or lab.decimate < 1:
        raise ValueError(f"laboratory.decimate = {lab.decimate!r} must be an integer ≥ 1")
    if not abs(lab.offset_v) < lab.range_v:
        raise ValueError(f"laboratory.offset_v = {lab.offset_v} must be inside the converter's ±{lab.range_v} V")
    check_replicates(cfg, "after decimation")
    nyquist_hz = 0.5 / cfg.dt_s
    if hi * (1 + cfg.prior_spread) >= 0.8 * nyquist_hz:
        raise ValueError(f"laboratory.band_hz top {hi:g} Hz (prior up to {hi * (1 + cfg.prior_spread):.4g} Hz) is not "
                         f"inside the decimated record's pass band (0.8 × Nyquist {nyquist_hz:.4g} Hz at decimate = "
                         f"{lab.decimate})")


def _rng(cfg: LaboratoryCellConfig, replicate: int, stream: str) -> np.random.Generator:
    return cell_rng(cfg, replicate, STREAMS[stream])


def schedule(cfg: LaboratoryCellConfig) -> tuple[np.ndarray, np.ndarray]:
    """The cell's moves, the same for every replicate (as a spacecraft cell's schedule): (step sample indices
    of the 5 kHz record (S,), the frequency of every mode in each dwell (S + 1, m), rad/s)."""
    lab = cfg.lab
    rng = _rng(cfg, 0, "schedule")
    ratios = rng.uniform(*lab.mode_ratio, size=lab.n_modes - 1)
    shape = np.cumprod(np.concatenate([[1.0], ratios]))            # ωᵢ / ω₁, fixed: the support scales all
    lo, hi = lab.band_hz
    f1 = rng.uniform(lo, hi / shape[-1])
    duration = cfg.n_raw / lab.fs_hz
    steps, levels = [], [f1]
    t = rng.uniform(*lab.dwell_s)
    while t < duration:
        steps.append(int(round(t * lab.fs_hz)))
        s = rng.uniform(*lab.step_rel)
        up = rng.random() < 0.5
        if levels[-1] * (1 + s) * shape[-1] > hi:
            up = False
        elif levels[-1] * (1 - s) < lo:
            up = True
        levels.append(levels[-1] * (1 + s if up else 1 - s))
        t += rng.uniform(*lab.dwell_s)
    return np.asarray(steps, int), 2 * np.pi * np.outer(levels, shape)


@dataclass(frozen=True)
class LabRecord:
    """One replicate at the converter's rate (before decimation)."""

    volts: np.ndarray            # (n_raw,) the quantised sensor output, V
    accel_m_s2: np.ndarray       # (n_raw,) the same in m/s² (offset included)
    clean_m_s2: np.ndarray       # (n_raw,) the beam's acceleration, noise-free, no offset
    freq_rad_s: np.ndarray       # (n_raw, m) the schedule at every sample
    steps: np.ndarray            # (S,) sample indices of the moves
    damping: np.ndarray          # (m,)


def lab_record(cfg: LaboratoryCellConfig, replicate: int) -> LabRecord:
    """Replicate r at ``fs_hz`` (module docstring): the schedule, the impulses, the sensor."""
    lab = cfg.lab
    n, m = cfg.n_raw, lab.n_modes
    dt = 1.0 / lab.fs_hz
    steps, levels = schedule(cfg)
    edges = np.concatenate([[0], steps, [n]])
    w = np.repeat(levels, np.diff(edges), axis=0)                               # (n, m), piecewise constant
    zeta = _rng(cfg, 0, "damping").uniform(*lab.damping, size=m)              # the beam's: every replicate
    # each mode its own input column (m ≤ 3 inputs): a move rings every mode with its own share
    model = ModalModel(freq_rad_s=levels[0].copy(), damping=zeta, tip_gain=np.ones(m),
                       input_gain=np.eye(m, len(INPUTS)), feedthrough=np.zeros(len(INPUTS)), xi0=np.zeros(m))
    rng, signs = _rng(cfg, replicate, "impulses"), _rng(cfg, replicate, "signs")
    u = np.zeros((1, n, len(INPUTS)))
    for k in edges[:-1]:
        peak = rng.uniform(*lab.impulse_g, size=m) * G_M_S2 * signs.choice([-1.0, 1.0], size=m)
        # a force F held for Δt gives the oscillator a velocity ≈ FΔt, i.e. an acceleration amplitude ≈ ωFΔt
        u[0, k, :m] = peak / (w[k] * dt)
    clean, _ = simulate(model, w, dt, u)
    clean = clean[0] - u[0] @ model.feedthrough                                   # no direct term
    noise = cfg.noise_ug * UG * _rng(cfg, replicate, "noise").standard_normal(n)
    v = lab.offset_v + (clean + noise) / G_M_S2 * lab.sensitivity_v_per_g
    lsb = 2 * lab.range_v / 2 ** lab.bits
    volts = np.clip(lsb * np.round(v / lsb), -lab.range_v, lab.range_v - lsb)
    return LabRecord(volts, volts / lab.sensitivity_v_per_g * G_M_S2, clean, w, steps, zeta)


def _decimate(y: np.ndarray, q: int) -> np.ndarray:
    """Every q-th sample after scipy.signal.resample_poly's anti-alias FIR (zero phase: output j is centred on
    input jq); the mean is taken out for the filter's zero padding and put back."""
    if q == 1:
        return y.copy()
    from scipy.signal import resample_poly  # the simulation only; the jobs import no scipy.signal

    c = float(np.mean(y))
    return resample_poly(y - c, 1, q) + c


def make_lab_cell(cfg: LaboratoryCellConfig) -> dict[str, np.ndarray]:
    """Simulate one laboratory cell (module docstring), all replicates, decimated."""
    check_laboratory(cfg)
    q, n = cfg.lab.decimate, cfg.n_samples
    dt = cfg.dt_s
    recs = [lab_record(cfg, r) for r in range(cfg.replicates)]
    noisy = np.stack([_decimate(rec.accel_m_s2, q)[:n] for rec in recs])
    clean = np.stack([_decimate(rec.clean_m_s2, q)[:n] for rec in recs])
    truth = recs[0].freq_rad_s[::q][:n]                                        # (n, m): the cell's schedule
    prior = replicate_priors(cfg, truth[0], lambda r: _rng(cfg, r, "prior"))
    return {
        "t_s": np.arange(n) * dt, "accel_m_s2": noisy, "accel_clean_m_s2": clean, "truth_freq_rad_s": truth,
        "truth_damping": recs[0].damping.copy(), "prior_rad_s": prior,
        "step_times_s": recs[0].steps / cfg.lab.fs_hz, "dt_s": np.float64(dt), "noise_ug": np.float64(cfg.noise_ug),
        "noise_std_m_s2": np.float64(cfg.noise_ug * UG), "seed": np.int64(cfg.seed),
        "step_time_s": np.float64(np.nan), "drift_span_s": np.array([np.nan, np.nan]),
        "kind": np.array("laboratory"),
        "config_json": np.array(json.dumps({
            "config": asdict(cfg), "streams": STREAMS,
            "rng": "numpy.random.default_rng([seed, round(noise_ug*1000), N, replicate, stream])",
            "decimation": "scipy.signal.resample_poly(x - mean, 1, decimate) + mean"}, sort_keys=True, default=float)),
    }


def main(argv=None) -> None:
    """``python -m experiments.simulate.laboratory rec.csv [--modes 1] [--seed 1] [--duration-s 12]``: one
    laboratory record as a logger's CSV at the converter's rate (time stamps printed to 1 µs, the sensor's
    output in g: volts / sensitivity, offset and quantisation included), the example of docs/measurements.md."""
    from experiments.cli import ArgumentParser  # the command only: the grids import this module
    from experiments.io import atomic_path  # (as above)

    parser = ArgumentParser(description=main.__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--modes", type=int, default=1)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--duration-s", type=float, default=12.0)
    a = parser.parse_args(argv)
    cfg = LaboratoryCellConfig(lab=LaboratoryConfig(n_modes=a.modes), duration_s=a.duration_s, replicates=1,
                               seed=a.seed)
    try:
        check_laboratory(cfg)
    except ValueError as exc:
        parser.error(str(exc))
    rec = lab_record(cfg, 0)
    t = np.arange(rec.volts.size) / cfg.lab.fs_hz
    with atomic_path(a.out) as tmp:
        np.savetxt(tmp, np.column_stack([t, rec.volts / cfg.lab.sensitivity_v_per_g]), fmt=["%.6f", "%.7e"],
                   delimiter=",", header="t,accel [g]", comments="")
    moves = ", ".join(f"{k / cfg.lab.fs_hz:.3f}" for k in rec.steps)
    levels = np.unique(rec.freq_rad_s[:, 0]).size
    print(f"wrote {a.out}: {t.size} samples at {cfg.lab.fs_hz:g} Hz; mode 1 from "
          f"{rec.freq_rad_s[0, 0] / (2 * np.pi):.4g} Hz over {levels} levels, moves at {moves} s")


if __name__ == "__main__":
    main()
