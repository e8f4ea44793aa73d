"""The Hydra configs as a Python package: installed as ``experiments.configs`` (package data), which Hydra finds
on its search path as ``pkg://experiments.configs`` (experiments/hydra_app/command_line.py). Holds no code."""
