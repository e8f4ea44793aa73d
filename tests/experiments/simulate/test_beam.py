import numpy as np
import pytest
from scipy.integrate import quad

from experiments.simulate.beam import BeamGeometry, cantilever_beta_l, modal_coefficients, mode_shape

# Clamped-free eigenvalues (Rao, Mechanical Vibrations, table of beta_n L) and docs/physics.md §1.
BETA_L = [1.875104, 4.694091, 7.854757, 10.995541]
OMEGA = [3.2300, 20.2423, 56.6790, 111.068]
P = [4.2282, 2.3433, 1.3739, 0.9822]
H = [33.427, 13.677, 7.570, 5.269]


def test_geometry_numbers_match_the_physics_reference():
    b = BeamGeometry()
    assert b.youngs_modulus_pa * b.second_moment_m4 == pytest.approx(291.67, rel=1e-4)
    assert b.mass_per_length == pytest.approx(1.35)
    assert b.mass_kg == pytest.approx(5.4)
    assert b.frequency_scale == pytest.approx(0.91866, rel=1e-5)


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_cantilever_eigenvalue_solves_frequency_equation(n):
    x = cantilever_beta_l(n)
    assert x == pytest.approx(BETA_L[n - 1], abs=1e-6)
    assert np.cos(x) * np.cosh(x) == pytest.approx(-1.0, abs=1e-9)


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_cantilever_frequency_matches_closed_form(n):
    b = BeamGeometry()
    omega = cantilever_beta_l(n) ** 2 * np.sqrt(b.youngs_modulus_pa * b.second_moment_m4
                                                 / (b.mass_per_length * b.length_m**4))
    assert omega == pytest.approx(OMEGA[n - 1], rel=2e-5)


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_mode_shape_normalisation_and_coefficients_by_quadrature(n):
    b, r0 = BeamGeometry(), 5.0
    bl = cantilever_beta_l(n)
    W = lambda x: float(mode_shape(x, bl, b.length_m))  # noqa: E731
    assert quad(lambda x: W(x) ** 2, 0, b.length_m, limit=200)[0] == pytest.approx(b.length_m, rel=1e-8)
    k = modal_coefficients(bl, b, r0)
    p_quad = b.mass_per_length * quad(W, 0, b.length_m, limit=200)[0]
    h_quad = b.mass_per_length * quad(lambda x: (r0 + x) * W(x), 0, b.length_m, limit=200)[0]
    assert k.momentum_kg == pytest.approx(p_quad, rel=1e-8)
    assert k.angular_momentum_kg_m == pytest.approx(h_quad, rel=1e-8)
    assert k.momentum_kg == pytest.approx(P[n - 1], abs=1e-4)
    assert k.angular_momentum_kg_m == pytest.approx(H[n - 1], abs=1e-3)
    assert k.tip_value == pytest.approx(2.0 * (-1) ** (n + 1), abs=1e-9)


def test_clamped_root_has_zero_displacement_and_slope():
    bl = cantilever_beta_l(2)
    assert mode_shape(0.0, bl, 4.0) == pytest.approx(0.0, abs=1e-12)
    eps = 1e-6
    assert (mode_shape(eps, bl, 4.0) - mode_shape(0.0, bl, 4.0)) / eps == pytest.approx(0.0, abs=1e-4)
