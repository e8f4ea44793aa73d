"""The face in code: every public module says what it exports (``__all__``), and the examples in the methods'
docstrings run (``doctest``), so a family's ``identify`` example cannot drift from the code."""

from __future__ import annotations

import ast
import doctest
import importlib
import pkgutil
from pathlib import Path

import pytest

import methods

ROOT = Path(__file__).resolve().parents[1]


def public_modules() -> list[Path]:
    """Modules of methods/ and experiments/ whose own name has no leading underscore (packages included)."""
    paths = [p for top in ("methods", "experiments") for p in (ROOT / top).rglob("*.py")
             if "configs" not in p.relative_to(ROOT).parts and "__pycache__" not in p.parts]
    return sorted(p for p in paths if p.name == "__init__.py" or not p.name.startswith("_"))


def bound_names(tree: ast.Module) -> set[str]:
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(t.id for t in targets if isinstance(t, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


@pytest.mark.parametrize("path", public_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_a_public_module_lists_its_face_and_every_name_in_it_exists(path):
    tree = ast.parse(path.read_text())
    declared = [node for node in tree.body if isinstance(node, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)]
    assert declared, f"{path.relative_to(ROOT)} has no __all__"
    listed = ast.literal_eval(declared[0].value)
    missing = set(listed) - bound_names(tree)
    assert not missing, f"{path.relative_to(ROOT)}: __all__ names {sorted(missing)}, not defined there"


METHOD_MODULES = ["methods"] + sorted(m.name for m in pkgutil.walk_packages(methods.__path__, "methods."))
NEEDS = {"methods.peers": "era"}     # a family whose example runs an optional library's method
WITH_EXAMPLES = {"methods.kalman", "methods.kalman.wkf", "methods.pem", "methods.pll", "methods.peers", "methods.fft"}


def test_the_methods_modules_are_all_found():
    assert {"methods.kalman", "methods.pem", "methods.pll", "methods.peers", "methods.fft"} <= set(METHOD_MODULES)


@pytest.mark.parametrize("name", METHOD_MODULES)
def test_the_examples_in_the_docstrings_run(name):
    """Every ``>>>`` example of methods/ (each family's face shows its ``identify`` at work) gives what it says."""
    needed = next((m for prefix, m in NEEDS.items() if name.startswith(prefix)), None)
    if needed:
        try:
            methods.require(needed)
        except ValueError as exc:
            pytest.skip(str(exc))
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS, verbose=False)
    assert result.failed == 0
    if name in WITH_EXAMPLES:
        assert result.attempted > 0, f"{name}: the face of a family shows identify at work"
