"""One home per default: a method's ``Options`` dataclass holds the defaults, its YAML config only what differs.

What a job runs is the composed config; these tests compose every method config with Hydra and compare its
options with the dataclass defaults overlaid by what the config files of its chain state, so a value taken
out of a YAML file falls back to the very ``Options`` default.
"""

from __future__ import annotations

import dataclasses

import pytest
from hydra import compose, initialize_config_module
from omegaconf import OmegaConf

import methods
from experiments.config_schema import METHOD_CONFIG_DIR, method_of_config, stated_options
from experiments.hydra_app.command_line import CONFIG_MODULE
from experiments.hydra_app.config_store import register

CONFIGS = sorted(p.stem for p in METHOD_CONFIG_DIR.glob("*.yaml"))


def installed(config: str) -> bool:
    try:
        methods.require(method_of_config(config))
    except ValueError:
        return False
    return True


def chain(config: str) -> list[str]:
    """The config and the variant parents it builds on, base first (akf_tuned -> [akf, akf_tuned])."""
    method = method_of_config(config)
    return [method, config] if config != method else [config]


@pytest.mark.parametrize("config", CONFIGS)
def test_a_composed_config_is_the_options_defaults_plus_what_its_files_state(config):
    if not installed(config):
        pytest.skip(f"{config}: optional library not installed")
    method = method_of_config(config)
    register(with_methods=[method])
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        cfg = compose(config_name="identify", overrides=[f"method={config}"])
    expected = dataclasses.asdict(methods.options_class(method)())
    for name in chain(config):
        expected.update(stated_options(name))
    assert OmegaConf.to_container(cfg.method.options) == expected


@pytest.mark.parametrize("config", [c for c in CONFIGS if method_of_config(c) == c])
def test_a_method_config_states_no_option_at_its_default(config):
    """Variants (``pem_paper``) may pin a default they depend on; a method's own config may not repeat one."""
    defaults = dataclasses.asdict(methods.options_class(config)())
    repeated = {k: v for k, v in stated_options(config).items() if defaults.get(k) == v}
    assert repeated == {}, f"configs/method/{config}.yaml repeats Options defaults: {repeated}"


def test_the_paper_setting_of_pem_has_one_home():
    """Table 5 runs the variant pem:paper's options, and those change what §4.3 says the paper did."""
    paper = stated_options("pem_paper")
    assert paper["predictor"] == "kalman" and paper["search"] == "gauss_newton" and paper["n_starts"] == 1
    assert (paper["kalman_qd"], paper["kalman_rd"]) == (0.001, 0.4)     # §4.3's LQE tuning
    assert stated_options("pem") == {}


def test_an_unknown_config_is_refused_with_its_name():
    with pytest.raises(ValueError, match="nosuch"):
        stated_options("nosuch")
