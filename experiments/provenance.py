"""What determines a job's result, computed cheaply: the method's resolved config, the files of its code,
the versions of the packages that code imports, a dataset's digest and the code's git state.

The Snakemake rules use the first three as the identify rule's params and inputs (Snakemake's own rerun
triggers then rerun exactly the affected jobs); the MLflow run key uses all five. Nothing here runs a method
or imports MLflow: the workflow evaluates these functions for every job when it builds the DAG (a method's
module is imported for its ``Options`` schema only).
"""

from __future__ import annotations

import ast
import functools
import hashlib
import json
import subprocess
import sys
from importlib.metadata import PackageNotFoundError, packages_distributions, version
from pathlib import Path

from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from hydra.initialize import get_gh_backup, restore_gh_from_backup
from omegaconf import OmegaConf

import methods
from experiments import paths
from experiments.config_schema import IdentifyConfig, method_of_config, method_schema

__all__ = ["ROOT", "canonical_json", "digest", "resolved_method_config", "method_code_files", "package_versions",
           "code_digest", "file_digest", "git_state"]

ROOT = paths.ROOT


def canonical_json(obj) -> str:
    """One text per value: sorted keys, no whitespace (the form digests are taken of)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def digest(text: str | bytes, length: int = 16) -> str:
    data = text.encode() if isinstance(text, str) else text
    return hashlib.sha256(data).hexdigest()[:length]


_SCHEMAS: dict[str, bool] = {}  # method -> its real schema (True) or an empty stand-in (False) is stored


@functools.cache
def resolved_method_config(config_name: str, overrides: tuple[str, ...] = (), root: str = str(ROOT)) -> str:
    """The method node of ``configs/identify.yaml`` with ``method=<config_name>`` and ``overrides``, composed
    by Hydra (defaults chain, variants, interpolations) and returned as canonical JSON.

    The method's structured schema is generated from its ``Options`` (its module is imported, not run), so
    the node holds every option the job runs with, the dataclass defaults included, and an override of an
    unknown option fails here with its name; the other methods' schemas are stood in for by empty nodes.
    Hydra's global state is left as it was found (a caller's own initialisation survives the call).
    """
    cs = ConfigStore.instance()
    cs.store(name="identify_schema", node=IdentifyConfig)
    for name in methods.names():
        if name not in _SCHEMAS:
            cs.store(group="method", name=f"{name}_schema", node={})
            _SCHEMAS[name] = False
    method = method_of_config(config_name)
    if method is not None and not _SCHEMAS.get(method):
        cs.store(group="method", name=f"{method}_schema", node=method_schema(method))
        _SCHEMAS[method] = True
    return canonical_json(OmegaConf.to_container(_compose_identify(config_name, overrides, root).method,
                                                 resolve=True))


def overridden_prior(config_name: str, overrides: tuple[str, ...] = (), root: str = str(ROOT)) -> list | None:
    """The job's ``prior`` (rad/s) after ``overrides`` (a grid's ``prior=...``), resolved; None: not set."""
    cfg = _compose_identify(config_name, overrides, root)
    prior = cfg.prior
    return OmegaConf.to_container(prior, resolve=True) if OmegaConf.is_config(prior) else prior


def _compose_identify(config_name: str, overrides: tuple[str, ...], root: str):
    """``configs/identify.yaml`` with ``method=<config_name>`` and ``overrides``, composed by Hydra."""
    backup = get_gh_backup()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(Path(root) / "configs"), version_base="1.3"):
            return compose(config_name="identify", overrides=[f"method={config_name}", *overrides])
    finally:
        restore_gh_from_backup(backup)


def _module_file(module: str, root: Path) -> Path | None:
    base = root.joinpath(*module.split("."))
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _imports(path: Path, package: str) -> set[str]:
    """Modules imported by the file ``path`` (absolute names; relative imports resolved in ``package``)."""
    stat = path.stat()
    names = set()
    for level, module, aliases in _import_statements(str(path), stat.st_mtime_ns, stat.st_size):
        if level is None:                                      # import a, b
            names.update(aliases)
            continue
        if level:
            parts = package.split(".")[: len(package.split(".")) - level + 1]
            base = ".".join(parts + ([module] if module else []))
        else:
            base = module or ""
        names.add(base)
        names.update(f"{base}.{a}" for a in aliases)   # `from methods import fft` imports a module
    return names


@functools.lru_cache(maxsize=256)
def _import_statements(path: str, _mtime_ns: int, _size: int) -> tuple:
    """The file's import statements as (level or None for ``import``, module, names), parsed once per
    version of the file (a job's code digest and package versions both read them)."""
    try:
        tree = ast.parse(Path(path).read_text(), filename=path)
    except SyntaxError:
        return ()               # the job itself will report it; the file is an input all the same
    out = []
    todo = [tree]
    while todo:                 # statements only (an import is one): ast.walk's every expression cost 2×
        node = todo.pop()
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            todo += [child for child in getattr(node, field, ()) if isinstance(child, ast.AST)]
        if isinstance(node, ast.Import):
            out.append((None, None, tuple(a.name for a in node.names)))
        elif isinstance(node, ast.ImportFrom):
            out.append((node.level, node.module, tuple(a.name for a in node.names)))
    return tuple(out)


@functools.cache
def method_code_files(config_name: str, root: str = str(ROOT)) -> tuple[str, ...]:
    """The source files a method's result depends on: its module and, transitively, every module of the
    ``methods`` package it imports. The package's ``__init__`` (the name registry) is left out: it maps names
    to modules and holds no numerics, so registering another method reruns nothing.

    Python's ``modulefinder`` would follow every import into numpy and scipy (seconds per method); only the
    ``methods`` package matters here, so its ``import`` statements are read with ``ast``.
    """
    root_path = Path(root)
    name = method_of_config(config_name)
    if name is None:
        raise ValueError(f"method config '{config_name}' names no registered method; known: "
                         f"{', '.join(methods.names())}")
    todo, seen = [methods.module_name(name)], {}
    while todo:
        module = todo.pop()
        path = _module_file(module, root_path)
        if path is None or module in seen:
            continue
        seen[module] = path
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        todo += [m for m in _imports(path, package) if m.split(".")[0] == "methods" and m != "methods"]
    files = [p for m, p in seen.items() if m != "methods"]
    return tuple(sorted(str(p.relative_to(root_path)) for p in files))


@functools.cache
def _distributions() -> dict[str, list[str]]:
    return packages_distributions()


@functools.cache
def package_versions(config_name: str, root: str = str(ROOT)) -> str:
    """Canonical JSON {distribution: version} of the third-party packages the method's code imports
    (and Python's own version): an upgrade of one of them reruns the method's jobs."""
    tops = set()
    for rel in method_code_files(config_name, root):
        tops.update(m.split(".")[0] for m in _imports(Path(root) / rel, "methods"))
    out = {"python": ".".join(map(str, sys.version_info[:3]))}
    for top in sorted(tops - {"methods", "__future__"} - set(sys.stdlib_module_names)):
        try:
            out[top] = version(top)           # the usual case: the distribution is named like the module
        except PackageNotFoundError:
            for dist in _distributions().get(top, [top]):
                try:
                    out[dist] = version(dist)
                except PackageNotFoundError:
                    out[dist] = "not installed"
    return canonical_json(out)


def code_digest(config_name: str, root: str = str(ROOT)) -> str:
    """A digest of the method's source files (their bytes, in name order)."""
    h = hashlib.sha256()
    for rel in method_code_files(config_name, root):
        h.update(rel.encode() + b"\0" + (Path(root) / rel).read_bytes() + b"\0")
    return h.hexdigest()[:16]


def file_digest(path) -> str:
    """SHA-256 of a file's bytes (a user's CSV; a dataset cell is digested by its arrays, see io.read_npz)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def git_state(root: str = str(ROOT)) -> dict:
    """The code version: ``commit`` (``unknown`` outside a git checkout), ``dirty`` (tracked files modified)
    and ``diff`` (a digest of the uncommitted changes, so two different dirty trees are told apart)."""
    def git(*args):
        return subprocess.run(["git", *args], cwd=root, capture_output=True, check=True).stdout

    try:
        commit = git("rev-parse", "HEAD").decode().strip()
        diff = git("diff", "HEAD", "--no-ext-diff", "--binary")
    except (OSError, subprocess.CalledProcessError):
        return {"commit": "unknown", "dirty": False, "diff": ""}
    return {"commit": commit, "dirty": bool(diff), "diff": digest(diff) if diff else ""}
