"""Speed of the identify job on a user's measurement file, start-up included, and where the time goes.

    python -m experiments.benchmarks.measurement [--samples 100000] [--repeats 3] [--before /path/to/old/repo]
        [--previous /path/to/another/checkout]

The record is the simulated steel-cantilever impact (:mod:`experiments.simulate.impact`, seed 1) written as
a logger's CSV (time stamps rounded to 1 µs, the signal in g). Rows, each the median of ``--repeats``
runs of the job as a user types it (``python -m experiments.jobs.identify ...``, a fresh process):

- no prior (stabilisation diagram, then pem): MLflow logging off; the default command, whose MLflow run is
  logged by a detached process after the job (:mod:`experiments.runlog.pending`; before the next run
  the benchmark waits for it, untimed, so no run pays for the last one's logging); and the run logged in
  the job (``runlog.background=false``), all on one SQLite store (a fresh one for the first run);
- with ``--previous``: the same no-prior rows and the 512-sample rows run by another checkout of this line
  (e.g. the one before a change);
- with ``--before``: the same jobs run by another checkout (``PYTHONPATH``), e.g. the release before
  this one, on the same record as a plain ``t,accel`` CSV in m/s² with the prior given (what it reads);
  and both checkouts on the first 512 samples of that CSV with the prior (the first user's record size).

Wall time on a shared machine is noisy: the CPU time of the child (user + system) is given beside it, and
the load average. Where the time goes: one run under ``cProfile`` (cumulative time of the job's phases;
the profiler's own overhead inflates Python-heavy parts) and one under ``python -X importtime`` (the
import of each top-level package). Writes ``results/bench/measurement.md``.
"""

from __future__ import annotations

import argparse
import os
import pstats
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from experiments import paths
from experiments.simulate.impact import G, simulate

__all__ = ["ROOT", "JOB", "PHASES", "write_records", "run_job", "timed", "profile_phases", "import_times", "main",
           "report"]

ROOT = paths.ROOT
JOB = ["-m", "experiments.jobs.identify", "method=pem"]
# The job's phases, as (label, profiled function: file suffix, function name), in the order they run.
PHASES = [
    ("command line composed and checked before Hydra starts (run_app's pre-check)", "hydra/compose.py", "compose"),
    ("file read (read_record)", "recordings/read.py", "read_record"),
    ("segmented, decimated (choose_segment)", "recordings/segment.py", "choose_segment"),
    ("stabilisation diagram (pyOMA2 SSI-cov, clusters, detection)", "peers/stabilisation.py", "stabilisation_diagram"),
    ("pem refines the modes (run_records)", "jobs/identify.py", "run_records"),
    ("figure, PNG and SVG (measurement_figure)", "report/measurement_figure.py", "measurement_figure"),
    ("the job's record: provenance of the code and packages (job_record)", "jobs/identify.py", "job_record"),
    ("MLflow: the run logged (previous) or queued, its logger started (_identify_file.log)", "jobs/_identify_file.py",
     "log"),
    ("Hydra's run (output dir, logging) around the task", "hydra/core/utils.py", "run_job"),
    ("the whole job after start-up (identify.main)", "jobs/identify.py", "main"),
]


def write_records(d: Path, n: int) -> dict[str, Path]:
    rec = simulate(1, n_samples=n)
    logger = d / "impact.csv"
    pd.DataFrame({"t": np.round(rec.t, 6), "tip [g]": rec.accel_g}).to_csv(logger, index=False)
    plain = d / "impact_plain.csv"             # what the first release reads: t exact, accel in m/s²
    pd.DataFrame({"t": rec.t, "accel": rec.accel_g * G}).to_csv(plain, index=False, float_format="%.17g")
    return {"logger": logger, "plain": plain, "prior": rec.freq_rad_s}


def wait_for_logging(cwd: Path, pythonpath: Path, env: dict | None) -> None:
    """Wait (untimed) until no MLflow run of a job is left to log: the queue's logger takes the store's lock
    after the detached one (a checkout without :mod:`experiments.runlog.pending` has nothing to wait for)."""
    for stage in ("runlog", "tracking"):       # the stage's name in this checkout, and before the rename
        if (Path(pythonpath) / "experiments" / stage / "pending.py").is_file():
            break
    else:
        return
    subprocess.run([sys.executable, "-m", f"experiments.{stage}.pending"], cwd=cwd, capture_output=True,
                   env={**os.environ, "PYTHONPATH": str(pythonpath), **(env or {})})


