"""Running a Hydra app so that bad input gets one clear line, a non-zero exit, and no output.

Hydra reports a composition error over several lines with a stack-trace hint. Here the configuration is
composed and checked once *before* Hydra starts the job (which creates its run directory): an unknown key,
a wrong type or an impossible value is reported as ``error: <one line>`` on stderr with exit status 2, and
nothing is written. Sweeps (``-m``) skip the pre-check and are checked per job.
"""

from __future__ import annotations

import re
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import hydra
from hydra import compose, initialize_config_module
from hydra.core.hydra_config import HydraConfig
from hydra.errors import OverrideParseException
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict

from experiments import paths
from experiments.io import atomic_write_text, check_writable

__all__ = ["CONFIG_MODULE", "CONFIG_DIR", "EXIT_BAD_INPUT", "BAD_INPUT", "one_line", "fail", "run_app",
           "check_command_line", "RENAMED_KEYS", "renamed_keys"]

# configs/ travels with the code as the package data `experiments.configs` (experiments/paths.py), so Hydra
# finds it from any working directory, installed or not.
CONFIG_MODULE = paths.CONFIG_MODULE
CONFIG_DIR = str(paths.CONFIGS)   # for code that reads a YAML file directly
EXIT_BAD_INPUT = 2
BAD_INPUT = (ValueError, FileNotFoundError, KeyError)


_MISSING_OPTION = re.compile(r"Could not find '(\w+)/([^']+)'")


def one_line(exc: BaseException) -> str:
    """The message of an exception (and what it was raised from) on one line, without Hydra's hints."""
    text = str(exc)
    missing = _MISSING_OPTION.search(text)
    if missing:
        group, name = missing.groups()
        known = sorted(p.stem for p in (paths.CONFIGS / group).glob("*.yaml"))
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


# Hydra's own command-line flags (``--help`` lists them); any other word starting with ``-`` is refused here in
# one line rather than by Hydra's argparse with its usage block.
HYDRA_FLAGS = frozenset({"-h", "--help", "--hydra-help", "--version", "-c", "--cfg", "--resolve", "-p",
                         "--package", "-i", "--info", "-r", "--run", "-m", "--multirun", "-sc", "--shell-completion",
                         "-cp", "--config-path", "-cn", "--config-name", "-cd", "--config-dir",
                         "--experimental-rerun"})


# Config keys renamed so that "tracking" names only frequency tracking: MLflow run logging is ``runlog``. Hydra
# has no alias of a key, so the old spelling is rewritten on the command line, with a note, until the next
# release.
RENAMED_KEYS = {"tracking": "runlog"}


def renamed_keys(args: list[str]) -> list[str]:
    """The command line with each renamed key (``runlog.enabled=false``, ``+tracking.x=...``,
    ``~tracking``) in its new spelling, and one note on stderr per old spelling used."""
    out = []
    for arg in args:
        match = re.match(r"([~+]*)(\w+)(?=[.=]|$)", arg)
        if match and match.group(2) in RENAMED_KEYS:
            new = match.group(1) + RENAMED_KEYS[match.group(2)] + arg[match.end():]
            print(f"note: {arg} is now {new}; the old spelling works until the next release", file=sys.stderr)
            arg = new
        out.append(arg)
    return out


def check_command_line(args: list[str]) -> None:
    """Refuse, in one line, an unknown flag and a key given twice (``method=pem method=fft``: Hydra would
    keep the last without a word)."""
    seen = {}
    for arg in args:
        if arg.startswith("-") and "=" not in arg and arg not in HYDRA_FLAGS:
            fail(f"unknown option {arg}; the options are key=value overrides (see --cfg job) and Hydra's flags "
                 f"(see --help)")
        match = _KEY_VALUE.match(arg)
        if match:
            key = match.group(1).lstrip("+~")
            if key in seen and seen[key] != arg:
                fail(f"{key} is given twice ({seen[key]} and {arg}); give it once")
            seen[key] = arg


