"""Benchmark commands (``python -m experiments.benchmarks.<name>``): medians, never timed tests.

Each command prints its tables and, run from the command line, also writes what it printed to the generated
page ``results/bench/<name>.md`` (:func:`run_with_page`), headed by the command, the time, the commit and the
machine's load: dated measurements live there, not in the READMEs.
"""

from __future__ import annotations

import contextlib
import io
import os
import shlex
import statistics
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from threadpoolctl import threadpool_info, threadpool_limits

from experiments.io import atomic_write_text
from experiments.provenance import git_state

PAGE_DIR = Path("results") / "bench"
_PAGE_ENV = "EXPERIMENTS_BENCH_PAGE"     # set while a page is being recorded: a child benchmark writes none

__all__ = ["interleaved_medians", "median_seconds", "blas_threads", "blas_threads_now", "one_blas_thread",
           "run_tracker_command", "page_text", "run_with_page"]

# The benchmarks multiply small matrices: more than one BLAS thread only adds overhead on a busy machine.
BLAS_THREADS = 1


def blas_threads() -> int:
    """The BLAS threads a benchmark runs with: ``OPENBLAS_NUM_THREADS`` when the user set it, else
    :data:`BLAS_THREADS`."""
    return int(os.environ.get("OPENBLAS_NUM_THREADS") or BLAS_THREADS)


def one_blas_thread():
    """The process's BLAS thread pools limited to :func:`blas_threads` while a benchmark runs (threadpoolctl).

    Setting ``OPENBLAS_NUM_THREADS`` inside the process would come too late: under ``python -m
    experiments.benchmarks.<name>`` this package's imports have loaded numpy, and OpenBLAS read the variable
    then."""
    return threadpool_limits(limits=blas_threads(), user_api="blas")


def run_tracker_command(main) -> None:
    """A tracker benchmark's ``__main__``: ``main()`` under :func:`one_blas_thread`; a bad tracker name or
    option (ValueError) is one ``error:`` line on stderr, exit status 2, nothing written."""
    try:
        with one_blas_thread():
            main()
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)


def blas_threads_now() -> int | None:
    """The threads of the process's BLAS thread pool as it stands (None: no BLAS loaded)."""
    counts = [pool["num_threads"] for pool in threadpool_info() if pool.get("user_api") == "blas"]
    return max(counts) if counts else None


def interleaved_medians(fns: dict, repeats: int, cpu: bool = False):
    """Median wall time of each ``fn()`` over ``repeats`` rounds, one call of every fn per round, so that
    a slow spell of the shared machine hits every row alike (the ratios are what to quote). ``cpu``: also
    the median process CPU time of the same calls (``time.process_time``; every thread of the process, so
    an absolute number with one BLAS thread), returned as a second dict."""
    times = {name: [] for name in fns}
    cpus = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times[name].append(time.perf_counter() - t0)
            cpus[name].append(time.process_time() - c0)
    wall = {name: statistics.median(t) for name, t in times.items()}
    return (wall, {name: statistics.median(t) for name, t in cpus.items()}) if cpu else wall


def median_seconds(fn, repeats: int) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls (the machine is shared: quote medians)."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


class _Tee(io.TextIOBase):
    """A text stream that writes through to ``stream`` and keeps a copy (the standard library has no tee;
    :func:`contextlib.redirect_stdout` needs one object that does both)."""

    def __init__(self, stream):
        self.stream = stream
        self.copy = io.StringIO()

    def write(self, s: str) -> int:
        self.stream.write(s)
        return self.copy.write(s)

    def flush(self) -> None:
        self.stream.flush()


def page_text(name: str, argv: list[str], printed: str, when: datetime | None = None) -> str:
    """The Markdown page of one benchmark run: a header (command, UTC time, commit, CPUs, load average,
    BLAS threads) and the printed output — as is when it holds Markdown tables, else fenced."""
    when = when or datetime.now(UTC)
    state = git_state()
    commit = state["commit"][:12] + (" + uncommitted changes" if state.get("dirty") else "")
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "unknown"
    command = shlex.join(["python", "-m", f"experiments.benchmarks.{name}", *argv])
    header = [f"# Benchmark `{name}` (generated)", "",
              f"- command: `{command}`",
              f"- run: {when:%Y-%m-%d %H:%M} UTC, commit {commit}",
              f"- machine: {os.cpu_count()} CPUs, load average {load} (1, 5, 15 min), "
              f"BLAS threads {blas_threads_now()}",
              "- times are medians on the machine as it was; compare rows of one run, not runs", ""]
    tables = any(line.startswith("|---") for line in printed.splitlines())
    body = printed if tables else f"```\n{printed.rstrip()}\n```\n"
    return "\n".join(header) + "\n" + body


def run_with_page(main, name: str, argv: list[str] | None = None, page_dir: Path = PAGE_DIR) -> int:
    """Run a benchmark's ``main(argv)``, printing as it does, then write what it printed to
    ``<page_dir>/<name>.md`` (atomically; see :func:`page_text`) and say so.

    A run that fails (a non-zero status or an exception, e.g. a refused seed) writes nothing. A benchmark
    started by another one (``pem --part speed`` runs ``pem_speed`` in child processes) writes no page of its
    own: its output belongs to the parent's page.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    if os.environ.get(_PAGE_ENV):
        return main(argv) or 0
    os.environ[_PAGE_ENV] = name
    tee = _Tee(sys.stdout)
    try:
        with contextlib.redirect_stdout(tee):
            status = main(argv) or 0
    finally:
        del os.environ[_PAGE_ENV]
    if status:
        return status
    path = atomic_write_text(Path(page_dir) / f"{name}.md", page_text(name, argv, tee.copy.getvalue()))
    print(f"page: {path}")
    return 0
