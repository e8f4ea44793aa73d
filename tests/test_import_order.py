"""The layering, read from the source with ``ast`` (every import, at module level and inside functions).

In the spirit of scikit-learn's import-consistency checks: the walls of the house are tested, not hoped for.

- ``experiments/`` stages import one way: io, paths, provenance (and the other modules at the top of
  ``experiments/``) -> recordings / simulate (data read, data made) -> report -> runlog (MLflow run logging)
  -> hydra_app (what every Hydra app runs before its task) -> jobs -> workflow (the Snakemake rules' Python)
  / tuning / benchmarks / paper. A stage imports only its own modules and earlier stages'; stages of one rank
  do not import each other.
- No module imports itself through others: the graph of imports among the project's modules (module level
  and inside functions) has no cycle.
- An import inside a function says why, in a comment on its line, or above it or above its group of imports.
- ``methods/`` imports nothing from ``experiments/`` and never Hydra, OmegaConf, MLflow or Snakemake.
- Outside a method family package (``methods/<family>/``), nothing imports the family's private
  (underscore) modules: the family's ``__init__`` is its face. Tests are exempt: they test the insides.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# rank of each stage; modules directly under experiments/ (io.py, config_schema.py) are the ground floor
STAGE_RANK = {"": 0, "recordings": 1, "simulate": 1, "report": 2, "runlog": 3, "hydra_app": 4, "jobs": 5,
              "workflow": 6, "tuning": 6, "benchmarks": 6, "paper": 6}
FORBIDDEN_IN_METHODS = ("experiments", "hydra", "omegaconf", "mlflow", "snakemake")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path``; ``from a import b`` yields ``a`` and
    ``a.b`` (``b`` may be a module), relative imports resolved against the file's package."""
    module = module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base_parts = parts[: len(parts) - node.level + 1]
                base = ".".join(base_parts + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            out.append((node.lineno, base))
            out += [(node.lineno, f"{base}.{a.name}") for a in node.names if a.name != "*"]
    return out


def stage_of(module: str) -> str | None:
    """The stage of an ``experiments`` module: its sub-package, or "" for the modules at the top."""
    parts = module.split(".")
    if parts[0] != "experiments":
        return None
    return parts[1] if len(parts) > 1 and parts[1] in STAGE_RANK else ""


def family_private(module: str) -> str | None:
    """The family of ``methods.<family>._private...``, else None."""
    parts = module.split(".")
    if len(parts) >= 3 and parts[0] == "methods" and parts[2].startswith("_") and not parts[2].startswith("__"):
        return parts[1]
    return None


def violations(paths, *, is_test=False) -> list[str]:
    """One line per import statement and broken rule."""
    found = {}
    for path in paths:
        here = module_name(path)
        here_stage = stage_of(here)
        for line, target in imported_modules(path):
            where = f"{path.relative_to(ROOT)}:{line} imports {target}"
            there_stage = stage_of(target)
            if here_stage is not None and there_stage is not None and here_stage != there_stage:
                if STAGE_RANK[there_stage] >= STAGE_RANK[here_stage]:
                    found.setdefault((path, line, "stage"),
                                     f"{where}: stage {here_stage or 'top'} may not import stage {there_stage}")
            if here.split(".")[0] == "methods" and target.split(".")[0] in FORBIDDEN_IN_METHODS:
                found.setdefault((path, line, "methods"), f"{where}: methods/ is pure numerics")
            family = family_private(target)
            if family and not is_test and not here.startswith(f"methods.{family}"):
                found.setdefault((path, line, "private"),
                                 f"{where}: a private module of methods/{family}/ (use the family's face)")
    return list(found.values())


def source_files(*tops: str) -> list[Path]:
    return sorted(p for top in tops for p in (ROOT / top).rglob("*.py") if "__pycache__" not in p.parts)


def test_the_code_keeps_its_walls():
    assert violations(source_files("methods", "experiments")) == []


def test_every_stage_folder_has_a_rank():
    """A new stage folder must be placed in the order before it can import or be imported."""
    folders = {p.name for p in (ROOT / "experiments").iterdir()
               if p.is_dir() and (p / "__init__.py").exists() and not p.is_symlink()}
    assert folders <= set(STAGE_RANK)


def test_tests_may_reach_inside_a_family():
    """Tests are exempt from the private-module rule only (a test of jobs/ may import tuning/ fixtures)."""
    assert not [v for v in violations(source_files("tests"), is_test=True) if "private" in v]


def jobs_folder_strays(paths) -> list[str]:
    """What in ``experiments/jobs/`` is not a job: a public module that a user cannot run (no ``main`` and no
    ``if __name__ == "__main__"``), or a private ``_module`` that is not used by exactly one job of the folder
    (a helper of several jobs belongs to the stage that names what it is)."""
    jobs = [p for p in paths if p.parent.name == "jobs" and p.parent.parent.name == "experiments"]
    found = []
    for path in jobs:
        if path.name == "__init__.py":
            continue
        text = path.read_text()
        if not path.name.startswith("_"):
            tree = ast.parse(text)
            runnable = any(isinstance(n, ast.FunctionDef) and n.name == "main" for n in tree.body) or \
                '__name__ == "__main__"' in text
            if not runnable:
                found.append(f"{path.relative_to(ROOT)} is not a job a user runs (no main)")
            continue
        users = [other for other in jobs if other != path and
                 any(t.split(".")[-1] == path.stem for _, t in imported_modules(other))]
        if len(users) != 1:
            found.append(f"{path.relative_to(ROOT)} is private but used by {len(users)} jobs")
    return found


def test_the_jobs_folder_holds_only_jobs():
    assert jobs_folder_strays(source_files("experiments")) == []


@pytest.mark.parametrize("files, expected", [
    ({"experiments/jobs/app.py": "def run_app():\n    pass\n"}, "is not a job a user runs"),
    ({"experiments/jobs/_flow.py": "X = 1\n",
      "experiments/jobs/a.py": "from experiments.jobs import _flow\ndef main(): pass\n",
      "experiments/jobs/b.py": "from experiments.jobs._flow import X\ndef main(): pass\n"}, "used by 2 jobs"),
    ({"experiments/jobs/_flow.py": "X = 1\n", "experiments/jobs/a.py": "def main(): pass\n"}, "used by 0 jobs"),
])
def test_the_jobs_check_sees_a_stray(files, expected, monkeypatch, tmp_path):
    for where, source in files.items():
        (tmp_path / where).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / where).write_text(source)
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    found = jobs_folder_strays(sorted(tmp_path / w for w in files))
    assert len(found) == 1 and expected in found[0], found


