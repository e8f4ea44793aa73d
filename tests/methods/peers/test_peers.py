"""The peer identifiers (methods/peers/era.py … bopdmd.py) through the one face.

Physics/maths checked: a noise-free record of the plant's four modes (exactly four damped sinusoids, the
paper's frequencies) is realised exactly by a model of order 2m + 1 + spare, so every library must return
the true eigenfrequencies |λ| to 1e-4 relative; with white noise the estimates stay near the truth; bad
options get a ValueError naming the value; a record too short for the model says so per mode.
"""

import numpy as np
import pytest
from _signals import DT, other_plant

import methods

PEERS = ["era", "n4sid", "ssi_cov", "ssi_data", "lsce", "hdmd", "bopdmd"]
PRIOR = np.array([3.80, 16.00, 26.00, 46.00])       # Table 3 (configs/method/<peer>.yaml)


@pytest.fixture(scope="module")
def truth(plant):
    return np.sort(np.abs(plant.truth()["freq_rad_s"]))


@pytest.mark.parametrize("name", PEERS)
def test_noise_free_record_gives_the_true_frequencies(name, plant, truth):
    y = plant.tip_acceleration(256, DT)
    est = methods.get(name)(y, DT, PRIOR)
    assert est.converged, est.message
    np.testing.assert_allclose(est.frequencies, truth, rtol=1e-4)
    assert est.converged_per_mode.tolist() == [True] * 4
    assert np.all(np.isnan(est.std))                 # no peer has an uncertainty by default


@pytest.mark.parametrize("name", PEERS)
def test_noisy_record_stays_near_the_truth(name, noisy_record, truth):
    """1000 µg, 256 samples, seed 3: modes 1, 2 and 4 within 1 % (mode 3 sits 1.76 rad/s from mode 2)."""
    est = methods.get(name)(noisy_record(256, 1000.0, seed=3), DT, PRIOR)
    ok = np.isfinite(est.frequencies)
    assert ok.sum() >= 3, est.message
    assert np.all(np.abs(est.frequencies[ok] - truth[ok]) / truth[ok] < 0.03), est.frequencies


@pytest.mark.parametrize("name", ["era", "hdmd", "lsce"])
def test_other_plants_and_a_bias(name):
    """Two and five modes, a sensor offset of 0.5 m/s²: the offset is a real pole, never a mode."""
    for m in (2, 5):
        freq, y = other_plant(m, 512, bias=0.5)
        est = methods.get(name)(y, DT, freq * 1.15)
        np.testing.assert_allclose(est.frequencies, freq, rtol=1e-4)


@pytest.mark.parametrize("name", PEERS)
def test_bad_options_name_the_value(name):
    y = np.cos(5 * np.arange(128) * DT)
    with pytest.raises(ValueError, match="band"):
        methods.get(name)(y, DT, [5.0], band=-1.0)
    with pytest.raises(ValueError, match="no_such_option"):
        methods.get(name)(y, DT, [5.0], no_such_option=1)
    with pytest.raises(ValueError, match="confirm = 'yes' must be true or false"):
        methods.check_options(name, [5.0], DT, {"confirm": "yes"})


@pytest.mark.parametrize("name", ["hdmd", "bopdmd"])
def test_a_bad_delays_fraction_is_refused_before_any_record(name):
    """check_options (no record) refuses it, and identify does so even on a flat record."""
    with pytest.raises(ValueError, match="delays_fraction = 1.5"):
        methods.check_options(name, [5.0], DT, {"delays_fraction": 1.5})
    with pytest.raises(ValueError, match="delays_fraction = 0"):
        methods.get(name)(np.zeros(128), DT, [5.0], delays_fraction=0.0)


@pytest.mark.parametrize("name", ["n4sid", "ssi_data"])
def test_too_short_record_fails_per_mode(name, plant):
    """20 samples cannot hold these libraries' Hankel matrices for 4 modes: NaN, not converged, no crash."""
    est = methods.get(name)(plant.tip_acceleration(20, DT), DT, PRIOR)
    assert not est.converged and np.all(np.isnan(est.frequencies))
    assert est.converged_per_mode.tolist() == [False] * 4


@pytest.mark.slow
def test_bopdmd_bagging_gives_the_librarys_spread(noisy_record):
    est = methods.get("bopdmd")(noisy_record(64, 1000.0, seed=4), DT, PRIOR, num_trials=5)
    assert np.all(np.isfinite(est.std[np.isfinite(est.frequencies)]))
    assert np.all(est.std[np.isfinite(est.frequencies)] > 0)


