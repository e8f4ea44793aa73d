"""Scenario axes: a cell's truth and CRLB follow its axis values; names are deterministic; bad cells refused.

Physics checked: more modal damping raises −Re λ/|λ| of the generating model and shortens the signal, so the
frequency bound grows; the gap axis moves mode 3 (and only it) and a smaller gap raises the bound of the
close pair; a longer sample interval moves Nyquist (π/Δt) and, at equal N, lengthens the record (smaller
bound); a weaker excitation of a mode raises its bound in proportion (σ_ω ∝ 1/a for one mode).
"""

import numpy as np
import pytest

from experiments.simulate import scenarios
from experiments.simulate.datasets import DatasetConfig, ScenarioConfig, make_cell
from experiments.simulate.plant import PlantConfig


def cell(**scenario):
    dt = scenario.pop("dt_s", 0.02)
    axes = ["dt_s"] if dt != 0.02 else []
    return make_cell(DatasetConfig(noise_ug=1000.0, n_samples=256, replicates=3, seed=5, dt_s=dt,
                                   scenario=ScenarioConfig(axes=axes, **scenario)))


@pytest.fixture(scope="module")
def base():
    return cell()


def test_damping_raises_the_true_damping_and_the_bound(base):
    damped = cell(damping=0.02)
    assert np.all(damped["truth_damping"] > 3 * base["truth_damping"])
    np.testing.assert_allclose(damped["truth_damping"], 0.02, rtol=0.05)   # coupling shifts ζ a little
    np.testing.assert_allclose(damped["truth_freq_rad_s"], base["truth_freq_rad_s"], rtol=1e-9)
    assert np.all(damped["crlb_std_rad_s"] > base["crlb_std_rad_s"])
    per_mode = cell(damping=[0.005, 0.005, 0.005, 0.03])
    assert per_mode["truth_damping"][3] > 5 * per_mode["truth_damping"][0]


def test_gap_moves_mode_3_only_and_a_close_pair_is_harder(base):
    close = cell(gap_rad_s=0.3)
    w = close["truth_freq_rad_s"]
    assert w[2] == pytest.approx(w[1] + 0.3, abs=1e-9)
    np.testing.assert_allclose(w[[0, 1, 3]], base["truth_freq_rad_s"][[0, 1, 3]], rtol=1e-9)
    assert np.all(close["crlb_std_rad_s"][1:3] > 10 * base["crlb_std_rad_s"][1:3])


def test_dt_moves_nyquist_and_the_bound(base):
    slow = cell(dt_s=0.04)                       # Nyquist 78.5 rad/s > 56.67: allowed
    # 10.24 s instead of 5.12 s: modes 1-3 still ring after 5 s (mode 4 has decayed: ζω = 0.28/s, no gain)
    assert np.all(slow["crlb_std_rad_s"][:3] < 0.7 * base["crlb_std_rad_s"][:3])
    with pytest.raises(ValueError, match="dt_s = 0.06 s puts Nyquist at 52.36 rad/s"):
        cell(dt_s=0.06)
    with pytest.raises(ValueError, match="at or above Nyquist"):
        scenarios.check_cell({"prior_scale": 1.4}, PlantConfig(), 0.04)   # 1.4 × 56.67 > 78.5


def test_weak_excitation_raises_that_modes_bound(base):
    weak = cell(excitation=[1, 1, 0.1, 1])
    ratio = weak["crlb_std_rad_s"] / base["crlb_std_rad_s"]
    assert ratio[2] == pytest.approx(10, rel=0.2)
    # the body couples the beam coordinates, so mode 3 of the tip signal is not q3 alone: about, not exactly, 0.1
    assert weak["truth_amplitude_m_s2"][2] == pytest.approx(0.1 * base["truth_amplitude_m_s2"][2], rel=0.3)


