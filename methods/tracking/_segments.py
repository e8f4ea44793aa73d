"""Pulse-free segments of a tracking window: the runs between the samples the pulse detector flags.

The fit over them — shared frequencies and damping, each segment's own amplitudes, phases and offset — is
pem's :func:`methods.pem.separable_fit` (variable projection; its docstring gives the model).
"""

from __future__ import annotations

import numpy as np


def segments(flags: np.ndarray, min_length: int) -> list[tuple[int, int]]:
    """Runs [a, b) of unflagged samples at least ``min_length`` long: a flagged sample belongs to no segment
    (its sample carries the pulse's feed-through) and the next free decay starts after it."""
    good = ~np.asarray(flags, dtype=bool)
    edges = np.diff(np.concatenate(([0], good.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True) if b - a >= min_length]
