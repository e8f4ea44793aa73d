"""One word, one meaning: "track" names frequency tracking, "runlog" names MLflow run logging.

Read from the source (``ast`` for the modules, the rule blocks of the ``.smk`` files, the structured configs and
the YAML files), each rule able to fail (the second half of this file breaks each one on purpose):

- modules: only the runlog stage (``experiments/runlog/``) imports MLflow; a module whose name says "track"
  (and not "runlog") reaches neither MLflow nor the runlog stage, directly or through other modules; a
  runlog module does not import the trackers (``methods.tracking``, ``methods.track``).
- rules: a rule that runs ``experiments.runlog`` is named for it ("runlog" in its name); a rule whose name
  says "track" and not "runlog" does not run it; a runlog rule runs no tracker job.
- config keys: the MLflow switch (:class:`experiments.config_schema.RunlogConfig`) sits under a key named
  ``runlog``, and no key that says "track" holds it, in the structured configs and in ``configs/**/*.yaml``.

A name that says both ("tracker_runs" under ``runlog/``, the rule ``tracking_runlog``) is run logging *of*
frequency tracking: the word "runlog" says what it does, "track" what it logs.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest
import yaml
from test_import_order import import_graph, imported_modules, module_name, source_files

import experiments.config_schema as config_schema

ROOT = Path(__file__).resolve().parents[1]
TRACKERS = ("methods.tracking", "methods.track")


def says_track(name: str) -> bool:
    return "track" in name.lower() and "runlog" not in name.lower()


def says_runlog(name: str) -> bool:
    return "runlog" in name.lower()


# ---- modules ------------------------------------------------------------------------------------------------


def module_violations(paths) -> list[str]:
    graph = import_graph(paths)
    by_name = {module_name(p): p for p in paths}
    mlflow_users = {m for m, p in by_name.items() if any(t.split(".")[0] == "mlflow" for _, t in imported_modules(p))}
    found = []
    for module, path in sorted(by_name.items()):
        if module in mlflow_users and not says_runlog(module):
            found.append(f"{module} imports mlflow outside the runlog stage (experiments/runlog/)")
        if says_track(module):
            seen, todo = set(), [module]
            while todo:
                for nxt in graph.get(todo.pop(), ()):
                    if nxt not in seen:
                        seen.add(nxt)
                        todo.append(nxt)
            reached = sorted(m for m in seen if says_runlog(m) or m in mlflow_users)
            if reached:
                found.append(f"{module} says track but reaches MLflow run logging ({', '.join(reached)})")
        if says_runlog(module):
            trackers = sorted({t for _, t in imported_modules(path) if t.startswith(TRACKERS)})
            if trackers:
                found.append(f"{module} says runlog but imports the trackers ({', '.join(trackers)})")
    return found


def test_modules_named_for_one_meaning_are_not_about_the_other():
    assert module_violations(source_files("methods", "experiments")) == []


# ---- rules --------------------------------------------------------------------------------------------------

RULE = re.compile(r"^rule\s+(\w+)\s*:", re.M)


def rule_blocks(text: str) -> dict[str, str]:
    """name -> the text of its block (up to the next top-level statement)."""
    out = {}
    for match in RULE.finditer(text):
        rest = text[match.end():]
        end = re.search(r"^\S", rest, re.M)
        out[match.group(1)] = rest[: end.start() if end else len(rest)]
    return out


def rule_violations(text: str) -> list[str]:
    found = []
    for name, block in rule_blocks(text).items():
        runs_runlog = "experiments.runlog" in block
        if runs_runlog and not says_runlog(name):
            found.append(f"rule {name} runs MLflow run logging but is not named for it (runlog)")
        if says_track(name) and runs_runlog:
            found.append(f"rule {name} says track but runs MLflow run logging")
        if says_runlog(name) and "experiments.jobs.track_job" in block:
            found.append(f"rule {name} says runlog but runs a tracker")
    return found


def workflow_text() -> str:
    files = [ROOT / "Snakefile", *sorted((ROOT / "experiments" / "workflow" / "rules").glob("*.smk"))]
    return "\n".join(f.read_text() for f in files)


def test_rules_named_for_one_meaning_are_not_about_the_other():
    text = workflow_text()
    assert {"runlog", "tracking_runlog", "tracking"} <= set(rule_blocks(text))     # the check sees the rules
    assert rule_violations(text) == []


# ---- config keys --------------------------------------------------------------------------------------------

RUNLOG_FIELDS = {f.name for f in dataclasses.fields(config_schema.RunlogConfig)}


def config_violations(classes) -> list[str]:
    found = []

    def walk(cls, where):
        for f in dataclasses.fields(cls):
            key = f"{where}.{f.name}" if where else f.name
            default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
            is_runlog = isinstance(default, config_schema.RunlogConfig) or f.type in ("RunlogConfig",
                                                                                      config_schema.RunlogConfig)
            if is_runlog and f.name != "runlog":
                found.append(f"{cls.__name__}: key {key} holds the MLflow switch but is not named runlog")
            if says_track(f.name) and is_runlog:
                found.append(f"{cls.__name__}: key {key} says track but is the MLflow switch")
            if dataclasses.is_dataclass(default) and not is_runlog:
                walk(type(default), key)

    for cls in classes:
        walk(cls, "")
    return found


def yaml_violations(text: str, where: str) -> list[str]:
    found = []

    def walk(node, path):
        if isinstance(node, dict):
            for key, value in node.items():
                if says_track(str(key)) and isinstance(value, dict) and RUNLOG_FIELDS & set(value):
                    found.append(f"{where}: key {path + str(key)} says track but holds MLflow run logging's "
                                 f"{sorted(RUNLOG_FIELDS & set(value))}")
                walk(value, f"{path}{key}.")
        elif isinstance(node, list):
            for item in node:
                walk(item, path)

    walk(yaml.safe_load(text), "")
    return found


def structured_configs() -> list[type]:
    from experiments.tuning.tune import TuneApp

    return [config_schema.IdentifyConfig, config_schema.ReproduceConfig, TuneApp]


def test_config_keys_named_for_one_meaning_are_not_about_the_other():
    classes = structured_configs()
    assert all(any(f.name == "runlog" for f in dataclasses.fields(c)) for c in classes)  # the check sees the key
    found = config_violations(classes)
    for path in sorted((ROOT / "configs").rglob("*.yaml")):
        found += yaml_violations(path.read_text(), str(path.relative_to(ROOT)))
    assert found == []


# ---- each check fails on a breach ---------------------------------------------------------------------------


@pytest.mark.parametrize("files, expected", [
    ({"experiments/jobs/track_x.py": "def f():\n    import mlflow\n"}, "imports mlflow outside the runlog stage"),
    ({"experiments/jobs/track_x.py": "from experiments.jobs import helper\n",
      "experiments/jobs/helper.py": "from experiments.runlog import store\n",
      "experiments/runlog/store.py": "import mlflow\n"}, "says track but reaches MLflow run logging"),
    ({"experiments/runlog/logger.py": "from methods.tracking import _pll\n"}, "says runlog but imports the trackers"),
    ({"experiments/runlog/logger.py": "from methods import track\n"}, "says runlog but imports the trackers"),
])
def test_the_module_check_fails_on_a_breach(files, expected, monkeypatch, tmp_path):
    import test_import_order

    for where, source in files.items():
        (tmp_path / where).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / where).write_text(source)
    monkeypatch.setattr(test_import_order, "ROOT", tmp_path)
    found = module_violations(sorted(tmp_path / w for w in files))
    assert len(found) == 1 and expected in found[0], found


@pytest.mark.parametrize("text, expected", [
    ('rule track:\n    shell:\n        "python -m experiments.runlog.identify_runs --grid x"\n', "says track"),
    ('rule tracking_mlflow:\n    shell:\n        "python -m experiments.runlog.tracker_runs"\n', "says track"),
    ('rule log:\n    shell:\n        "python -m experiments.runlog.identify_runs"\n', "is not named for it"),
    ('rule runlog_x:\n    shell:\n        "python -m experiments.jobs.track_job run x"\n', "runs a tracker"),
])
def test_the_rule_check_fails_on_a_breach(text, expected):
    assert any(expected in v for v in rule_violations(text)), rule_violations(text)


def test_the_config_check_fails_on_a_breach():
    @dataclasses.dataclass
    class Old:
        tracking: config_schema.RunlogConfig = dataclasses.field(default_factory=config_schema.RunlogConfig)

    found = config_violations([Old])
    assert any("says track but is the MLflow switch" in v for v in found), found
    assert yaml_violations("defaults: [x]\ntracking:\n  enabled: false\n", "x.yaml")
    assert not yaml_violations("runlog:\n  enabled: false\ntracker: akf\n", "x.yaml")