def test_harness_prior_follows_its_axes_and_never_enters_a_plain_cell(base):
    assert "prior_rad_s" not in base and "scenario_json" not in base
    c = cell(prior_scale=0.8)
    np.testing.assert_allclose(c["prior_rad_s"], np.tile(0.8 * c["truth_freq_rad_s"], (3, 1)))
    w = base["truth_freq_rad_s"]
    s1, s2 = cell(prior_spread=0.1)["prior_rad_s"], cell(prior_spread=0.2)["prior_rad_s"]
    u = scenarios.prior_draws(5, 3, 4)           # the documented draw: the same u for every spread
    np.testing.assert_allclose(s1, np.sort(w * (1 + 0.1 * u), axis=1))
    np.testing.assert_allclose(s2, np.sort(w * (1 + 0.2 * u), axis=1))
    assert np.all(np.diff(s2, axis=1) > 0)       # sorted: slot i is the i-th mode
    more = scenarios.harness_prior(base["truth_freq_rad_s"], {"prior_spread": 0.2}, 5, 10)
    np.testing.assert_array_equal(more[:3], s2)  # R = 3 is a prefix of R = 10


def test_prior_cells_store_the_spread_their_priors_were_drawn_with(base):
    assert "prior_std_rad_s" not in base
    w = base["truth_freq_rad_s"]
    np.testing.assert_allclose(cell(prior_scale=0.8)["prior_std_rad_s"], 0.0)      # a bias, not a spread
    c = cell(prior_spread=0.2, prior_scale=1.1)
    np.testing.assert_allclose(c["prior_std_rad_s"], 1.1 * w * 0.2 / np.sqrt(3))
    # against the draws themselves: U(−1, 1) over many replicates has std 1/√3
    many = scenarios.harness_prior(w, {"prior_spread": 0.2}, 5, 4000)
    unsorted = w * (1 + 0.2 * scenarios.prior_draws(5, 4000, 4))
    np.testing.assert_allclose(unsorted.std(axis=0), scenarios.prior_std(w, {"prior_spread": 0.2}), rtol=0.05)
    assert many.shape == (4000, 4)


def test_cell_names_are_deterministic_and_plain_cells_keep_their_names():
    assert scenarios.cell_name(1000.0, 256) == "noise1000ug_n256"
    assert scenarios.cell_name(0.1, 20, {}) == "noise0.1ug_n20"
    name = scenarios.cell_name(1000, 256, {"gap_rad_s": 0.3, "prior_scale": 0.8, "damping": [0.001, 0.02]})
    assert name == "noise1000ug_n256_ps0.8_z0.001-0.02_gap0.3"
    grid = {"noise_ug": [10, 1000], "n_samples": [256],
            "scenarios": [{"prior_scale": [0.8, 1.2], "gap_rad_s": [1.0]}, {"damping": [0.01]}, {}]}
    first = scenarios.grid_cells(grid)
    assert list(first) == list(scenarios.grid_cells(grid))
    assert len(first) == 2 * 2 + 2 + 2 and "noise10ug_n256" in first
    assert first["noise1000ug_n256_ps1.2_gap1"]["axes"] == {"prior_scale": 1.2, "gap_rad_s": 1.0}
    assert list(scenarios.grid_cells({"noise_ug": [1], "n_samples": [64]})) == ["noise1ug_n64"]


def test_bad_axis_values_are_refused_naming_the_cell():
    grid = {"name": "g", "noise_ug": [1000], "n_samples": [256], "scenarios": [{"gap_rad_s": [1, 40]}]}
    with pytest.raises(ValueError, match=r"cell noise1000ug_n256_gap40: gap_rad_s = 40 puts mode 3 at 60.24"):
        scenarios.check_grid(grid, PlantConfig())
    with pytest.raises(ValueError, match="damping = \\[0.01, 0.02\\] has 2 entries"):
        scenarios.check_cell({"damping": [0.01, 0.02]}, PlantConfig(), 0.02)
