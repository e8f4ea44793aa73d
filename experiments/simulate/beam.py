"""Clamped–free Euler–Bernoulli beam: eigenvalues, mode shapes and modal coefficients (paper eqs. 1–2).

Normalisation: W_n(x) = cosh βx − cos βx − σ_n (sinh βx − sin βx), so ∫₀ᴸ W_n² dx = L and W_n(L) = 2(−1)^(n+1)
(Rao, *Mechanical Vibrations*). See docs/physics.md §1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BeamGeometry", "cantilever_beta_l", "sigma", "mode_shape", "ModalCoefficients", "modal_coefficients"]


@dataclass
class BeamGeometry:
    """Paper §2 'Geometrical parameters'. Bending about the thickness ``height_m``."""

    length_m: float = 4.0
    width_m: float = 0.05
    height_m: float = 0.01
    density_kg_m3: float = 2700.0
    youngs_modulus_pa: float = 70e9

    @property
    def area_m2(self) -> float:
        return self.width_m * self.height_m

    @property
    def second_moment_m4(self) -> float:
        return self.width_m * self.height_m**3 / 12.0

    @property
    def mass_per_length(self) -> float:
        """ρA in kg/m."""
        return self.density_kg_m3 * self.area_m2

    @property
    def mass_kg(self) -> float:
        return self.mass_per_length * self.length_m

    @property
    def frequency_scale(self) -> float:
        """√(EI/(ρA L⁴)) in 1/s: ω_n = (β_n L)² × this."""
        ei = self.youngs_modulus_pa * self.second_moment_m4
        return float(np.sqrt(ei / (self.mass_per_length * self.length_m**4)))


def cantilever_beta_l(n: int) -> float:
    """n-th root (n ≥ 1) of the clamped–free frequency equation cos(βL)·cosh(βL) = −1.

    The roots lie in ((2n−1)π/2 − 0.5, (2n−1)π/2 + 0.5); the function is written as cos(x) + 1/cosh(x) to
    avoid overflow of cosh for large x.
    """
    guess = (2 * n - 1) * np.pi / 2
    from scipy.optimize import brentq  # 0.2 s of import: not paid by a job that only registers configs

    return float(brentq(lambda x: np.cos(x) + 1.0 / np.cosh(x), guess - 0.5, guess + 0.5, xtol=1e-15))


def sigma(beta_l: float) -> float:
    """σ_n = (cosh βL + cos βL)/(sinh βL + sin βL)."""
    return float((np.cosh(beta_l) + np.cos(beta_l)) / (np.sinh(beta_l) + np.sin(beta_l)))


def mode_shape(x: np.ndarray, beta_l: float, length_m: float) -> np.ndarray:
    """W(x) of the clamped–free mode with eigenvalue βL, normalised so that ∫₀ᴸ W² dx = L."""
    beta = beta_l / length_m
    bx = beta * np.asarray(x, dtype=float)
    s = sigma(beta_l)
    return np.cosh(bx) - np.cos(bx) - s * (np.sinh(bx) - np.sin(bx))


@dataclass(frozen=True)
class ModalCoefficients:
    """Coefficients of one mode shape in the coupled equations (4).

    ``momentum_kg`` p = ∫ρA W dx; ``angular_momentum_kg_m`` h = ∫ρA (r₀ + x) W dx about the body centre;
    ``tip_value`` W(L).
    """

    beta_l: float
    momentum_kg: float
    angular_momentum_kg_m: float
    tip_value: float


def modal_coefficients(beta_l: float, beam: BeamGeometry, root_offset_m: float) -> ModalCoefficients:
    """Closed forms p = 2ρAσ/β and h = r₀ p + 2ρA/β² (integrals of W and xW over the clamped–free beam)."""
    beta = beta_l / beam.length_m
    rho_a = beam.mass_per_length
    p = 2.0 * rho_a * sigma(beta_l) / beta
    h = root_offset_m * p + 2.0 * rho_a / beta**2
    tip = float(mode_shape(beam.length_m, beta_l, beam.length_m))
    return ModalCoefficients(beta_l, p, h, tip)
