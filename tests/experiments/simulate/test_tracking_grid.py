"""The shipped tracking grids validate, and their cells are the product of their axes."""

import pytest
import yaml

from experiments.jobs.track_job import check_tracker, grid_trackers, tracker_cells
from experiments.paths import GRIDS
from experiments.simulate.tracking_grid import load_grid


@pytest.mark.parametrize("name, cells", [("tracking", 4 * 2 * 2 + 3 * 2), ("tracking_smoke", 2),
                                         ("tracking_full", 4 * 3 * 2)])
def test_shipped_grids_validate(name, cells):
    grid = load_grid(name, check_cells=(name != "tracking_full"))
    # the product of the axes, and one cell per laboratory entry
    assert len(grid["cells"]) == cells + len(grid.get("laboratory") or {})
    assert all(c["config"].replicates == grid["replicates"] for c in grid["cells"].values())


def test_the_default_grid_has_every_schedule_kind_and_the_paper_plant():
    grid = load_grid("tracking", check_cells=False)
    kinds = {k for s in grid["schedules"].values() for k in s}
    assert {"drift", "propellant_kg", "step", "slosh"} <= kinds
    cell = next(iter(grid["cells"].values()))["config"]
    assert cell.plant.target_freq_rad_s == [3.23, 20.24, 22.0, 56.67] and cell.plant.beam.youngs_modulus_pa == 70e9


def test_a_typo_in_a_schedule_key_names_the_key(tmp_path):
    grid = yaml.safe_load((GRIDS / "tracking_smoke.yaml").read_text())
    grid["schedules"]["step"]["step_tme_s"] = 3.0
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump(grid))
    with pytest.raises(ValueError, match="schedules.step: Additional properties are not allowed .'step_tme_s'"):
        load_grid(str(path))


def test_the_default_grid_has_the_ambient_classes_at_both_noise_levels():
    # white force only, white force with sparse pulses, and sloshing under both, at 100 and 1000 µg
    cells = load_grid("tracking", check_cells=False)["cells"].values()
    have = {(c["schedule"], c["excitation"], c["noise_ug"]) for c in cells}
    for sched in ("drift", "step", "slosh"):
        for exc in ("disturbance", "sparse"):
            assert {(sched, exc, 100.0), (sched, exc, 1000.0)} <= have
    sparse = next(c["config"].excitation for c in cells if c["excitation"] == "sparse")
    assert sparse.disturbance_force_n > 0 and sparse.thruster_torque_n_m > 0 and sparse.thruster_rate_hz < 0.2
    assert ("fuel", "sparse", 100.0) not in have


def test_an_exclude_that_names_no_excitation_of_the_grid_is_refused(tmp_path):
    grid = yaml.safe_load((GRIDS / "tracking_smoke.yaml").read_text())
    grid["exclude"] = [{"schedule": "step", "excitation": "thruster"}]
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump(grid))
    with pytest.raises(ValueError, match="exclude.0.excitation: 'thruster' names no excitation of this grid"):
        load_grid(str(path))
    grid["exclude"] = [{"schedule": "step", "excitation": "thrusters"}]
    path.write_text(yaml.safe_dump(grid))
    schedules = [c["schedule"] for c in load_grid(str(path))["cells"].values()]
    assert "step" not in schedules and "drift" in schedules   # the laboratory cells are not the product's


def test_an_exclude_with_a_tracker_leaves_only_that_tracker_out_of_the_cells_it_selects(tmp_path):
    grid = yaml.safe_load((GRIDS / "tracking_smoke.yaml").read_text())
    path = tmp_path / "g.yaml"
    grid["trackers"], grid["tracker_options"] = ["fft", "pll:tuned"], {}
    path.write_text(yaml.safe_dump(grid))
    loaded = load_grid(str(path))
    with pytest.raises(ValueError, match="pll option .* has 4 entries; the prior has 1"):
        check_tracker(loaded, "pll:tuned")          # per-mode tuned values on a one-mode laboratory cell

    grid["exclude"] = [{"tracker": "pll:tuned", "excitation": "laboratory"}]
    path.write_text(yaml.safe_dump(grid))
    loaded = load_grid(str(path))
    assert grid_trackers(loaded) == ["fft", "pll:tuned"]
    check_tracker(loaded, "pll:tuned")
    every, pll = tracker_cells(loaded, "fft"), tracker_cells(loaded, "pll:tuned")
    assert every == loaded["cells"] and set(pll) == {n for n, c in every.items() if c["excitation"] != "laboratory"}
    assert pll and len(pll) < len(every)

    for item, words in (({"tracker": "pll:tuned"}, "exclude.0: tracker 'pll:tuned' needs a schedule or"),
                        ({"tracker": "pll:tuned", "excitation": "lab"}, "exclude.0.excitation: 'lab' names no")):
        grid["exclude"] = [item]
        path.write_text(yaml.safe_dump(grid))
        with pytest.raises(ValueError, match=words):
            load_grid(str(path))
    grid["exclude"] = [{"tracker": "akf", "excitation": "laboratory"}]
    path.write_text(yaml.safe_dump(grid))
    with pytest.raises(ValueError, match="exclude: tracker 'akf' is not one of the grid's trackers"):
        grid_trackers(load_grid(str(path)))