def run_job(args: list[str], cwd: Path, pythonpath: Path, env: dict | None = None) -> tuple[float, float, str]:
    """Wall and CPU seconds (user + system of the child) of one job, and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, *args], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(pythonpath), **(env or {})})
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode != 0:
        raise RuntimeError(f"job failed ({proc.returncode}): {proc.stderr.strip()[-400:]}")
    if not {"runlog.enabled=false", OLD_OFF} & set(args):
        wait_for_logging(cwd, pythonpath, env)
    return wall, cpu, proc.stdout


# MLflow logging off: this checkout's key, and the one a checkout before the rename (--before, --previous)
# reads (this one reads it too, with a note).
OLD_OFF = "tracking.enabled=false"


def off(path) -> str:
    return "runlog.enabled=false" if path == ROOT else OLD_OFF


def timed(label: str, args: list[str], cwd: Path, pythonpath: Path, repeats: int, env=None) -> dict:
    runs = [run_job(args, cwd, pythonpath, env) for _ in range(repeats)]
    walls, cpus = [r[0] for r in runs], [r[1] for r in runs]
    print(f"{label}: wall {np.median(walls):.2f} s, CPU {np.median(cpus):.2f} s", file=sys.stderr, flush=True)
    return {"label": label, "wall": float(np.median(walls)), "cpu": float(np.median(cpus)),
            "wall_min": float(min(walls)), "cpu_min": float(min(cpus)), "stdout": runs[-1][2]}


def run_dir(args: list[str], folder: str) -> list[str]:
    """The job's arguments with its run folder set to ``folder`` (a key given twice is refused by the job)."""
    return [a for a in args if not a.startswith("hydra.run.dir=")] + [f"hydra.run.dir={folder}"]


def profile_phases(args: list[str], cwd: Path, env: dict | None = None,
                   pythonpath: Path = ROOT) -> tuple[list[tuple[str, float]], float]:
    out = cwd / "job.prof"
    proc = subprocess.run([sys.executable, "-m", "cProfile", "-o", str(out), *args], cwd=cwd, check=True,
                          capture_output=True, env={**os.environ, "PYTHONPATH": str(pythonpath), **(env or {})})
    if b"wrote " not in proc.stdout:          # cProfile exits 0 even when the job refused its arguments
        raise RuntimeError("the profiled job wrote nothing: " + proc.stderr.decode(errors="replace").strip()[-300:])
    stats = pstats.Stats(str(out)).stats
    total = max(v[3] for v in stats.values())
    rows = []
    for label, suffix, func in PHASES:
        cum = sum(v[3] for (file, _, name), v in stats.items() if file.endswith(suffix) and name == func)
        rows.append((label, cum))
    return rows, total


