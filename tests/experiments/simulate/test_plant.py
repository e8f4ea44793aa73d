import numpy as np
import pytest
import scipy.linalg

from experiments.simulate.plant import PlantConfig, build_plant

TABLE3 = [3.23, 20.24, 22.00, 56.67]
FREE_FREE = [3.3208, 20.3557, 22.0210, 56.7821]          # docs/physics.md §2, 270 kg body, no calibration
CALIBRATED_CANTILEVER = [3.1417, 20.1272, 21.9791, 56.5671]


def test_coupled_frequencies_match_table3_after_calibration(plant):
    np.testing.assert_allclose(plant.freq_rad_s, TABLE3, rtol=1e-4)
    np.testing.assert_allclose(plant.cantilever_freq_rad_s, CALIBRATED_CANTILEVER, atol=1e-4)


def test_uncalibrated_coupled_frequencies_match_free_free_values():
    p = build_plant(PlantConfig(calibrate=False))
    np.testing.assert_allclose(p.freq_rad_s, FREE_FREE, atol=1e-4)
    assert p.freq_rad_s[0] / 3.2300 - 1 == pytest.approx(0.0281, abs=2e-4)      # the 2.8 % shift


def test_mass_matrix_is_symmetric_positive_definite_with_expected_condition(plant):
    M = plant.M
    np.testing.assert_array_equal(M, M.T)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    assert np.linalg.cond(M) == pytest.approx(950, rel=0.01)
    assert M[1, 1] == pytest.approx(4771.8, abs=0.05)


def test_undamped_generalised_eigenproblem_gives_six_rigid_and_four_flexible_modes():
    p = build_plant(PlantConfig(damping=[0.0] * 4))
    lam = scipy.linalg.eigh(p.K, p.M, eigvals_only=True)
    assert np.all(np.abs(lam[:6]) < 1e-9)
    np.testing.assert_allclose(np.sqrt(lam[6:]), p.freq_rad_s, rtol=1e-10)


def test_tip_response_matches_independent_damped_sinusoid_sum(plant):
    t = np.arange(2048) * 0.02
    y = plant.tip_acceleration(t.size, 0.02)
    ref = plant.modal_sum(t)
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_undamped_tip_response_matches_second_order_modal_superposition():
    # Independent route: mass-normalised modes of (K, M); eta(t) = sum phi_i (phi_i^T M eta0) cos(w_i t).
    p = build_plant(PlantConfig(damping=[0.0] * 4))
    lam, phi = scipy.linalg.eigh(p.K, p.M)
    lam, phi = lam[6:], phi[:, 6:]
    eta0 = p.x0[:10]
    t = np.arange(1024) * 0.02
    weights = -(lam * (p.c_tip @ phi) * (phi.T @ p.M @ eta0))
    ref = np.cos(np.sqrt(lam)[None, :] * t[:, None]) @ weights
    y = p.tip_acceleration(t.size, 0.02)
    assert np.max(np.abs(y - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_zero_initial_momentum_means_no_rigid_drift(plant):
    # Body displacement after 60 s stays bounded by the vibration amplitude (no secular growth).
    import scipy.linalg as sl
    x = sl.expm(plant.A * 60.0) @ plant.x0
    assert np.all(np.abs(x[:6]) < 1e-2)
    momentum = plant.M @ x[10:]
    assert np.all(np.abs(momentum[:6]) < 1e-10)


def test_tip_amplitudes_match_the_physics_reference(plant):
    p = build_plant(PlantConfig(calibrate=False))
    np.testing.assert_allclose(p.modal_amplitude, [1.06, 3.90, 5.12, 6.47], atol=0.006)


def test_damping_is_configurable_per_mode():
    p = build_plant(PlantConfig(damping=[0.01, 0.002, 0.005, 0.02]))
    np.testing.assert_allclose(p.damping, [0.01, 0.002, 0.005, 0.02], rtol=0.05)


@pytest.mark.parametrize("bad", [dict(damping=[0.005] * 3), dict(damping=[1.2] * 4), dict(body_mass_kg=0.0)])
def test_bad_plant_config_is_rejected(bad):
    with pytest.raises(ValueError):
        PlantConfig(**bad)
