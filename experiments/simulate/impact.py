"""A simulated impact test of a steel cantilever, as a practitioner's logger records it (the record of
docs/measurements.md, its tests and experiments.benchmarks.measurement).

Three bending modes of a clamped–free steel strip (0.5 m × 30 mm × 5 mm: 16.7, 104.7, 293.1 Hz from
experiments.simulate.beam's eigenvalues), tip acceleration in g sampled at 2048 Hz, white sensor noise
over the whole record, and the hammer blow at a random time after a stretch of noise: for t ≥ t_hit the
impulse response Σᵢ aᵢ e^(−ζᵢωᵢτ) sin(ω_dᵢτ), τ = t − t_hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from experiments.cli import ArgumentParser
from experiments.io import atomic_path
from experiments.simulate.beam import BeamGeometry, cantilever_beta_l
from experiments.simulate.crlb import crlb_std
from experiments.units import G_M_S2

__all__ = ["G", "STEEL_STRIP", "FS_HZ", "DURATION_S", "DAMPING", "AMPLITUDE_G", "NOISE_G", "Impact",
           "cantilever_frequencies_rad_s", "simulate", "main"]

G = G_M_S2
STEEL_STRIP = BeamGeometry(length_m=0.5, width_m=0.03, height_m=0.005, density_kg_m3=7850.0,
                           youngs_modulus_pa=210e9)
FS_HZ = 2048.0
DURATION_S = 6.0
DAMPING = np.array([0.012, 0.006, 0.004])
AMPLITUDE_G = np.array([0.6, -1.5, 1.0])        # tip signs of cantilever modes 1–3
NOISE_G = 0.003


@dataclass
class Impact:
    """The record (``t`` s, ``accel_g``), the time of the blow and the modes' truth."""

    t: np.ndarray
    accel_g: np.ndarray
    t_hit: float
    freq_rad_s: np.ndarray
    damping: np.ndarray

    def crlb_rad_s(self, start_s: float, stop_s: float) -> np.ndarray:
        """The CRLB of the frequencies from the free decay between start_s and stop_s at the logger's own
        rate and noise (what decimation cannot improve on)."""
        dt = self.t[1] - self.t[0]
        n = int(round((stop_s - start_s) / dt)) + 1
        tau0 = start_s - self.t_hit
        wd = self.freq_rad_s * np.sqrt(1 - self.damping**2)
        amp = AMPLITUDE_G * G * np.exp(-self.damping * self.freq_rad_s * tau0)
        phase = wd * tau0 - np.pi / 2                      # sin(wd(τ0 + t)) = cos(wd t + wd τ0 − π/2)
        return crlb_std(self.freq_rad_s, self.damping, amp, phase, n, dt, NOISE_G * G)


def cantilever_frequencies_rad_s(n_modes: int = 3) -> np.ndarray:
    scale = STEEL_STRIP.frequency_scale
    return np.array([cantilever_beta_l(k) ** 2 * scale for k in range(1, n_modes + 1)])


def simulate(seed: int, n_samples: int | None = None) -> Impact:
    """The impact record of ``seed`` (``n_samples`` at :data:`FS_HZ`, default :data:`DURATION_S` of them)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(DURATION_S * FS_HZ) if n_samples is None else int(n_samples)) / FS_HZ
    t_hit = float(rng.uniform(0.5, 2.0))
    w = cantilever_frequencies_rad_s()
    y = NOISE_G * rng.standard_normal(t.size)
    tau = t - t_hit
    on = tau >= 0
    for wi, zi, ai in zip(w, DAMPING, AMPLITUDE_G, strict=True):
        y[on] += ai * np.exp(-zi * wi * tau[on]) * np.sin(wi * np.sqrt(1 - zi**2) * tau[on])
    return Impact(t, y, t_hit, w, DAMPING.copy())


def main(argv=None) -> None:
    """``python -m experiments.simulate.impact beam.csv [--seed 1]``: the record as a logger's CSV (time
    stamps printed to 1 µs, the tip acceleration in g), the example of docs/measurements.md."""
    parser = ArgumentParser(description=main.__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--seed", type=int, default=1)
    a = parser.parse_args(argv)
    rec = simulate(a.seed)
    with atomic_path(a.out) as tmp:
        np.savetxt(tmp, np.column_stack([rec.t, rec.accel_g]), fmt=["%.6f", "%.7e"], delimiter=",",
                   header="t,tip [g]", comments="")
    print(f"wrote {a.out}: {rec.t.size} samples at {FS_HZ:g} Hz, the blow at {rec.t_hit:.4f} s; modes "
          f"{', '.join(f'{w / (2 * np.pi):.4g}' for w in rec.freq_rad_s)} Hz, damping "
          f"{', '.join(f'{z:g}' for z in rec.damping)}")


if __name__ == "__main__":
    main()
