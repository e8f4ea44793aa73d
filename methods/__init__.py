"""Identification methods: arrays in, an :class:`~methods.estimate.Estimate` out.

Every method is a module exposing

* ``identify(y, dt, prior, **options) -> Estimate``: it starts with ``check_inputs(y, dt, prior)`` (the
  common rules: real finite samples of physical size, a positive ``dt``, a positive, increasing prior below
  Nyquist) and ``check_options(prior, dt, **options)``;
* ``Options``: a dataclass of its keyword options with the paper's settings as defaults;
* ``check_options(prior, dt, **options) -> Options``: every check of the options that needs no record
  (unknown key, wrong value, a per-mode list of the wrong length, a filter that cannot be designed at
  ``dt``), raising ``ValueError`` with one line naming the option. It must be cheap: the jobs call it,
  through :func:`check_options`, before the first record is read, so that a bad option is one
  ``error:`` line and not a failure in the middle of a run.

Honesty contract of the ``Estimate``: a mode the record does not determine (an all-zero or constant record
— see ``estimate.flat_record`` —, a peak not above the noise, a filter that learnt nothing) has
``extra["converged_per_mode"]`` False and a std that is NaN or finite and honest, never 0
(tests/methods/test_contract.py checks every registered method).

``get(name)`` finds a method by name. Adding a method: write ``methods/<name>.py`` with the three names
above and add one line to ``_REGISTRY``. Nothing here imports the experiments, Hydra, MLflow or the file
system.
"""

from __future__ import annotations

import importlib

import numpy as np

from methods.estimate import Estimate, check_inputs, check_prior, failed, flat_record, make_options

# name -> module path; modules are imported on first use so that a light method does not pay for the
# import of a heavy one (CasADi, filterpy).
_REGISTRY: dict[str, str] = {
    "fft": "methods.fft",
    "akf": "methods.akf",
    "wkf": "methods.wkf",
    "pem": "methods.pem",
    "pll": "methods.pll",
}

__all__ = ["Estimate", "check_inputs", "check_options", "check_prior", "failed", "flat_record", "get", "names",
           "options_class"]


def names() -> list[str]:
    """Names of the registered methods."""
    return list(_REGISTRY)


def _module(name: str):
    if name not in _REGISTRY:
        raise ValueError(f"unknown method '{name}'; known methods: {', '.join(_REGISTRY)}")
    return importlib.import_module(_REGISTRY[name])


def get(name: str):
    """Return the ``identify(y, dt, prior, **options) -> Estimate`` function of method ``name``."""
    return _module(name).identify


def options_class(name: str):
    """Return the ``Options`` dataclass of method ``name`` (its keyword options and defaults)."""
    return _module(name).Options


def check_options(name: str, prior, dt: float, options: dict | None = None):
    """Validate method ``name``'s options for this prior and sample interval, without a record.

    Returns the method's ``Options``; raises ``ValueError`` (one line, naming the option) when one is
    impossible. A module that does not (yet) define ``check_options`` gets the generic check of unknown
    keys only.
    """
    module = _module(name)
    dt, prior = check_prior(dt, prior)
    options = dict(options or {})
    if hasattr(module, "check_options"):
        return module.check_options(np.asarray(prior), dt, **options)
    return make_options(module.Options, options, name)
