"""What keys and describes a job's MLflow run, without pandas or MLflow: the run key, the flat parameters and
the resolved config as YAML (a measurement job builds its run here and leaves the logging to
:mod:`experiments.runlog.pending`; :mod:`experiments.runlog.identify_runs` logs a grid's jobs with them)."""

from __future__ import annotations

import yaml

from experiments.provenance import canonical_json, digest

__all__ = ["IDENTIFY_SOURCE", "run_key", "job_params", "config_yaml"]

IDENTIFY_SOURCE = "experiments/jobs/identify.py"


def run_key(record: dict) -> str:
    """``<grid>/<method>/<cell>/<digest>`` over what determines the result: the dataset's content, the
    resolved method config, prior and replicates, the code version (commit, dirty diff, method files) and
    the package versions; never a path or a time."""
    cfg = record["config"]
    keyed = {"method": cfg["method"], "prior": cfg.get("prior"), "replicates": cfg["data"].get("replicates"),
             "dataset": record["dataset"]["digest"], "code": record["code"], "versions": record["versions"]}
    return f"{record['grid']}/{record['method']}/{record['dataset']['name']}/{digest(canonical_json(keyed))}"


def job_params(record: dict, table=None) -> dict:
    """Flat MLflow parameters of a job: the method's resolved options, the prior, the cell's settings (and,
    given its results table, a pandas DataFrame, the number of replicates)."""
    cfg = record["config"]
    params = {"method": record["method"], "method_config": record["method_config"],
              "prior_rad_s": cfg.get("prior") or cfg["method"].get("prior_rad_s"),
              "dataset": record["dataset"]["name"], "dataset_digest": record["dataset"]["digest"],
              "git_commit": record["code"]["commit"], "git_dirty": record["code"]["dirty"]}
    params.update(record["dataset"].get("settings", {}))
    if table is not None:
        params["replicates"] = int(table["replicate"].nunique())
    params.update({f"option.{k}": v for k, v in (cfg["method"].get("options") or {}).items()})
    return params


def config_yaml(record: dict) -> str:
    """The resolved config (plain JSON values) as YAML: PyYAML's C dumper with the options of
    ``OmegaConf.to_yaml`` (the same text on every job of the paper grid, 15x faster: OmegaConf's node
    tree took 8 % of a grid's MLflow logging)."""
    return yaml.dump(record["config"], Dumper=_DUMPER, default_flow_style=False, allow_unicode=True, sort_keys=False)


_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)     # the pure-Python one where libyaml is absent
