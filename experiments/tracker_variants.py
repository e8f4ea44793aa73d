"""Tracker variants: ``name:variant`` in a tracking grid's ``trackers:`` (or a benchmark's rows) is tracker
``name`` with the options of ``configs/tracker/<name>_<variant>.yaml`` over the tracker's defaults.

A variant file (written by ``python -m experiments.tuning.tune tuning=track_<name>``, or by hand) is

    tracker: akf
    variant: tuned
    options: {qd_frequency: 1.0e-06, ...}

The label ``akf:tuned`` names the variant's folder, its rows in the tables and its lines in the figures; the
plain ``akf`` stays a row of its own (the tracker's defaults).
"""

from __future__ import annotations

from pathlib import Path

from experiments import paths

__all__ = ["VARIANT_DIR", "known_variants", "split", "variant_options", "variant_path"]

VARIANT_DIR = paths.TRACKER_CONFIGS


def split(spec: str) -> tuple[str, str]:
    """``akf:tuned`` -> (``akf``, ``tuned``); ``akf`` -> (``akf``, ``""``)."""
    name, _, variant = str(spec).partition(":")
    return name, variant


def variant_path(name: str, variant: str, root: Path | None = None) -> Path:
    return (root or VARIANT_DIR) / f"{name}_{variant}.yaml"


def known_variants(name: str, root: Path | None = None) -> list[str]:
    """The variants of tracker ``name`` that have a config file."""
    d = root or VARIANT_DIR
    return sorted(p.stem[len(name) + 1:] for p in d.glob(f"{name}_*.yaml")) if d.is_dir() else []


def variant_options(spec: str, root: Path | None = None) -> dict:
    """The options a variant sets (empty for a plain tracker name). ``ValueError`` (one line) for a variant
    with no config file or a file that names another tracker."""
    name, variant = split(spec)
    if not variant:
        return {}
    path = variant_path(name, variant, root)
    if not path.is_file():
        known = known_variants(name, root)
        raise ValueError(f"unknown tracker variant '{spec}': no {path.name} in configs/tracker; known variants "
                         f"of {name}: {', '.join(f'{name}:{v}' for v in known) or 'none'}")
    from omegaconf import OmegaConf  # reads 1e-6 as a number, as the writer (OmegaConf.to_yaml) means it

    body = OmegaConf.to_container(OmegaConf.load(path), resolve=True) or {}
    if not isinstance(body, dict) or body.get("tracker") != name or not isinstance(body.get("options", {}), dict):
        raise ValueError(f"{path}: must be a mapping with tracker: {name} and options: {{...}}")
    return dict(body.get("options") or {})
