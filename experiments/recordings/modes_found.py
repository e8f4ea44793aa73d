"""The modes of a measurement without a prior: a stabilisation diagram of a segment (docs/measurements.md).

Shared by the identify job on a user's file (:mod:`experiments.jobs.identify`) and the track job
(:mod:`experiments.jobs.track_file`).
"""

from __future__ import annotations

import numpy as np

from experiments.recordings.formats import INSTALL_HINT

__all__ = ["find_modes"]


def find_modes(data: dict, n_modes: int | None):
    """The modes of the segment from a stabilisation diagram: (prior in rad/s, the diagram)."""
    try:
        from methods.peers.stabilisation import stabilisation_diagram  # optional extra (pyOMA2): refused below
        diagram = stabilisation_diagram(data["segment"].y, data["dt"],
                                        band_rad_s=tuple(2 * np.pi * np.asarray(data["segment"].band_hz)),
                                        n_modes=n_modes)
    except ModuleNotFoundError as exc:
        raise ValueError(f"finding the modes without a prior needs the package '{exc.name}': {INSTALL_HINT}"
                         ) from None
    if diagram.modes_rad_s.size == 0:
        lo, hi = data["segment"].band_hz
        raise ValueError(f"{data['source']}: no mode stands out of the noise between {lo:.4g} and {hi:.4g} Hz "
                         f"({diagram.n_clusters} stable clusters on the stabilisation diagram); give a prior")
    return diagram.modes_rad_s, diagram