@pytest.mark.parametrize("n, noise_ug", [(64, 100.0), (512, 10.0), (1024, 10000.0)])
def test_hdmd_truncated_svd_gives_pydmd_s_own_eigenvalues(noisy_record, n, noise_ug):
    """DMD of the delay snapshots projected on their leading singular vectors (ARPACK) has the eigenvalues
    of pydmd's HankelDMD with its full SVDs, to rounding: the same poles, picks and flags."""
    from pydmd import DMD, HankelDMD

    from methods.peers import hdmd

    y = noisy_record(n, noise_ug, seed=11)
    d, order = hdmd.delays_and_order(y.size, PRIOR, DT, hdmd.Options())
    full = HankelDMD(svd_rank=order, d=d).fit(y[None, :]).eigs
    H = hdmd.delay_embedding(y, d)
    np.testing.assert_array_equal(H[3], y[3:3 + y.size - d + 1])
    cut = DMD(svd_rank=order).fit(hdmd.leading_subspace(H, order).T @ H).eigs
    np.testing.assert_allclose(np.sort_complex(cut), np.sort_complex(full), rtol=1e-9, atol=1e-12)
    a, b = (methods.get("hdmd")(y, DT, PRIOR, svd=s) for s in ("full", "truncated"))
    np.testing.assert_allclose(a.frequencies, b.frequencies, rtol=1e-9)
    assert a.converged_per_mode.tolist() == b.converged_per_mode.tolist()


def test_hdmd_leading_subspace_leaves_a_square_rank_to_the_full_svd():
    H = np.lib.stride_tricks.sliding_window_view(np.arange(12.0), 6)      # 7 x 6: X1 is 7 x 5
    from methods.peers import hdmd

    assert hdmd.leading_subspace(H, 5) is None and hdmd.leading_subspace(H, 4).shape == (7, 4)


@pytest.mark.parametrize("name, option, value", [("hdmd", "svd", "randomised"), ("bopdmd", "start", "prior"),
                                                 ("bopdmd", "eps_stall", 1.0), ("bopdmd", "eps_stall", -1e-3),
                                                 ("bopdmd", "full_jacobian", "yes")])
def test_the_cost_options_are_checked_before_any_record(name, option, value):
    with pytest.raises(ValueError, match=f"{option} = "):
        methods.check_options(name, [5.0], DT, {option: value})


@pytest.mark.parametrize("n_samples, noise_ug, seed", [(64, 100.0, 5), (256, 1000.0, 3)])
def test_bopdmd_kaufman_jacobian_reaches_the_full_jacobian_s_optimum(noisy_record, n_samples, noise_ug, seed,
                                                                      monkeypatch):
    """Kaufman's Jacobian drops a term orthogonal to the residual, so the gradient and the stationary points
    are the full Jacobian's: run to pydmd's own stall test (1e-12), both end at the same frequencies; and the
    option reaches pydmd (its varpro_opts_dict)."""
    import pydmd

    y = noisy_record(n_samples, noise_ug, seed=seed)
    full = methods.get("bopdmd")(y, DT, PRIOR, eps_stall=1e-12, full_jacobian=True)
    seen = []
    real = pydmd.BOPDMD

    def spy(*args, **kwargs):
        seen.append(kwargs["varpro_opts_dict"]["use_fulljac"])
        return real(*args, **kwargs)

    monkeypatch.setattr(pydmd, "BOPDMD", spy)
    kaufman = methods.get("bopdmd")(y, DT, PRIOR, eps_stall=1e-12)
    assert seen == [False]
    np.testing.assert_allclose(kaufman.frequencies, full.frequencies, rtol=1e-6)


def test_bopdmd_dmd_start_reaches_pydmd_s_own_optimum(noisy_record):
    """From the exact-DMD start in the projected coordinates, with the stall test at 1e-12 (pydmd's
    default), the variable projection ends where pydmd's own path (trapezoidal start, its SVDs) ends."""
    y = noisy_record(512, 100.0, seed=12)
    own = methods.get("bopdmd")(y, DT, PRIOR, start="trapezoid", eps_stall=1e-12)
    ours = methods.get("bopdmd")(y, DT, PRIOR, start="dmd", eps_stall=1e-12)
    np.testing.assert_allclose(ours.frequencies, own.frequencies, rtol=2e-6)