def import_times(args: list[str], cwd: Path, pythonpath: Path = ROOT, env=None,
                 top: int = 12) -> list[tuple[str, float]]:
    """Import time (s) per package (scipy per subpackage), summed over every module's own time, from
    ``python -X importtime``."""
    proc = subprocess.run([sys.executable, "-X", "importtime", *args], cwd=cwd, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(pythonpath), **(env or {})})
    per = {}
    for line in proc.stderr.splitlines():
        m = re.match(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", line)
        if m:
            parts = m.group(2).split(".")
            pkg = ".".join(parts[:2]) if parts[0] == "scipy" and len(parts) > 1 else parts[0]
            per[pkg] = per.get(pkg, 0.0) + int(m.group(1)) * 1e-6
    total = sum(per.values())
    return [("all imports", total), *sorted(per.items(), key=lambda kv: -kv[1])[:top]]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", type=Path, default=None, help="another checkout to time on the same record")
    parser.add_argument("--previous", type=Path, default=None,
                        help="a checkout of this line (e.g. before a change): the same commands as this release")
    a = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        files = write_records(d, a.samples)
        small = d / "small_plain.csv"
        small.write_text("".join(files["plain"].read_text().splitlines(keepends=True)[:513]))
        prior = "[" + ",".join(f"{w:.1f}" for w in files["prior"] * 0.98) + "]"
        store = {"MLFLOW_TRACKING_URI": f"sqlite:///{d / 'mlflow.db'}"}
        new = [*JOB, f"data.path={files['logger']}", "hydra.run.dir=run"]
        small_new = [*JOB, f"data.path={small}", f"prior={prior}", "hydra.run.dir=run_small"]
        rows = []
        for label, path in (("this release", ROOT), ("previous (--previous)", a.previous)):
            if path is None:
                continue
            db = {"MLFLOW_TRACKING_URI": f"sqlite:///{d / ('mlflow.db' if path == ROOT else 'mlflow_prev.db')}"}
            rows += [timed(f"{label}, no prior, MLflow logging off", [*new, off(path)], d, path, a.repeats),
                     timed(f"{label}, no prior, the default command (MLflow logging on)", new, d, path,
                           a.repeats, db)]
            if path == ROOT:        # the checkout before may have no runlog.background: its run is in the job
                rows.append(timed(f"{label}, no prior, MLflow run logged in the job (runlog.background=false)",
                                  [*new, "runlog.background=false"], d, path, a.repeats, db))
            rows += [timed(f"{label}, 512 samples, prior given, MLflow logging off", [*small_new, off(path)],
                           d, path, a.repeats),
                     timed(f"{label}, 512 samples, prior given, the default command (MLflow logging on)", small_new,
                           d, path, a.repeats, db)]
        if a.before is not None:
            old = [*JOB, f"data.path={files['plain']}", f"prior={prior}", "hydra.run.dir=run_before"]
            rows += [timed("before (--before), prior given, MLflow logging off", [*old, OLD_OFF], d,
                           a.before, a.repeats),
                     timed("before (--before), prior given, MLflow logging on", old, d, a.before, a.repeats,
                           {"MLFLOW_TRACKING_URI": f"sqlite:///{d / 'mlflow_before.db'}"})]
            args = [*JOB, f"data.path={small}", f"prior={prior}", "hydra.run.dir=run_small_before"]
            rows += [timed("before (--before), 512 samples, prior given, MLflow logging off",
                           [*args, OLD_OFF],
                           d, a.before, a.repeats),
                     timed("before (--before), 512 samples, prior given, MLflow logging on", args, d, a.before,
                           a.repeats, {"MLFLOW_TRACKING_URI": f"sqlite:///{d / 'mlflow_small.db'}"})]
        profiles = {"this release": profile_phases(run_dir(new, "run_prof"), d, store)}
        wait_for_logging(d, ROOT, store)
        if a.previous is not None:
            profiles["previous (--previous)"] = profile_phases(
                run_dir(new, "run_prof_prev"), d, {"MLFLOW_TRACKING_URI": f"sqlite:///{d / 'mlflow_prev.db'}"},
                a.previous)
        os.environ.update(store)
        imports = {"this release, MLflow logging off": import_times([*run_dir(new, "run_imp"),
                                                               "runlog.enabled=false"], d),
                   "this release, the default command (MLflow logging on)": import_times(
                       run_dir(new, "run_imp2"), d)}
        wait_for_logging(d, ROOT, store)
        if a.previous is not None:
            imports["previous (--previous), the default command (MLflow logging on)"] = import_times(
                run_dir(new, "run_imp4"), d, a.previous,
                {"MLFLOW_TRACKING_URI": f"sqlite:///{d / 'mlflow_prev.db'}"})
        if a.before is not None:
            imports["before, 512 samples, MLflow logging on"] = import_times(
                [*JOB, f"data.path={small}", f"prior={prior}", "hydra.run.dir=run_imp3"], d, a.before,
                {"MLFLOW_TRACKING_URI": f"sqlite:///{d / 'mlflow_small.db'}"})
        answer = rows[0]["stdout"]
    print(report(a, rows, profiles, imports, answer))


def report(a, rows, profiles, imports, answer) -> str:
    lines = [f"The identify job on a {a.samples}-sample logger CSV and on 512 samples, each a fresh process "
             f"(median and min of {a.repeats}; wall times on a shared machine are noisy, CPU time is the "
             "child's user + system; the default command's MLflow run is logged by a detached process, "
             "not timed, and waited for before the next run):", "",
             "| job | wall (median) | CPU (median) | wall (min) | CPU (min) |", "|---|---|---|---|---|"]
    lines += [f"| {r['label']} | {r['wall']:.2f} s | {r['cpu']:.2f} s | {r['wall_min']:.2f} s | {r['cpu_min']:.2f} s |"
              for r in rows]
    for who, (phases, total) in profiles.items():
        lines += ["", f"## Where the time goes, {who} (one run of the default command under cProfile, "
                  f"{total:.2f} s profiled; this release logs its MLflow run in another process)", "",
                  "| phase | cumulative |", "|---|---|"]
        lines += [f"| {label} | {cum:.2f} s |" for label, cum in phases]
    for label, table in imports.items():
        lines += ["", f"Imports, {label} (`python -X importtime`, each module's own time summed per package; "
                  "scipy per subpackage):", "", "| package | import |", "|---|---|"]
        lines += [f"| {pkg} | {sec:.2f} s |" for pkg, sec in table]
    lines += ["", "The answer of the first run:", "", "```", answer.strip(), "```", ""]
    return "\n".join(lines)


if __name__ == "__main__":
    from experiments.benchmarks import run_with_page

    raise SystemExit(run_with_page(main, "measurement"))   # prints, and writes results/bench/measurement.md
