"""Scenario axes of a grid: what a cell varies besides noise and record length, and how cells are named.

A grid (``configs/grid/<name>.yaml``) lists ``noise_ug`` × ``n_samples`` and, optionally, ``scenarios``: a
list of blocks, each a mapping axis → values. The axes of one block are crossed with each other and with
noise × length; the blocks are joined (a cell named twice is made once). No ``scenarios`` (or an empty
block) gives the plain cells ``noise{x}ug_n{N}`` of before, bit-identical.

| axis | value | what changes | name part |
|---|---|---|---|
| ``prior_scale`` | c > 0 | every prior frequency × c (a common mass/stiffness error) | ``_ps{c}`` |
| ``prior_spread`` | 0 ≤ s < 1 | each prior frequency × (1 + s·uᵢ), uᵢ ~ U(−1, 1) per replicate and mode | ``_pe{s}`` |
| ``damping`` | ζ or [ζ₁…ζₘ] | the generating model's modal damping, common or per mode | ``_z{ζ}`` |
| ``gap_rad_s`` | g > 0 | mode 3 moved to ω₂ + g (the paper's modified mode; ω₂ stays) | ``_gap{g}`` |
| ``excitation`` | a or [a₁…aₘ] | Table 2's initial modal displacements scaled per mode | ``_exc{a}`` |
| ``dt_s`` | Δt > 0 | the sample interval (Nyquist π/Δt above every mode and prior) | ``_dt{Δt}`` |
| ``bias_m_s2`` | b | a constant sensor offset, m/s² | ``_bias{b}`` |
| ``measurement`` | acceleration / position | the methods' option (akf, wkf); others skip the cell | ``_{value}`` |
| ``ar1`` | −1 < φ < 1 | AR(1) measurement noise of the same variance (experiments.simulate.mismatch) | ``_ar{φ}`` |
| ``unmodelled_mode`` | r ≥ 0 | the beam's next mode (111 rad/s) at r × mode 4's amplitude | ``_um{r}`` |
| ``duffing`` | δ | every mode a Duffing oscillator, frequency (1 + δ)ω at release; truth: the linear ω | ``_duf{δ}`` |
| ``saturation`` | 0 < s ≤ 1 | the sensor clips at s × the largest clean sample | ``_sat{s}`` |
| ``quantisation`` | q > 0 | the sensor rounds to q × the noise std | ``_qt{q}`` |

**The prior.** In a cell without a prior axis, every method gets its own config's prior (the paper's, as
before). In a cell with ``prior_scale`` and/or ``prior_spread`` the harness forms the prior from the
generating model's eigenfrequencies ω (the "nominal model" of the user, here exactly the truth):
``prior[r, i] = c · ωᵢ · (1 + s · uᵢ(r))`` with u(r) = ``default_rng([seed, PRIOR_STREAM, r]).uniform(-1, 1, m)``,
sorted increasingly (slot i still means the i-th mode). Every method of the cell gets the same prior per
replicate and never the truth. The draw depends on the replicate only (common random numbers): the cells
``_pe0.1`` and ``_pe0.2`` err in the same directions, the second twice as far, so a basin curve is smooth
and R = 20 is a prefix of R = 100.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from experiments.simulate import mismatch

__all__ = ["AXES", "PER_MODE_AXES", "PRIOR_AXES", "MEASUREMENTS", "PRIOR_STREAM", "GAP_MODES", "cell_name",
           "grid_cells", "per_mode", "apply_to_plant", "nominal_frequencies", "has_prior_axis", "prior_draws",
           "harness_prior", "check_cell", "check_grid", "result_columns"]

# axis -> the prefix of its part of a cell name; the order is the order of the parts in the name.
AXES: dict[str, str] = {
    "prior_scale": "ps",
    "prior_spread": "pe",
    "damping": "z",
    "gap_rad_s": "gap",
    "excitation": "exc",
    "dt_s": "dt",
    "bias_m_s2": "bias",
    "measurement": "",
    # the model mismatches (experiments/simulate/mismatch.py)
    "ar1": "ar",
    "unmodelled_mode": "um",
    "duffing": "duf",
    "saturation": "sat",
    "quantisation": "qt",
}
PER_MODE_AXES = ("damping", "excitation")     # a number (every mode) or one value per mode
PRIOR_AXES = ("prior_scale", "prior_spread")
MEASUREMENTS = ("acceleration", "position")
PRIOR_STREAM = 0x5052                           # "PR": the prior draws' stream, apart from the noise's
GAP_MODES = (2, 3)                              # the gap axis moves mode 3 relative to mode 2 (1-based)


def _fmt(value) -> str:
    if isinstance(value, (list, tuple)):
        return "-".join(_fmt(v) for v in value)
    if isinstance(value, str):
        return value
    return f"{float(value):g}"


def cell_name(noise_ug: float, n_samples: int, axes: dict | None = None) -> str:
    """``noise{x}ug_n{N}`` followed by one part per axis in :data:`AXES` order, e.g.
    ``noise1000ug_n256_ps0.8_gap0.5``. Deterministic: the same values give the same name."""
    name = f"noise{float(noise_ug):g}ug_n{int(n_samples)}"
    for axis, prefix in AXES.items():
        if axes and axes.get(axis) is not None:
            name += f"_{prefix}{_fmt(axes[axis])}"
    return name


def grid_cells(grid: dict) -> dict[str, dict]:
    """Every cell of a grid: name -> {noise_ug, n_samples, axes}, in a deterministic order."""
    blocks = grid.get("scenarios") or [{}]
    cells: dict[str, dict] = {}
    for block in blocks:
        names = [a for a in AXES if a in block]
        for values in itertools.product(*(block[a] for a in names)):
            axes = dict(zip(names, values, strict=True))
            for noise in grid["noise_ug"]:
                for n in grid["n_samples"]:
                    cells.setdefault(cell_name(noise, n, axes),
                                     {"noise_ug": noise, "n_samples": n, "axes": axes})
    return cells


def per_mode(value, m: int, axis: str) -> list[float]:
    """A per-mode axis value as m numbers (a number applies to every mode)."""
    if isinstance(value, (list, tuple)):
        if len(value) != m:
            raise ValueError(f"{axis} = {list(value)} has {len(value)} entries; the plant has {m} modes")
        return [float(v) for v in value]
    return [float(value)] * m


def apply_to_plant(plant_cfg, axes: dict):
    """The plant config of a cell: damping, the moved mode 3, the scaled excitation (a new object)."""
    m = len(plant_cfg.shape_modes)
    changes = {}
    if axes.get("damping") is not None:
        changes["damping"] = per_mode(axes["damping"], m, "damping")
    if axes.get("excitation") is not None:
        scale = per_mode(axes["excitation"], m, "excitation")
        changes["initial_displacement_m"] = [q * a for q, a in zip(plant_cfg.initial_displacement_m, scale,
                                                                    strict=True)]
    if axes.get("gap_rad_s") is not None:
        lo, hi = (i - 1 for i in GAP_MODES)
        target = list(plant_cfg.target_freq_rad_s)
        if hi not in [i - 1 for i in plant_cfg.modified_modes]:
            raise ValueError(f"gap_rad_s needs mode {GAP_MODES[1]} to be a modified mode of the plant "
                             f"(its stiffness free); modified_modes = {list(plant_cfg.modified_modes)}")
        target[hi] = target[lo] + float(axes["gap_rad_s"])
        changes["target_freq_rad_s"] = target
    return dataclasses.replace(plant_cfg, **changes) if changes else plant_cfg


def nominal_frequencies(plant_cfg, axes: dict) -> np.ndarray:
    """The model's target frequencies in a cell (equal to the truth when the plant is calibrated)."""
    return np.asarray(apply_to_plant(plant_cfg, axes).target_freq_rad_s, dtype=float)


