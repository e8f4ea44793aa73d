"""Search spaces of method options, declared in ``configs/tuning/<method>.yaml`` under ``space:``.

Each entry names one option of the method (a field of its ``Options``) and how to search it:

- ``{low, high, log}``: a float (``log: true`` for a scale parameter such as a variance or a gain);
  ``int: true`` for an integer;
- ``{choices: [...]}``: a categorical option (e.g. the measurement model);
- ``per_mode: true``: one parameter per prior frequency (a per-loop list such as the PLL's ω_L);
- ``relative: true``: the searched number multiplies the base config's value (a list is scaled entry by
  entry), so one range fits loops whose paper values differ by 20×.

The base config (e.g. the paper's ``configs/method/pll.yaml``) supplies every option not searched; the
``fixed:`` section of the tuning config overrides some of them for every trial.
"""

from __future__ import annotations

from typing import Any

__all__ = ["KNOWN_KEYS", "check_space", "param_names", "suggest_options", "resolve", "base_params"]

KNOWN_KEYS = {"low", "high", "log", "int", "choices", "per_mode", "relative"}


def check_space(space: dict, option_names: set[str], n_modes: int, base: dict) -> None:
    """Raise ValueError naming the entry for a space that cannot be searched."""
    if not space:
        raise ValueError("tuning.space is empty: name at least one option to search")
    for name, spec in space.items():
        if name not in option_names:
            raise ValueError(f"tuning.space.{name}: not an option of the method; known: "
                             f"{', '.join(sorted(option_names))}")
        unknown = set(spec) - KNOWN_KEYS
        if unknown:
            raise ValueError(f"tuning.space.{name}: unknown keys {sorted(unknown)}; known: {sorted(KNOWN_KEYS)}")
        if "choices" in spec:
            if not spec["choices"]:
                raise ValueError(f"tuning.space.{name}.choices is empty")
            continue
        low, high = spec.get("low"), spec.get("high")
        if low is None or high is None or not low < high:
            raise ValueError(f"tuning.space.{name}: needs low < high (got low={low}, high={high})")
        if spec.get("log") and low <= 0:
            raise ValueError(f"tuning.space.{name}: log scale needs low > 0 (got {low})")
        if spec.get("relative"):
            value = base.get(name)
            if value is None:
                raise ValueError(f"tuning.space.{name}: relative to the base config's value, which is null")
            if spec.get("per_mode") and isinstance(value, list) and len(value) not in (1, n_modes):
                raise ValueError(f"tuning.space.{name}: base value has {len(value)} entries for {n_modes} modes")


def _suggest(trial, key: str, spec: dict):
    if "choices" in spec:
        return trial.suggest_categorical(key, list(spec["choices"]))
    if spec.get("int"):
        return trial.suggest_int(key, int(spec["low"]), int(spec["high"]), log=bool(spec.get("log")))
    return trial.suggest_float(key, float(spec["low"]), float(spec["high"]), log=bool(spec.get("log")))


def param_names(name: str, spec: dict, n_modes: int) -> list[str]:
    """The Optuna parameter name(s) of one space entry: ``rd``, or ``loop_bandwidth_rad_s[0]`` … per mode."""
    return [f"{name}[{i}]" for i in range(n_modes)] if spec.get("per_mode") else [name]


def suggest_options(trial, space: dict, base: dict, n_modes: int) -> dict[str, Any]:
    """The options of one trial: base value where not searched, searched values where they are."""
    out = {}
    for name, spec in space.items():
        draws = [_suggest(trial, key, spec) for key in param_names(name, spec, n_modes)]
        out[name] = resolve(name, spec, draws, base.get(name), n_modes)
    return out


def resolve(name: str, spec: dict, draws: list, base_value, n_modes: int):
    """Turn drawn parameter values into the option value (scaling the base for ``relative``)."""
    if not spec.get("relative"):
        return draws if spec.get("per_mode") else draws[0]
    base_list = base_value if isinstance(base_value, list) else None
    if base_list is None:
        factor = draws[0]
        return [float(base_value) * d for d in draws] if spec.get("per_mode") else float(base_value) * factor
    if len(base_list) == 1:
        base_list = base_list * n_modes
    factors = draws if spec.get("per_mode") else draws * len(base_list)
    return [float(b) * f for b, f in zip(base_list, factors, strict=True)]


def base_params(space: dict, base: dict, n_modes: int) -> dict[str, Any]:
    """The parameter values that reproduce the base config (to enqueue it as trial 0), where the base lies
    inside the space: 1 for a relative entry, the base value for an absolute one."""
    out = {}
    for name, spec in space.items():
        value = base.get(name)
        keys = param_names(name, spec, n_modes)
        if spec.get("relative"):
            out.update(dict.fromkeys(keys, 1.0) if spec["low"] <= 1.0 <= spec["high"] else {})
            continue
        if "choices" in spec:
            if value in list(spec["choices"]):
                out[keys[0]] = value
            continue
        values = value if isinstance(value, list) else [value] * len(keys)
        if value is None or len(values) != len(keys):
            continue
        for key, v in zip(keys, values, strict=True):
            if spec["low"] <= float(v) <= spec["high"]:
                out[key] = v
    return out
