"""The Hydra configs as a Python package: installed as ``experiments.configs`` (package data), which Hydra finds
on its search path as ``pkg://experiments.configs`` (experiments/jobs/app.py). Holds no code."""
