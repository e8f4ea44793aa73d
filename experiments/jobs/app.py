"""Running a Hydra app so that bad input gets one clear line, a non-zero exit, and no output.

Hydra reports a composition error over several lines with a stack-trace hint. Here the configuration is
composed and checked once *before* Hydra starts the job (which creates its run directory): an unknown key,
a wrong type or an impossible value is reported as ``error: <one line>`` on stderr with exit status 2, and
nothing is written. Sweeps (``-m``) skip the pre-check and are checked per job.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from pathlib import Path

import hydra
from hydra import compose, initialize_config_module
from hydra.errors import OverrideParseException
from omegaconf import DictConfig, OmegaConf, open_dict

from experiments.io import check_writable

# configs/ travels with the code as the package data `experiments.configs` (experiments/configs links to it in
# the repository; a wheel holds a copy), so Hydra finds it from any working directory, installed or not.
CONFIG_MODULE = "experiments.configs"
CONFIG_DIR = str(Path(__file__).resolve().parents[1] / "configs")   # for code that reads a YAML file directly
EXIT_BAD_INPUT = 2
BAD_INPUT = (ValueError, FileNotFoundError, KeyError)


_MISSING_OPTION = re.compile(r"Could not find '(\w+)/([^']+)'")


def one_line(exc: BaseException) -> str:
    """The message of an exception (and what it was raised from) on one line, without Hydra's hints."""
    text = str(exc)
    missing = _MISSING_OPTION.search(text)
    if missing:
        group, name = missing.groups()
        known = sorted(p.stem for p in (Path(CONFIG_DIR) / group).glob("*.yaml"))
        return f"unknown {group} '{name}'; known: {', '.join(known)}"
    parts = []
    while exc is not None:
        text = str(exc).strip()
        if text and text not in parts:
            parts.append(text)
        exc = exc.__cause__
    lines = []
    for line in "\n".join(parts).splitlines():
        line = line.strip()
        if not line or line.startswith(("To append to your config", "Set the environment variable")):
            continue
        lines.append(line)
    return re.sub(r"\s+", " ", "; ".join(lines))


_KEY_VALUE = re.compile(r"^([+~]{0,2}[\w.@/-]+)=(.*)$", re.S)


def quote_unicode_value(arg: str) -> str:
    """``key=value`` with a non-ASCII character in a plain value (``data.path=mesure_été.csv``) quoted for
    Hydra, whose override grammar reads only ASCII in unquoted values; anything else is left as it is."""
    match = _KEY_VALUE.match(arg)
    if not match or arg.isascii():
        return arg
    key, value = match.groups()
    if any(c in value for c in "'\"\\[]{},"):
        return arg            # quoted, a list/dict/sweep, or escapes: the user's own syntax stands
    return f"{key}='{value}'"


def fail(message: str) -> None:
    print(f"error: {message}", file=sys.stderr)
    sys.exit(EXIT_BAD_INPUT)


def run_app(config_name: str, task: Callable[[DictConfig], object],
            check: Callable[[DictConfig], object] | None = None) -> None:
    """Pre-check the command line, then hand it to ``hydra.main``.

    ``check(cfg)`` raises ``ValueError`` (or FileNotFoundError) for impossible values; ``task(cfg)`` does
    the work. A bad-input exception from either becomes one line on stderr and exit status 2.
    """
    args = sys.argv[1:] = [quote_unicode_value(a) for a in sys.argv[1:]]
    if not any(a in ("-m", "--multirun") or a.startswith("-") for a in args):
        try:
            with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
                cfg = compose(config_name=config_name, overrides=args, return_hydra_config=True)
            _check_outputs_writable(cfg)
            with open_dict(cfg):
                del cfg["hydra"]
            OmegaConf.resolve(cfg)
            if check is not None:
                check(cfg)
        except OverrideParseException as exc:
            fail(f"cannot read the override {exc.override}: {one_line(exc)}; a value with brackets, commas, "
                 f"spaces or quotes is quoted whole, e.g. prior='[3.8,16,26,46]'")
        except Exception as exc:  # noqa: BLE001 - every composition/validation error is bad input
            fail(one_line(exc))

    def guarded(cfg: DictConfig):
        try:
            if check is not None:
                check(cfg)
            return task(cfg)
        except BAD_INPUT as exc:
            if _in_sweep():        # one bad trial of a sweep is recorded (error.txt) and the sweep goes on
                return _record_failure(one_line(exc))
            _remove_empty_run_dir()
            fail(one_line(exc))

    hydra.main(config_path=f"pkg://{CONFIG_MODULE}", config_name=config_name, version_base="1.3")(guarded)()


def _check_outputs_writable(cfg: DictConfig) -> None:
    """Hydra's run folder (``hydra.run.dir``, made before the job starts) and the job's ``out``/``out_dir``
    must be writable: else one line now instead of an ``os.mkdir`` traceback from Hydra or the job."""
    run_dir = OmegaConf.select(cfg, "hydra.run.dir", default=None)
    if run_dir is not None:
        check_writable(run_dir, "hydra.run.dir")
    for key in ("out", "out_dir"):
        value = OmegaConf.select(cfg, key, default=None)
        if isinstance(value, str) and value:
            check_writable(value, key)


def _remove_empty_run_dir() -> None:
    """Take away the run directory Hydra made for a job that failed on bad input before writing anything."""
    import shutil

    from hydra.core.hydra_config import HydraConfig

    try:
        run_dir = Path(HydraConfig.get().runtime.output_dir)
    except ValueError:
        return
    if run_dir.resolve() == Path.cwd().resolve() or not run_dir.is_dir():
        return
    leftovers = [p for p in run_dir.iterdir() if p.name != ".hydra" and p.suffix != ".log"]
    if not leftovers:
        shutil.rmtree(run_dir, ignore_errors=True)


def _in_sweep() -> bool:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    return HydraConfig.initialized() and HydraConfig.get().mode == RunMode.MULTIRUN


def _record_failure(message: str) -> float:
    """A failed sweep job: the line on stderr and in ``error.txt`` of its run directory; the worst objective."""
    from hydra.core.hydra_config import HydraConfig

    from experiments.io import atomic_write_text

    print(f"error: {message}", file=sys.stderr)
    atomic_write_text(Path(HydraConfig.get().runtime.output_dir) / "error.txt", f"error: {message}\n")
    return float("inf")