def has_prior_axis(axes: dict) -> bool:
    return any(axes.get(a) is not None for a in PRIOR_AXES)


def prior_draws(seed: int, replicates: int, m: int) -> np.ndarray:
    """u(r) ~ U(−1, 1)^m per replicate r (the per-mode prior-error directions; see the module docstring)."""
    return np.array([np.random.default_rng([int(seed), PRIOR_STREAM, r]).uniform(-1.0, 1.0, m)
                     for r in range(replicates)]).reshape(replicates, m)


def harness_prior(freq_rad_s, axes: dict, seed: int, replicates: int) -> np.ndarray:
    """prior[r, i] = c · ωᵢ · (1 + s · uᵢ(r)), sorted per replicate; shape (R, m)."""
    w = np.asarray(freq_rad_s, dtype=float)
    c = float(axes.get("prior_scale") or 1.0)
    s = float(axes.get("prior_spread") or 0.0)
    prior = c * w[None, :] * (1.0 + s * prior_draws(seed, replicates, w.size))
    return np.sort(prior, axis=1)


def prior_std(freq_rad_s, axes: dict) -> np.ndarray:
    """The 1σ spread the harness's priors are drawn with, per mode: c·ωᵢ·s/√3, rad/s.

    prior = c·ω·(1 + s·u) with u ~ U(−1, 1) has std c·ω·s/√3 around c·ω (the std of U(−1, 1) is 1/√3).
    The common factor c is a fixed error of the cell, not a spread: a cell with ``prior_scale`` alone has
    spread 0 (its prior is wrong by a known-to-the-harness bias that a method's prior_std_rad_s does not
    describe). This is what a method's ``prior_std_rad_s`` would state for the cell's priors.
    """
    w = np.asarray(freq_rad_s, dtype=float)
    c = float(axes.get("prior_scale") or 1.0)
    s = float(axes.get("prior_spread") or 0.0)
    return c * w * s / math.sqrt(3.0)


