"""Benchmark commands (``python -m experiments.benchmarks.<name>``): medians, never timed tests."""

from __future__ import annotations

import statistics
import time

__all__ = ["interleaved_medians", "median_seconds"]


def interleaved_medians(fns: dict, repeats: int) -> dict:
    """Median wall time of each ``fn()`` over ``repeats`` rounds, one call of every fn per round, so that
    a slow spell of the shared machine hits every row alike (the ratios are what to quote)."""
    times = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    return {name: statistics.median(t) for name, t in times.items()}


def median_seconds(fn, repeats: int) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls (the machine is shared: quote medians)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)