@pytest.mark.parametrize("source, where, expected", [
    ("from experiments.jobs import config\n", "experiments/runlog/x.py", "may not import stage jobs"),
    ("def f():\n    from experiments.tuning.objective import objective\n", "experiments/jobs/x.py",
     "may not import stage tuning"),
    ("from ..jobs import config\n", "experiments/report/x.py", "may not import stage jobs"),
    ("from experiments.paper import table5\n", "experiments/benchmarks/x.py", "may not import stage paper"),
    ("def f():\n    import hydra\n", "methods/pem/x.py", "pure numerics"),
    ("from experiments.io import read_npz\n", "methods/fft.py", "pure numerics"),
    ("from methods.kalman import _filter\n", "experiments/benchmarks/x.py", "private module of methods/kalman/"),
    ("from methods.pem._fit import fit\n", "methods/peers/x.py", "private module of methods/pem/"),
])
def test_the_check_sees_each_kind_of_breach(source, where, expected, monkeypatch, tmp_path):
    """Each rule fires on a file that breaks it (module or function level, absolute or relative)."""
    fake_root = tmp_path
    path = fake_root / where
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(source)
    monkeypatch.setitem(globals(), "ROOT", fake_root)
    found = violations([path])
    assert len(found) == 1 and expected in found[0], found


@pytest.mark.parametrize("source, where", [
    ("from experiments.jobs import config\n", "experiments/tuning/x.py"),
    ("from experiments.io import read_npz\n", "experiments/simulate/x.py"),
    ("from methods.kalman._filter import prepare\n", "methods/kalman/x.py"),
    ("import methods\nfrom methods.kalman import akf\n", "experiments/jobs/x.py"),
])
def test_the_check_lets_the_allowed_imports_pass(source, where, monkeypatch, tmp_path):
    path = tmp_path / where
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(source)
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    assert violations([path]) == []