def check_cell(axes: dict, plant_cfg, dt_s: float) -> None:
    """Raise ``ValueError`` (one sentence naming the value) for an impossible cell: mode order broken by the
    gap, a mode or a prior at or above Nyquist, a measurement no method reads."""
    m = len(plant_cfg.shape_modes)
    for axis in PER_MODE_AXES:
        if axes.get(axis) is not None:
            per_mode(axes[axis], m, axis)
    w = nominal_frequencies(plant_cfg, axes)
    if axes.get("gap_rad_s") is not None and not np.all(np.diff(w) > 0):
        raise ValueError(f"gap_rad_s = {axes['gap_rad_s']:g} puts mode {GAP_MODES[1]} at {w[GAP_MODES[1] - 1]:g} "
                         f"rad/s, past mode {GAP_MODES[1] + 1} ({w[GAP_MODES[1]]:g} rad/s)")
    nyquist = math.pi / dt_s
    if w.max() >= nyquist:
        raise ValueError(f"dt_s = {dt_s:g} s puts Nyquist at {nyquist:.4g} rad/s, at or below the highest "
                         f"mode ({w.max():.4g} rad/s)")
    if has_prior_axis(axes):
        top = float(axes.get("prior_scale") or 1.0) * w.max() * (1.0 + float(axes.get("prior_spread") or 0.0))
        if top >= nyquist:
            raise ValueError(f"prior_scale/prior_spread {axes.get('prior_scale')}/{axes.get('prior_spread')} "
                             f"allow a prior of {top:.4g} rad/s, at or above Nyquist {nyquist:.4g} rad/s "
                             f"(dt_s = {dt_s:g} s)")

    mismatch.check_axes(mismatch.present(axes))
    if axes.get("measurement") is not None and axes["measurement"] not in MEASUREMENTS:
        raise ValueError(f"measurement = {axes['measurement']!r} must be one of {', '.join(MEASUREMENTS)}")


def check_grid(grid: dict, plant_cfg) -> dict[str, dict]:
    """All cells of a grid, each checked (raises ``ValueError`` naming the first bad cell)."""
    cells = grid_cells(grid)
    for name, cell in cells.items():
        try:
            check_cell(cell["axes"], plant_cfg, float(cell["axes"].get("dt_s", grid.get("dt_s", 0.02))))
        except ValueError as exc:
            raise ValueError(f"grid {grid.get('name')!r}, cell {name}: {exc}") from None
    return cells


def result_columns(axes: dict, mode: int) -> dict:
    """The axis values a results row carries (per-mode axes: this mode's value)."""
    out = {}
    for axis in AXES:
        value = axes.get(axis)
        if value is None:
            continue
        if axis in PER_MODE_AXES and isinstance(value, (list, tuple)):
            value = value[mode - 1]
        out[axis] = value if isinstance(value, str) else float(value)
    return out
