"""Shared pieces of the development scripts (not a test; pytest does not collect it): a benchmark cell
simulated once and kept as a pickle, and which configs are white-force drifts."""

import pickle
from pathlib import Path

from experiments.simulate.tracking_data import make_cell


def cached_cell(cfg, cache: str | None, key: str) -> dict:
    """``make_cell(cfg)``, read from ``<cache>/<key>.pkl`` when it is there and written there when it is not."""
    path = Path(cache) / f"{key}.pkl" if cache else None
    if path is not None and path.exists():
        return pickle.loads(path.read_bytes())
    cell = make_cell(cfg)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(cell))
    return cell


def white_force_drift(cfg) -> bool:
    """A drift under a white force alone: no slosh, no thruster pulses."""
    return (cfg.schedule.drift is not None and not cfg.schedule.slosh and cfg.excitation.disturbance_force_n > 0
            and cfg.excitation.thruster_torque_n_m == 0)