# ---- no cycles ----------------------------------------------------------------------------------------------


def import_graph(paths) -> dict[str, set[str]]:
    """module -> the project's modules it imports (module level and inside functions): ``import a.b`` is an
    edge to ``a.b``; ``from a import n`` to ``a.n`` when that is a module of the project, else to ``a`` (the
    module the name ``n`` comes from)."""
    modules = {module_name(p) for p in paths}
    graph = {}
    for path in paths:
        here = module_name(path)
        package = here if path.name == "__init__.py" else here.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                edges |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    parts = package.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                edges |= {f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names}
        graph[here] = {e for e in edges if e in modules} - {here}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected component of more than one module (Tarjan's algorithm, iterative), each
    sorted: the modules that import each other, directly or through others."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = [0]
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in graph:
                    continue
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


def test_no_two_modules_import_each_other():
    assert cycles(import_graph(source_files("methods", "experiments"))) == []


@pytest.mark.parametrize("files, expected", [
    ({"experiments/a.py": "from experiments import b\n", "experiments/b.py": "def f():\n    import experiments.a\n"},
     [["experiments.a", "experiments.b"]]),
    ({"methods/x/_p.py": "from methods.x import _q\n", "methods/x/_q.py": "from methods.x import _r\n",
      "methods/x/_r.py": "def g():\n    from methods.x._p import f\n", "methods/x/__init__.py": ""},
     [["methods.x._p", "methods.x._q", "methods.x._r"]]),
    ({"methods/y/__init__.py": "from methods.y._a import f\n", "methods/y/_a.py": "from methods.y import _b\n",
      "methods/y/_b.py": "import numpy\n"}, []),
    ({"methods/z/__init__.py": "from methods.z._a import f\ndef h(): pass\n",
      "methods/z/_a.py": "def f():\n    from methods.z import h\n"}, [["methods.z", "methods.z._a"]]),
])
def test_the_cycle_check_sees_a_cycle_and_only_a_cycle(files, expected, monkeypatch, tmp_path):
    """A direct and an indirect cycle (through a function-level import) are found; a package that imports its
    submodule which imports a sibling is no cycle, one whose submodule takes a name from it is."""
    for where, source in files.items():
        (tmp_path / where).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / where).write_text(source)
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    paths = sorted(tmp_path / w for w in files)
    assert cycles(import_graph(paths)) == expected


# ---- an import inside a function says why -------------------------------------------------------------------


def unexplained_function_imports(paths) -> list[str]:
    """``file:line`` of each import inside a function with no comment on its line(s), on the line above, or
    above the run of import lines it belongs to."""
    found = []
    for path in paths:
        lines = path.read_text().splitlines()
        for fn in ast.walk(ast.parse("\n".join(lines), filename=str(path))):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if not isinstance(node, (ast.Import, ast.ImportFrom)):
                    continue
                own = lines[node.lineno - 1: node.end_lineno]
                k = node.lineno - 2
                while k >= 0 and lines[k].strip().startswith(("import ", "from ")) and "#" not in lines[k]:
                    k -= 1          # up the run of imports this one belongs to
                above = lines[k].strip() if k >= 0 else ""
                if not any("#" in ln for ln in own) and not above.startswith("#") and "#" not in above:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    return found


def test_every_import_inside_a_function_says_why():
    assert unexplained_function_imports(source_files("methods", "experiments")) == []


@pytest.mark.parametrize("source, bad", [
    ("def f():\n    import scipy\n", True),
    ("def f():\n    x = 1\n    import scipy\n", True),
    ("def f():\n    import scipy  # 0.3 s: one caller\n", False),
    ("def f():\n    # 0.3 s: one caller\n    import scipy\n    from scipy import linalg\n", False),
    ("import os\n\ndef f():\n    return os.sep\n", False),
])
def test_the_why_check_sees_a_bare_function_import(source, bad, monkeypatch, tmp_path):
    path = tmp_path / "experiments" / "x.py"
    path.parent.mkdir(parents=True)
    path.write_text(source)
    monkeypatch.setitem(globals(), "ROOT", tmp_path)
    assert bool(unexplained_function_imports([path])) is bad
