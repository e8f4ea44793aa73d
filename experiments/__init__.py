"""Experiments: the spacecraft truth model, datasets, the Hydra jobs, scoring, tracking, tables and plots."""

__all__ = []
