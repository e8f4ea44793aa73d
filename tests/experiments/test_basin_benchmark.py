"""The basin benchmark's random structures obey the documented rules, and it refuses the scoring seed."""

import numpy as np
import pytest

from experiments.benchmarks import basin
from experiments.report.scoring import identifiable


@pytest.mark.parametrize("k", range(12))
def test_structures_are_other_than_the_papers_and_identifiable(k):
    s = basin.draw_structure(7, k, 512, 0.01)
    w = s["freq"]
    assert 2 <= w.size <= 5
    assert np.all((w >= 1.5) & (w <= 80)) and np.all(w[1:] / w[:-1] >= 1.08)
    assert np.all((s["zeta"] >= 0.002) & (s["zeta"] <= 0.03))
    assert (s["offset"] != 0) == bool(k % 2)
    assert np.all(identifiable(w, s["crlb"]))
    assert basin.draw_structure(7, k, 512, 0.01)["freq"].tolist() == w.tolist()   # seeded


def test_trials_give_sorted_priors_within_the_stated_errors():
    s = basin.draw_structure(7, 3, 512, 0.01)
    for kind, value, prior, i in basin.trials(s, [0.7, 1.3], 0.25, 3, 7):
        assert np.all(np.diff(prior) > 0)
        if kind == "common":
            np.testing.assert_allclose(prior, value * s["freq"])
        else:        # the documented draw: u ~ U(-1, 1) from default_rng([seed, 0x4241, k, 1000 + d])
            u = np.random.default_rng([7, 0x4241, 3, 1000 + i - 2]).uniform(-1, 1, s["freq"].size)
            assert np.all(np.abs(u) <= 1)
            np.testing.assert_allclose(prior, np.sort(s["freq"] * (1 + 0.25 * u)))


def test_scoring_seed_is_refused(capsys):
    assert basin.main(["--seed", "20261121", "--structures", "1"]) == 2
    assert capsys.readouterr().err.startswith("error: --seed 20261121 is the grids' scoring seed")


def test_label_outcome_tells_a_crossed_label_from_an_inaccurate_mode_and_an_honest_gap():
    s = {"freq": np.array([5.0, 10.0, 20.0]), "crlb": np.full(3, 1e-4)}
    assert basin.label_outcome(s, [5.0, 10.0, 20.0], [True] * 3) == (False, False, False)
    assert basin.label_outcome(s, [10.0, 5.0, 20.0], [True] * 3) == (True, False, True)      # swapped
    assert basin.label_outcome(s, [5.0, 10.0, 23.0], [True] * 3) == (True, False, False)     # inaccurate
    assert basin.label_outcome(s, [5.0, np.nan, 23.0], [True, False, False]) == (False, True, False)


def test_independent_errors_with_a_least_error_stay_within_it_and_the_spread():
    """--spread-min 0.15 --spread 0.25: every prior frequency is 15–25 % off (before sorting: the draw of each
    mode's error, its sign u's), and spread_min = 0 gives the ±spread·u draw unchanged."""
    s = basin.draw_structure(7, 3, 512, 0.01)
    for (_, _, prior, i), (_, _, plain, _) in zip(basin.trials(s, [], 0.25, 4, 7, 0.15),
                                                  basin.trials(s, [], 0.25, 4, 7), strict=True):
        u = np.random.default_rng([7, 0x4241, 3, 1000 + i]).uniform(-1, 1, s["freq"].size)
        error = np.sign(u) * (0.15 + 0.10 * np.abs(u))
        assert np.all((np.abs(error) >= 0.15) & (np.abs(error) <= 0.25))
        np.testing.assert_allclose(prior, np.sort(s["freq"] * (1 + error)))
        np.testing.assert_allclose(plain, np.sort(s["freq"] * (1 + 0.25 * u)))


def test_a_least_error_above_the_spread_is_refused(capsys):
    assert basin.main(["--spread", "0.2", "--spread-min", "0.3", "--structures", "1"]) == 2
    assert "--spread-min" in capsys.readouterr().err
