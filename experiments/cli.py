"""The command-line parser of the project's argparse commands, whose refusals are one line, and the line a
workflow step ends with to say what it cost.

``argparse`` reports a bad command line as a usage block and a message (several lines); here it is one line,
``error: <command>: <what>; see <command> --help``, with exit status 2, as every other bad input.
"""

from __future__ import annotations

import argparse
import os
import re
import sys

__all__ = ["ArgumentParser", "CPU_LINE", "cpu_line", "read_cpu_line"]

# The last line of a tracking-grid step's log: its CPU seconds from the process's start (imports included) and of
# the worker processes it waited for. Snakemake's benchmark files sample a job's CPU every few seconds and miss
# up to the last interval's; the grid's cost model (experiments.benchmarks.tracking_grid_cost --run) reads this.
CPU_LINE = re.compile(r"^total: ([0-9.]+) s CPU", re.MULTILINE)


def cpu_line() -> str:
    """``total: <s> s CPU (...)``: user + system time of this process and of its finished children."""
    return f"total: {sum(os.times()[:4]):.3f} s CPU (this process from its start, and its workers)"


def read_cpu_line(text: str) -> float | None:
    """The CPU seconds of the last :func:`cpu_line` in a log's ``text``, None if it has none."""
    found = CPU_LINE.findall(text)
    return float(found[-1]) if found else None


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with a one-line refusal (``--help`` is unchanged)."""

    def error(self, message: str):
        print(f"error: {self.prog}: {' '.join(message.split())}; see {self.prog} --help", file=sys.stderr)
        sys.exit(2)
