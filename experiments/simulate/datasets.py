"""Noisy tip-accelerometer datasets: one ``.npz`` file per (noise, record length) cell, all replicates.

File schema (every entry a plain numpy array; ``numpy.load(path)`` reads it, no pickle):

| key | shape | meaning |
|---|---|---|
| ``t_s`` | (N,) | sample times, t_k = k·dt |
| ``accel_m_s2`` | (R, N) | measured tip acceleration, one row per replicate |
| ``accel_clean_m_s2`` | (N,) | the noise-free tip acceleration (truth) |
| ``dt_s``, ``noise_ug``, ``noise_std_m_s2``, ``bias_m_s2``, ``seed`` | () | the cell's settings |
| ``truth_freq_rad_s``, ``truth_damping`` | (4,) | eigenfrequencies and damping of the generating model |
| ``truth_amplitude_m_s2``, ``truth_phase_rad`` | (4,) | modal amplitudes/phases of the tip signal |
| ``cantilever_freq_rad_s`` | (4,) | the beam stiffness frequencies used (after calibration) |
| ``crlb_std_rad_s`` | (4,) | Cramér–Rao bound of each frequency for this cell (16 unknowns) |
| ``crlb_offset_std_rad_s`` | (4,) | the same with the sensor offset unknown too (17 unknowns) |
| ``provenance_json`` | () str | the config, seed scheme, package versions |
| ``scenario_json`` | () str | the cell's scenario axis values (JSON; only in cells with an axis) |
| ``prior_rad_s`` | (R, 4) | the harness's prior per replicate (only in cells with a prior axis) |
| ``prior_std_rad_s`` | (4,) | the 1σ spread those priors were drawn with, c·ωᵢ·s/√3 (same cells) |
| ``checksum_sha256`` | () str | SHA-256 of all the other arrays (``experiments.io.array_checksum``) |

Read a cell with ``experiments.io.read_npz`` (or ``numpy.load``): it verifies the checksum, so a file
changed or truncated after it was written is refused instead of giving stale results.
Replicate r of a cell draws its noise from ``numpy.random.default_rng([seed, noise_ng, N, r])`` with
``noise_ng`` the noise level in nano-g: the same config gives the same bytes, and a cell with R = 20 holds
the first 20 replicates of the same cell with R = 100. Scenario axes (damping, the mode gap, excitation,
the harness's prior, ...) are described in ``experiments.simulate.scenarios``.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np

from experiments.io import write_npz
from experiments.simulate import mismatch, scenarios
from experiments.simulate.crlb import crlb_std
from experiments.simulate.plant import PlantConfig, build_plant
from experiments.units import G_M_S2, MAX_ABS_ACCEL_M_S2

__all__ = ["G0", "UG", "MIN_SAMPLES", "MAX_SEED", "CELL_KEYS", "ScenarioConfig", "DatasetConfig", "scenario_axes",
           "check_noise_and_seed", "check_dataset_config", "replicate_rng", "make_cell", "write_cell"]

G0 = G_M_S2                  # standard gravity, m/s²
UG = G0 * 1e-6               # 1 µg in m/s²
MAX_SEED = 2**63 - 1         # the seed is stored as an int64 (and numpy's seed sequence takes any such)
MIN_SAMPLES = 8
# The entries a job needs from a cell (experiments.io.read_npz(path, required=CELL_KEYS)).
CELL_KEYS = ("t_s", "accel_m_s2", "dt_s", "noise_ug", "seed", "truth_freq_rad_s", "crlb_std_rad_s",
             "crlb_offset_std_rad_s")


@dataclass
class ScenarioConfig:
    """A cell's scenario axes (experiments.simulate.scenarios); None = not an axis of this cell.
    dt_s and bias_m_s2 are the dataset's own fields."""

    prior_scale: float | None = None
    prior_spread: float | None = None
    damping: Any = None              # ζ for every mode, or one per mode
    gap_rad_s: float | None = None
    excitation: Any = None           # scale of Table 2's displacements, for every mode or one per mode
    measurement: str | None = None   # read by the methods that offer it (the identify job's override)
    ar1: float | None = None         # model mismatches (experiments.simulate.mismatch): AR(1) noise φ,
    unmodelled_mode: float | None = None  # the beam's next mode (× mode 4's amplitude),
    duffing: float | None = None     # Duffing frequency shift at release,
    saturation: float | None = None  # clipping level (× the largest clean sample),
    quantisation: float | None = None  # rounding step (× the noise std)
    axes: list[str] = field(default_factory=list)   # which settings are axes of the grid (names the cell)


@dataclass
class DatasetConfig:
    """One dataset cell. Units in names."""

    noise_ug: float = 1000.0
    n_samples: int = 256
    replicates: int = 20
    dt_s: float = 0.02
    bias_m_s2: float = 0.0
    seed: int = 20261121
    out: str = "results/dataset.npz"
    plant: PlantConfig = field(default_factory=PlantConfig)
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)


def scenario_axes(cfg: DatasetConfig) -> dict:
    """The cell's axis values: every scenario setting that is not None, and dt_s / bias_m_s2 when
    ``scenario.axes`` names them (otherwise they are the grid's constants and do not name the cell)."""
    sc = cfg.scenario
    named = list(sc.axes or [])
    for axis in named:
        if axis not in scenarios.AXES:
            raise ValueError(f"scenario.axes names '{axis}', not an axis; known: {', '.join(scenarios.AXES)}")
    out = {}
    for axis in scenarios.AXES:
        if axis in ("dt_s", "bias_m_s2"):
            if axis in named:
                out[axis] = float(getattr(cfg, axis))
            continue
        value = getattr(sc, axis)
        if value is not None:
            out[axis] = list(value) if isinstance(value, (list, tuple)) else value
    return out


