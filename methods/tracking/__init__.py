"""Online tracking of modal frequencies that drift and jump: ``track(name, y, dt, prior, **options) -> Track``.

Every tracker gets the samples, the sample interval, a prior and its options (never the truth) and returns a
:class:`Track`: estimates over time, each using only the samples up to its own time (causal). The trackers:

* ``akf``, ``wkf`` — the paper's filters, per-sample frequency states (random-walk process noise
  ``qd_frequency``); :mod:`methods.kalman.online`;
* ``pll`` — the loop bank's VCO frequency after every sample;
* every batch method of :func:`methods.names` other than these (``pem``, ``fft``, ``era``, ``n4sid``,
  ``ssi_cov``, ``ssi_data``, ``lsce``, ``hdmd``, ``bopdmd``, plugins) under its own name, on a sliding window
  of ``window_samples`` every ``hop_samples``, warm-started from the previous window;
* ``rls_ar`` — recursive least squares (Ljung's RPEM for an AR model) with forgetting, modes from its poles;
* ``next_era`` — the naive baseline: NExT autocorrelation of a sliding window through ERA;
* ``gated_pencil`` — a matrix pencil on the Hankel columns no thruster pulse crosses, then the trend stage.

Every windowed tracker takes ``trend=True``: its estimates put at the window's centre and carried to the
present by a local-linear-trend Kalman filter (:mod:`methods.tracking._trend`).

Each tracker's options are a dataclass (:func:`track_options_class`) whose defaults are the tracker's;
:func:`check_track_options` checks them without a record (with ``n_samples``: against the record's length too).
Nothing here imports the experiments, Hydra, MLflow or files. See methods/tracking/README.md.

Where the code lives: a method family keeps its numerics, batch or sample by sample (``methods.kalman.online``:
the filters with a causal P0 and restarts; ``methods.pll``: the loop bank, online by design); this package
holds every tracker, one private module each (``_kalman``, ``_pll``: adapters of the families' runs to
:class:`Track`; ``_windowed``, ``_rls_ar``, ``_next_era``, ``_gated_pencil``: trackers of no family), and the face.
"""

from __future__ import annotations

import importlib
import time

import numpy as np

from methods.estimate import check_inputs, check_prior
from methods.tracking._track import Track, with_runtime

# Trackers that run natively (their own per-sample recursion or their own windows): name -> module.
_NATIVE: dict[str, str] = {
    "akf": "methods.tracking._kalman",
    "wkf": "methods.tracking._kalman",
    "pll": "methods.tracking._pll",
    "rls_ar": "methods.tracking._rls_ar",
    "next_era": "methods.tracking._next_era",
    "gated_pencil": "methods.tracking._gated_pencil",
}
_WINDOWED = "methods.tracking._windowed"


def batch_names() -> list[str]:
    """The batch methods (:func:`methods.names`). The registry lives in methods/__init__.py, which imports
    this face and hands its ``names`` down here (replacing this function), so that the two do not import
    each other; none before that."""
    return []

__all__ = ["Track", "check_track_options", "track", "track_names", "track_options_class"]


def track_names() -> list[str]:
    """Names of the trackers: the native ones, then every other batch method (plugins included) on a
    sliding window."""
    native = list(_NATIVE)
    windowed = [n for n in batch_names() if n not in _NATIVE]
    return native[:3] + windowed + native[3:]


def _module(name: str):
    if name in _NATIVE:
        return importlib.import_module(_NATIVE[name])
    if name in batch_names():
        return importlib.import_module(_WINDOWED)
    raise ValueError(f"unknown tracker '{name}'; known trackers: {', '.join(track_names())}")


def track_options_class(name: str):
    """The options dataclass of tracker ``name`` (its keyword options and their defaults)."""
    module = _module(name)
    if name in ("akf", "wkf"):
        return module.OPTIONS[name]
    if module.__name__ == _WINDOWED:
        return module.options_class(name)
    return getattr(module, "PllOptions", None) or module.Options


def check_track_options(name: str, prior, dt: float, options: dict | None = None, *, n_samples: int | None = None):
    """Validate tracker ``name``'s options for this prior and sample interval, before any work.

    Returns the tracker's options dataclass; raises ``ValueError`` (one line, naming the option) when one is
    impossible: an unknown key, a window of fewer than 8 samples, ``hop_samples`` ≤ 0, or — when the record
    length ``n_samples`` is given — a window longer than the record.
    """
    module = _module(name)
    dt, prior = check_prior(dt, prior)
    if n_samples is not None and (isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer))
                                  or n_samples < 1):
        raise ValueError(f"n_samples = {n_samples!r} must be a positive integer")
    return module.check_options(name, prior, dt, dict(options or {}), n_samples)


def track(name: str, y, dt, prior, **options) -> Track:
    """Track the modal frequencies of record ``y`` online with tracker ``name``.

    Parameters
    ----------
    name : str
        A tracker of :func:`track_names`.
    y : array_like, shape (n,)
        Tip acceleration in m/s², sampled at t_k = kΔt.
    dt : float
        Sample interval Δt in s.
    prior : array_like, shape (m,)
        A-priori frequencies in rad/s, increasing: the start of every tracker, and the order of the output.
    **options
        Fields of :func:`track_options_class` (name).

    Returns
    -------
    Track
        ``t_s`` (K,), ``frequencies``/``std``/``converged`` (K, m) in prior order, the estimate at ``t_s[k]``
        from the samples up to ``t_s[k]`` only; ``runtime_s`` the CPU time of the run.
    """
    start = time.process_time()
    y, dt, prior = check_inputs(y, dt, prior)
    module = _module(name)
    module.check_options(name, prior, dt, options, y.size)
    result = module.run(name, y, dt, prior, options)
    return with_runtime(result, time.process_time() - start)
