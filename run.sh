#!/usr/bin/env bash
# Set-up and entry points. The first call creates .venv with Python 3.11 and installs the project.
#   ./run.sh reproduce     the paper reproduction: the paper grid, tables, figures (snakemake paper)
#   ./run.sh test          lint, workflow lint, and the test suite (with the smoke workflow end to end)
#   ./run.sh smoke | full  the CI grid / the R = 100 grid up to 2048 samples
#   ./run.sh mlflow-server postgresql+psycopg://USER:PASSWORD@HOST/DB     a shared MLflow server (docs/cluster.md)
#   ./run.sh snakemake ... / python ...   anything else, inside the environment
set -euo pipefail
cd "$(dirname "$0")"
PYTHON=${PYTHON:-python3.11}
command -v "$PYTHON" >/dev/null || PYTHON=python3

if [ ! -x .venv/bin/python ] || [ pyproject.toml -nt .venv/.installed ]; then
  "$PYTHON" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' \
    || { echo "error: Python 3.11 is required (found $("$PYTHON" --version 2>&1))" >&2; exit 2; }
  [ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e '.[dev,peers,tuning,cluster,measurements]'
  touch .venv/.installed
fi
# The project's own modules as bytecode, as pip leaves every installed package: each workflow job is a
# process that imports them, and where PYTHONDONTWRITEBYTECODE is set (containers, CI images) every one of
# them would compile the sources again (~0.2 s a process). Only stale or missing files are written.
.venv/bin/python -m compileall -q methods experiments >/dev/null || true
export PATH="$PWD/.venv/bin:$PATH"
CORES=${CORES:-$(nproc 2>/dev/null || echo 2)}

# A workflow killed with SIGKILL leaves Snakemake's lock behind; clear it when no Snakemake runs in this
# working directory (Snakemake works in its --directory, so a process's cwd tells which folder it locks;
# another user's workflow elsewhere on the machine does not count). Without /proc, any Snakemake counts.
# Every output is written atomically, so a job killed mid-way leaves no file, and one killed after its rename
# but before Snakemake recorded it is complete and safe to redo: Snakemake reruns it without asking. The
# option is given here, not in a default workflow profile, whose "Using workflow specific profile ..." line
# Snakemake prints before anything else, a grid's one-line refusal included.
RERUN=--rerun-incomplete
snakemake_runs_here() {
  local pid
  for pid in $(pgrep -f snakemake 2>/dev/null); do
    [ "$pid" = "$$" ] && continue
    if [ -d /proc/self ]; then
      [ "$(readlink "/proc/$pid/cwd" 2>/dev/null)" = "$PWD" ] && return 0
    else
      return 0
    fi
  done
  return 1
}
unlock_if_stale() {
  if [ -n "$(ls -A .snakemake/locks 2>/dev/null)" ] && ! snakemake_runs_here; then
    snakemake --unlock --cores 1 >/dev/null 2>&1 || true
  fi
}

case "${1:-}" in
  reproduce|paper) shift; unlock_if_stale; exec snakemake $RERUN --cores "$CORES" paper "$@" ;;
  smoke)           shift; unlock_if_stale; exec snakemake $RERUN --cores "$CORES" smoke "$@" ;;
  full)            shift; unlock_if_stale; exec snakemake $RERUN --cores "$CORES" full "$@" ;;
  snakemake)       shift; unlock_if_stale; exec snakemake $RERUN "$@" ;;
  tracking-server)   # the old name of mlflow-server, until the next release
    echo "note: ./run.sh tracking-server is now ./run.sh mlflow-server; the old name works until the next release" >&2
    shift; exec "$0" mlflow-server "$@" ;;
  mlflow-server)
    # mlflow server on a PostgreSQL backend store; artifacts are uploaded through the server into
    # results/mlflow-artifacts (or --artifacts-destination). Later options override: --host, --port, ...
    shift
    case "${1:-}" in
      postgresql*://*) ;;
      *) echo "error: mlflow-server needs the PostgreSQL URL first, e.g. postgresql+psycopg://USER:PASSWORD@HOST/DB (got '${1:-}')" >&2; exit 2 ;;
    esac
    db=$1; shift
    exec mlflow server --backend-store-uri "$db" --artifacts-destination "$PWD/results/mlflow-artifacts" \
      --host 0.0.0.0 --port 5000 "$@" ;;
  test)
    shift
    ruff check .
    snakemake --lint
    # the suite in parallel, one worker per core; a test file stays on one worker (its module fixtures run once)
    exec python -m pytest -n "${TEST_WORKERS:-$CORES}" --dist loadfile "$@" ;;
  "" | -h | --help) sed -n '2,7p' "$0" ;;
  *) exec "$@" ;;
esac
