"""What a job's result depends on, for Snakemake's rerun triggers: the method's code files (inputs), its
resolved config and the versions of the packages it imports (params). Computed by :mod:`experiments.provenance`
(which the MLflow run key uses too); a plugin method without a config is named by its overrides."""

from __future__ import annotations

from pathlib import Path

from experiments import provenance

__all__ = ["method_code", "resolved_config", "method_versions"]


def method_code(root, config: str) -> list[str]:
    return [str(Path(root) / f) for f in provenance.method_code_files(config, str(root))]


def resolved_config(root, config: str, overrides: tuple[str, ...] = ()) -> str:
    if not (Path(root) / "configs" / "method" / f"{config}.yaml").exists():
        return provenance.canonical_json({"plugin": config, "overrides": overrides})
    return provenance.resolved_method_config(config, tuple(overrides), str(root))


def method_versions(root, config: str) -> str:
    return provenance.package_versions(config, str(root))