def _check_sweep(config_name: str, args: list[str]) -> None:
    """A sweep (``-m``) composes each job when it starts it, and a value no job can compose (``method=nosuch``)
    would end the whole sweep with Hydra's error over many lines: each swept value is composed here first,
    with the other overrides, and the first that fails is one line. Values a job's own check refuses are
    left to the job (recorded in its ``error.txt``; the sweep goes on)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser  # Hydra internals: sweeps only

    words = [a for a in args if not a.startswith("-")]
    try:
        overrides = OverridesParser.create().parse_overrides(words)
    except OverrideParseException as exc:
        fail(f"cannot read the override {exc.override}: {one_line(exc)}")
    plain = [o.input_line for o in overrides if not o.is_sweep_override()]
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        for override in overrides:
            if not override.is_sweep_override():
                continue
            try:
                values = list(override.sweep_string_iterator())
            except Exception:  # noqa: BLE001 - an interval sweep (a sweeper plugin's) has no values to list
                continue
            for value in values:
                line = f"{override.get_key_element()}={value}"
                try:
                    compose(config_name=config_name, overrides=[*plain, line], return_hydra_config=True)
                except Exception as exc:  # noqa: BLE001 - every composition error is bad input
                    fail(f"{line} (of the sweep {override.input_line}): {one_line(exc)}")


def fail(message: str) -> None:
    print(f"error: {message}", file=sys.stderr)
    sys.exit(EXIT_BAD_INPUT)


def run_app(config_name: str, task: Callable[[DictConfig], object],
            check: Callable[[DictConfig], object] | None = None) -> None:
    """Pre-check the command line, then hand it to ``hydra.main``.

    ``check(cfg)`` raises ``ValueError`` (or FileNotFoundError) for impossible values; ``task(cfg)`` does
    the work. A bad-input exception from either becomes one line on stderr and exit status 2.
    """
    args = sys.argv[1:] = renamed_keys([quote_unicode_value(a) for a in sys.argv[1:]])
    check_command_line(args)
    if any(a in ("-m", "--multirun") for a in args):
        _check_sweep(config_name, args)
    if not any(a in ("-m", "--multirun") or a.startswith("-") for a in args):
        try:
            with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
                cfg = compose(config_name=config_name, overrides=args, return_hydra_config=True)
                _check_added_keys(config_name, args)
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


_ABSENT = object()


def _check_added_keys(config_name: str, args: list[str]) -> None:
    """Hydra's ``+key=value`` adds a key the config does not have, and nothing would read it: a typo or a
    hostile key (``+method._target_=os.system``) would pass without a word. Refused unless the key exists
    (``++key=value`` on a known key is an override). A config group (``+group=option``) and Hydra's own
    ``hydra.*`` keys are Hydra's to judge."""
    added = [a for a in args if a.startswith("+") and "=" in a and "/" not in a.split("=", 1)[0]
             and not a.lstrip("+").startswith("hydra.")]        # Hydra's own keys (hydra.job.env_set...)
    if not added:
        return
    base = compose(config_name=config_name, overrides=[a for a in args if a not in added], return_hydra_config=True)
    for arg in added:
        key = arg.lstrip("+").split("=", 1)[0]
        if OmegaConf.select(base, key, default=_ABSENT) is _ABSENT:
            raise ValueError(f"{arg}: the job has no key {key} (+ adds a key nothing reads); see --cfg job")


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
    return HydraConfig.initialized() and HydraConfig.get().mode == RunMode.MULTIRUN


def _record_failure(message: str) -> float:
    """A failed sweep job: the line on stderr and in ``error.txt`` of its run directory; the worst objective."""
    print(f"error: {message}", file=sys.stderr)
    atomic_write_text(Path(HydraConfig.get().runtime.output_dir) / "error.txt", f"error: {message}\n")
    return float("inf")
