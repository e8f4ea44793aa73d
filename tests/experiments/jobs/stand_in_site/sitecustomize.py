"""Installs the stand-in tracker (tests/experiments/jobs/_stand_in_tracker.py) into ``methods`` in every
Python process started with this folder on PYTHONPATH: the tracking workflow's test runs Snakemake and its
jobs that way, before and independently of the real trackers."""

import importlib.util
import pathlib

_spec = importlib.util.spec_from_file_location(
    "_stand_in_tracker", pathlib.Path(__file__).resolve().parents[1] / "_stand_in_tracker.py")
_mod = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_mod)

import methods  # noqa: E402

for _fn in (_mod.track, _mod.track_names, _mod.check_track_options):
    setattr(methods, _fn.__name__, _fn)
