"""A trivial stand-in for the trackers' face (``methods.track``), for the tests of the tracking workflow only.

It reports the prior until 2 s of samples are in, then, every 25 samples, the m largest peaks of the
spectrum of the last 2 s (causal, a few lines of numpy). Not a method: it exists so that the truth side's
jobs are tested before, and independently of, the real trackers.
"""

import time
from dataclasses import dataclass, field

import numpy as np


@dataclass
class StandInTrack:
    t_s: np.ndarray
    frequencies: np.ndarray
    std: np.ndarray
    converged: np.ndarray
    runtime_s: float = 0.0
    message: str = ""
    extra: dict = field(default_factory=dict)


def prior_hop(prior) -> int:
    """The hop of the stand-in ``prior_hop``: 20-30 samples, set by the prior as a real tracker's hop is."""
    return 20 + int(round(1000 * float(np.asarray(prior)[0]))) % 11


def track(name, y, dt, prior, **options):
    if name == "broken":
        raise RuntimeError("the stand-in breaks on purpose")
    t0 = time.process_time()
    prior = np.asarray(prior, dtype=float)
    m = prior.size
    window = int(2.0 / dt)
    hop = prior_hop(prior) if name == "prior_hop" else 25
    ends = np.arange(hop - 1, y.size, hop)
    out = np.tile(prior, (ends.size, 1))
    freqs = 2 * np.pi * np.fft.rfftfreq(4 * window, dt)
    for j, e in enumerate(ends):
        if e + 1 < window:
            continue
        spec = np.abs(np.fft.rfft(y[e + 1 - window:e + 1] * np.hanning(window), 4 * window))
        peaks = np.flatnonzero((spec[1:-1] > spec[:-2]) & (spec[1:-1] > spec[2:])) + 1
        top = np.sort(freqs[peaks[np.argsort(spec[peaks])[-m:]]])
        if top.size == m:
            out[j] = top
    return StandInTrack(ends * dt, out, np.full(out.shape, np.nan), np.ones(out.shape, bool),
                        time.process_time() - t0, "stand-in")


# the windowed trackers the grids give options to, played by the same stand-in (they accept a hop)
WINDOWED = ["n4sid", "ssi_cov", "ssi_data", "lsce", "hdmd", "bopdmd"]


def track_names():
    return ["stand_in", "broken", "prior_hop", *WINDOWED]


def check_track_options(name, prior, dt, options=None, *, n_samples=None):
    if name not in track_names():
        raise ValueError(f"unknown tracker '{name}'")
    for key in options or {}:
        if not (name in WINDOWED and key in ("hop_samples", "hop_fraction")):
            raise ValueError(f"{name}: unknown option '{key}'")


def install(monkeypatch):
    import methods

    for fn in (track, track_names, check_track_options):
        monkeypatch.setattr(methods, fn.__name__, fn, raising=False)
