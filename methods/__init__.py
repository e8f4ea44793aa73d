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
``converged_per_mode`` False and a std that is NaN or finite and honest, never 0
(tests/methods/test_contract.py checks every registered method).

Optional: ``identify_batch(y, dt, priors, **options) -> list[Estimate]`` on R records at once (``y`` R × n,
``priors`` one prior or R × m), returning exactly what ``identify`` returns on each row, computed together
where that shares work (``akf``/``wkf``: the R filters in lock-step). :func:`get_batch` finds it; the jobs
use it for a cell's replicates; tests/methods/test_contract.py checks it against ``identify`` row by row.

**Tracking.** ``track(name, y, dt, prior, **options) -> Track`` runs a method online over a record whose
frequencies move (:mod:`methods.tracking`): ``akf``, ``wkf``, ``pll`` natively, every other method here on a
sliding window, and the trackers ``rls_ar`` and ``next_era``; ``track_names()``, ``track_options_class()``
and ``check_track_options()`` are the registry's counterparts for trackers.

``get(name)`` finds a method by name. Adding a method: write ``methods/<name>.py`` with the three names
above and add one line to ``_REGISTRY``. Nothing here imports the experiments, Hydra, MLflow or the file
system.

**Methods from other packages.** An installed distribution that declares an entry point in the group
``spacecraft_modal_id.methods`` (:data:`ENTRY_POINT_GROUP`), e.g. in its pyproject.toml::

    [project.entry-points."spacecraft_modal_id.methods"]
    mymethod = "my_package.my_method"      # a module with identify() and Options

joins the registry under that name (``names()``, ``get()``, ``options_class()``) and runs in any grid
without an edit here. A module may set ``PRIOR_RAD_S`` (its default a-priori frequencies); built-in names
cannot be replaced by a plugin.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
from importlib.metadata import entry_points

import numpy as np

from methods.estimate import Estimate, check_inputs, check_prior, failed, flat_record, make_options

# name -> module path; modules are imported on first use so that a light method does not pay for the
# import of a heavy one (CasADi, filterpy).
_REGISTRY: dict[str, str] = {
    "fft": "methods.fft",
    "akf": "methods.kalman.akf",
    "wkf": "methods.kalman.wkf",
    "pem": "methods.pem",
    "pll": "methods.pll",
    # the field's established identifiers (optional extra .[peers]; methods/peers/README.md)
    "era": "methods.peers.era",
    "n4sid": "methods.peers.n4sid",
    "ssi_cov": "methods.peers.ssi_cov",
    "ssi_data": "methods.peers.ssi_data",
    "lsce": "methods.peers.lsce",
    "hdmd": "methods.peers.hdmd",
    "bopdmd": "methods.peers.bopdmd",
}

# The library each peer method needs (the optional extra .[peers]); checked before a job starts.
_REQUIRES: dict[str, str] = {
    "era": "control", "n4sid": "nfoursid", "ssi_cov": "strid", "ssi_data": "strid", "lsce": "sdypy.EMA",
    "hdmd": "pydmd", "bopdmd": "pydmd",
}

ENTRY_POINT_GROUP = "spacecraft_modal_id.methods"

__all__ = ["ENTRY_POINT_GROUP", "Estimate", "Track", "check_inputs", "check_options", "check_prior",
           "check_track_options", "failed", "flat_record", "get", "get_batch", "module_name", "names",
           "options_class", "plugins", "require", "track", "track_names", "track_options_class"]


@functools.cache
def plugins() -> dict[str, str]:
    """Methods of other installed packages: entry-point name -> module path (group ENTRY_POINT_GROUP)."""
    return {ep.name: ep.module for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name not in _REGISTRY}


def _all() -> dict[str, str]:
    return _REGISTRY | plugins()


def names() -> list[str]:
    """Names of the registered methods: the built-in ones, then those of installed plugins."""
    return list(_all())


def require(name: str) -> None:
    """Raise ``ValueError`` (one line) if method ``name`` is unknown or its optional library is missing."""
    if name not in _all():
        raise ValueError(f"unknown method '{name}'; known methods: {', '.join(_all())}")
    lib = _REQUIRES.get(name)
    if lib is not None:
        try:
            found = importlib.util.find_spec(lib) is not None
        except ModuleNotFoundError:           # the parent package of a dotted name is missing
            found = False
        if not found:
            raise ValueError(f"method '{name}' needs the library '{lib}', which is not installed "
                             f"(pip install -e '.[peers]')")


def module_name(name: str) -> str:
    """The module that implements method ``name`` (e.g. ``methods.fft``), without importing it."""
    require(name)
    return _all()[name]


def _module(name: str):
    return importlib.import_module(module_name(name))


def get(name: str):
    """Return the ``identify(y, dt, prior, **options) -> Estimate`` function of method ``name``."""
    return _module(name).identify


def get_batch(name: str):
    """Return method ``name``'s ``identify_batch(y, dt, priors, **options) -> list[Estimate]``, or None
    when it has none (then call ``identify`` per record)."""
    return getattr(_module(name), "identify_batch", None)


def options_class(name: str):
    """Return the ``Options`` dataclass of method ``name`` (its keyword options and defaults)."""
    return _module(name).Options


def check_options(name: str, prior, dt: float, options: dict | None = None):
    """Validate method ``name``'s options for this prior and sample interval, without a record.

    Returns the method's ``Options``; raises ``ValueError`` (one line, naming the option) when one is
    impossible. A plugin module that does not define ``check_options`` gets the generic check of unknown
    keys only.
    """
    module = _module(name)
    dt, prior = check_prior(dt, prior)
    options = dict(options or {})
    if hasattr(module, "check_options"):
        return module.check_options(np.asarray(prior), dt, **options)
    return make_options(module.Options, options, name)


# The tracking face (methods/tracking/): every method run online over a record whose frequencies move. It runs
# the batch methods of this registry on windows: ``names`` is handed down to it, not imported back.
from methods import tracking as _tracking_face  # noqa: E402
from methods.tracking import Track, check_track_options, track, track_names, track_options_class  # noqa: E402

_tracking_face.batch_names = names
