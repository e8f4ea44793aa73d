"""MLflow runs of the track job on a user's file (experiments/jobs/track_file.py), logged after its answer.

The track job is frequency tracking and imports no MLflow logging (tests/test_names.py): it writes its run,
ready to log, as ``mlflow_track_run.json`` in its run folder (experiment, run key, parameters, metrics, tags,
texts, the dataset and the artifacts: the keyword arguments of :func:`experiments.runlog.pending.enqueue`) and
starts this module, detached, or waits for it (``--now``). This module queues the folder as the identify job
queues its own (:mod:`experiments.runlog.pending`) and logs every waiting run:

    python -m experiments.runlog.file_tracks RUN_DIR [--now]
    python -m experiments.runlog.file_tracks --check          # the store, before any work: one line, exit 2
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from experiments.runlog import pending
from experiments.runlog.store import check_store

__all__ = ["RUN_FILE", "enqueue_folder", "main"]

RUN_FILE = "mlflow_track_run.json"


def enqueue_folder(run_dir: Path) -> str:
    """Queue the run the track job wrote in ``run_dir``; its key."""
    run_dir = Path(run_dir)
    spec = json.loads((run_dir / RUN_FILE).read_text())
    pending.enqueue(run_dir, spec["experiment"], spec["run_key"], params=spec["params"], metrics=spec["metrics"],
                    tags=spec["tags"], texts=spec["texts"], dataset=spec["dataset"],
                    artifacts=[run_dir / name for name in spec["artifacts"]])
    return spec["run_key"]


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv == ["--check"]:
        try:
            check_store()
        except ValueError as exc:
            print(f"error: {' '.join(str(exc).split())}", file=sys.stderr)
            return 2
        return 0
    now = "--now" in argv
    folders = [a for a in argv if a != "--now"]
    if len(folders) != 1:
        print("error: give one run folder of the track job (and --now to log in this process)", file=sys.stderr)
        return 2
    key = enqueue_folder(Path(folders[0]))
    if now:
        out = pending.log_folder(Path(folders[0]))       # None: another logger logged it meanwhile
        print(f"run {key} ({'logged' if out is not None and out[2] else 'already there'})")
        return 0
    logged, failed = pending.log_all()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