def check_noise_and_seed(noise_ug: float, seed: int) -> None:
    """The bounds of a cell's noise level and seed (also checked by the workflow on a grid's cells)."""
    if not noise_ug * UG <= MAX_ABS_ACCEL_M_S2:
        raise ValueError(f"noise_ug = {noise_ug} is above {MAX_ABS_ACCEL_M_S2 / UG:.3g} µg (1e5 g): its samples "
                         f"would not be physical accelerations, which every method refuses")
    if not 0 <= seed <= MAX_SEED:
        raise ValueError(f"seed = {seed} must be an integer from 0 to {MAX_SEED} (2^63 - 1)")


def check_dataset_config(cfg: DatasetConfig) -> None:
    """Raise ``ValueError`` with one clear sentence for an impossible cell."""
    if not cfg.noise_ug > 0:
        raise ValueError(f"noise_ug = {cfg.noise_ug} must be positive (the 1σ noise level in µg)")
    check_noise_and_seed(cfg.noise_ug, cfg.seed)
    if cfg.n_samples < MIN_SAMPLES:
        raise ValueError(f"n_samples = {cfg.n_samples} is too short: at least {MIN_SAMPLES} samples")
    if cfg.replicates < 1:
        raise ValueError(f"replicates = {cfg.replicates} must be at least 1")
    if not cfg.dt_s > 0:
        raise ValueError(f"dt_s = {cfg.dt_s} must be positive")
    if not np.isfinite(cfg.bias_m_s2):
        raise ValueError(f"bias_m_s2 = {cfg.bias_m_s2} must be a finite number")
    scenarios.check_cell(scenario_axes(cfg), cfg.plant, cfg.dt_s)


def replicate_rng(seed: int, noise_ug: float, n_samples: int, replicate: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(round(noise_ug * 1000)), int(n_samples), int(replicate)])


def make_cell(cfg: DatasetConfig) -> dict[str, np.ndarray]:
    """Simulate one cell: the exact noise-free response plus seeded white noise and bias."""
    check_dataset_config(cfg)
    axes = scenario_axes(cfg)
    plant = build_plant(scenarios.apply_to_plant(cfg.plant, axes))
    clean = plant.tip_acceleration(cfg.n_samples, cfg.dt_s)
    sigma = cfg.noise_ug * UG
    truth = plant.truth()
    wrong = mismatch.present(axes)
    signal = mismatch.mismatched_signal(truth, clean, cfg.dt_s, wrong) if wrong else clean
    noisy = np.empty((cfg.replicates, cfg.n_samples))
    for r in range(cfg.replicates):
        rng = replicate_rng(cfg.seed, cfg.noise_ug, cfg.n_samples, r)
        if wrong:
            y = signal + cfg.bias_m_s2 + mismatch.noise(rng, cfg.n_samples, sigma, wrong)
            noisy[r] = mismatch.sensor(y, signal, sigma, wrong, rng)   # (its grid's offset after the noise)
        else:
            noisy[r] = clean + cfg.bias_m_s2 + sigma * rng.standard_normal(cfg.n_samples)
    modal = (truth["freq_rad_s"], truth["damping"], truth["amplitude_m_s2"], truth["phase_rad"])
    bound = crlb_std(*modal, cfg.n_samples, cfg.dt_s, sigma)
    bound_offset = crlb_std(*modal, cfg.n_samples, cfg.dt_s, sigma, offset=True)
    provenance = {
        "config": {k: v for k, v in asdict(cfg).items() if k != "out" and (k != "scenario" or axes)},
        "noise_scheme": "numpy.random.default_rng([seed, round(noise_ug*1000), n_samples, replicate])",
        "versions": _versions(),
    }
    extra = {}
    if axes:
        extra["scenario_json"] = np.array(json.dumps(axes, sort_keys=True))
        provenance["scenario"] = axes
        provenance["plant_in_cell"] = asdict(scenarios.apply_to_plant(cfg.plant, axes))
    if scenarios.has_prior_axis(axes):
        extra["prior_rad_s"] = scenarios.harness_prior(truth["freq_rad_s"], axes, cfg.seed, cfg.replicates)
        extra["prior_std_rad_s"] = scenarios.prior_std(truth["freq_rad_s"], axes)
        provenance["prior_scheme"] = ("prior[r] = sort(prior_scale * truth * (1 + prior_spread * "
                                      f"default_rng([seed, {scenarios.PRIOR_STREAM}, r]).uniform(-1, 1, m)))")
    return {
        "t_s": np.arange(cfg.n_samples) * cfg.dt_s,
        "accel_m_s2": noisy,
        "accel_clean_m_s2": clean,
        "dt_s": np.float64(cfg.dt_s),
        "noise_ug": np.float64(cfg.noise_ug),
        "noise_std_m_s2": np.float64(sigma),
        "bias_m_s2": np.float64(cfg.bias_m_s2),
        "seed": np.int64(cfg.seed),
        "truth_freq_rad_s": truth["freq_rad_s"],
        "truth_damping": truth["damping"],
        "truth_amplitude_m_s2": truth["amplitude_m_s2"],
        "truth_phase_rad": truth["phase_rad"],
        "cantilever_freq_rad_s": truth["cantilever_freq_rad_s"],
        "crlb_std_rad_s": bound,
        "crlb_offset_std_rad_s": bound_offset,
        "provenance_json": np.array(json.dumps(provenance, sort_keys=True)),
        **extra,
    }


def write_cell(cfg: DatasetConfig) -> Path:
    return write_npz(cfg.out, make_cell(cfg))


def _versions() -> dict[str, str]:
    out = {}
    for pkg in ("spacecraft-modal-id", "numpy", "scipy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = "not installed"
    return out
