"""The Bayesian yardstick of a grid cell (experiments/simulate/yardstick.py) against independent numbers."""

import numpy as np
import pandas as pd
import pytest

from experiments.report.summary import YARDSTICK_COLUMNS, attach_yardstick
from experiments.simulate import bayes, yardstick
from experiments.simulate.crlb import crlb_std

T_S = np.arange(16) * 0.05
TRUTH, ZETA, AMP, PHASE = 5.0, 0.01, 1.0, 0.3
MU, S = 4.4, 1.0


def one_mode_cell(sigma: float, records: int = 4) -> dict:
    rng = np.random.default_rng(3)
    clean = AMP * np.exp(-ZETA * TRUTH * T_S) * np.cos(TRUTH * np.sqrt(1 - ZETA**2) * T_S + PHASE)
    modal = (np.array([TRUTH]), np.array([ZETA]), np.array([AMP]), np.array([PHASE]))
    return {"t_s": T_S, "accel_m_s2": clean + sigma * rng.standard_normal((records, T_S.size)),
            "dt_s": np.float64(0.05), "noise_ug": np.float64(sigma / 9.80665e-6), "noise_std_m_s2": np.float64(sigma),
            "seed": np.int64(11), "truth_freq_rad_s": modal[0], "truth_damping": modal[1],
            "truth_amplitude_m_s2": modal[2], "truth_phase_rad": modal[3],
            "crlb_std_rad_s": crlb_std(*modal, T_S.size, 0.05, sigma)}


def grid_posterior_mean(y, sigma):
    """E[ω | y] by the trapezoid rule on a fine grid: Gaussian prior, the amplitudes and offset at their
    least-squares values (np.linalg.lstsq), ζ known."""
    w = np.linspace(max(MU - 7 * S, 0.05), MU + 7 * S, 4001)
    log_post = np.empty(w.size)
    for k, wk in enumerate(w):
        env = np.exp(-ZETA * wk * T_S)
        arg = wk * np.sqrt(1 - ZETA**2) * T_S
        A = np.column_stack([env * np.cos(arg), env * np.sin(arg), np.ones_like(T_S)])
        rss = np.sum((y - A @ np.linalg.lstsq(A, y, rcond=None)[0]) ** 2)
        log_post[k] = -0.5 * rss / sigma**2 - 0.5 * ((wk - MU) / S) ** 2
    p = np.exp(log_post - log_post.max())
    return np.trapezoid(w * p, w) / np.trapezoid(p, w)


def test_a_one_mode_cell_matches_a_grid_integral_and_the_van_trees_bound_called_directly():
    sigma = 0.05
    cell = one_mode_cell(sigma)
    assert cell["crlb_std_rad_s"][0] > yardstick.LOOSE * S            # loose: the posterior mean is computed
    (row,) = yardstick.cell_rows(cell, [MU], [S], particles=400)
    assert row["loose"] and row["particles"] == 400
    est = np.array([grid_posterior_mean(y, sigma) for y in cell["accel_m_s2"]])
    rmse = np.sqrt(np.mean((est - TRUTH) ** 2))
    assert row["posterior_mean_rmse_rad_s"] == pytest.approx(rmse, abs=0.02 + 4 * row["posterior_mean_mc_rad_s"])
    assert row["posterior_mean_bias_rad_s"] == pytest.approx(np.mean(est - TRUTH),
                                                             abs=0.02 + 4 * row["posterior_mean_mc_rad_s"])
    assert row["posterior_mean_mc_rad_s"] < 0.1 * rmse
    vt = bayes.van_trees_std([MU], [S], [ZETA], [AMP], [PHASE], T_S.size, 0.05, sigma, offset=True, points=5,
                             known_damping=True)
    assert row["van_trees_std_rad_s"] == pytest.approx(vt[0], rel=1e-12)
    assert row["prior_error_rad_s"] == pytest.approx(abs(MU - TRUTH))
    # the prior mean alone is further off than the posterior mean here (the record holds information)
    assert rmse < abs(MU - TRUTH)


def test_where_the_classical_bound_is_tight_no_posterior_mean_is_computed():
    cell = one_mode_cell(1e-4)
    assert cell["crlb_std_rad_s"][0] < yardstick.LOOSE * S
    (row,) = yardstick.cell_rows(cell, [MU], [S])
    assert not row["loose"] and row["particles"] == 0 and np.isnan(row["posterior_mean_rmse_rad_s"])
    assert 0 < row["van_trees_std_rad_s"] < 0.01 * S        # the record dominates the prior


def test_the_summary_gets_rmse_over_the_posterior_mean_only_in_cells_where_the_bound_is_loose():
    summary = pd.DataFrame({"method": ["a", "a", "b", "a"], "noise_ug": [10.0, 10.0, 10.0, 1.0],
                            "n_samples": [20, 20, 20, 20], "mode": [1, 2, 1, 1], "rmse_rad_s": [0.5, 0.2, 1.0, 0.1],
                            "rmse_over_crlb": [1.0, 2.0, 3.0, 1.0], "rmse_over_crlb_offset": [1.0, 1.0, 1.0, 1.0],
                            "identifiable": [False, True, False, True]})
    table = pd.DataFrame({"noise_ug": [10.0, 10.0, 1.0], "n_samples": [20, 20, 20], "mode": [1, 2, 1],
                          "loose": [True, False, False], "van_trees_std_rad_s": [0.1, 0.01, 0.05],
                          "posterior_mean_rmse_rad_s": [0.25, 0.05, np.nan],
                          "posterior_mean_mc_rad_s": [0.01, 0.001, np.nan]})
    out = attach_yardstick(summary, table)
    assert list(out.columns[7:7 + len(YARDSTICK_COLUMNS)]) == YARDSTICK_COLUMNS   # beside RMSE/CRLB
    # mode 2 shares its cell with the loose mode 1: the posterior mean is its yardstick too
    np.testing.assert_allclose(out["rmse_over_posterior_mean"], [2.0, 4.0, 4.0, np.nan])
    np.testing.assert_allclose(out["van_trees_std_rad_s"], [0.1, 0.01, 0.1, 0.05])


@pytest.mark.parametrize(("args", "message"), [
    (["--prior-rad-s", "4.4", "--prior-std-rad-s", "-1"], "--prior-std-rad-s [-1.0] must be positive"),
    (["--prior-rad-s", "4.4", "5", "--prior-std-rad-s", "1"], "one per mode of --prior-std-rad-s"),
    (["--prior-rad-s", "4.4", "--prior-std-rad-s", "1", "--particles", "3"], "--particles 3 must be at least 10"),
])
def test_the_job_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    from experiments.io import write_npz
    from experiments.jobs import yardstick as job

    write_npz(tmp_path / "cell.npz", one_mode_cell(0.05, records=2))
    out = tmp_path / "y.csv"
    assert job.main([*args, "--out", str(out), str(tmp_path / "cell.npz")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err and message in err, err
    assert not out.exists()
    # and a good call writes one row per mode
    assert job.main(["--prior-rad-s", "4.4", "--prior-std-rad-s", "1", "--particles", "50", "--out", str(out),
                     str(tmp_path / "cell.npz")]) == 0
    assert len(pd.read_csv(out)) == 1
