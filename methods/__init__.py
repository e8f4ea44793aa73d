"""Identification methods: arrays in, an :class:`~methods.estimate.Estimate` out.

Every method is a module exposing ``identify(y, dt, prior, **options) -> Estimate`` and an ``Options``
dataclass (its keyword options with the paper's settings as defaults). ``get(name)`` finds it by name.
Adding a method: write ``methods/<name>.py`` and add one line to ``_REGISTRY``. Nothing here imports
the experiments, Hydra, MLflow or the file system.
"""

from __future__ import annotations

import importlib

from methods.estimate import Estimate, check_inputs, failed

# name -> module path; modules are imported on first use so that a light method does not pay for the
# import of a heavy one (CasADi, filterpy).
_REGISTRY: dict[str, str] = {
    "fft": "methods.fft",
    "akf": "methods.akf",
    "wkf": "methods.wkf",
    "pem": "methods.pem",
    "pll": "methods.pll",
}

__all__ = ["Estimate", "check_inputs", "failed", "get", "module_name", "names", "options_class"]


def names() -> list[str]:
    """Names of the registered methods."""
    return list(_REGISTRY)


def module_name(name: str) -> str:
    """The module that implements method ``name`` (e.g. ``methods.fft``), without importing it."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown method '{name}'; known methods: {', '.join(_REGISTRY)}")
    return _REGISTRY[name]


def _module(name: str):
    return importlib.import_module(module_name(name))


def get(name: str):
    """Return the ``identify(y, dt, prior, **options) -> Estimate`` function of method ``name``."""
    return _module(name).identify


def options_class(name: str):
    """Return the ``Options`` dataclass of method ``name`` (its keyword options and defaults)."""
    return _module(name).Options
