"""Two disjoint windows of a softening steel cantilever's impact record: do their answers agree within 3σ?

    python -m experiments.benchmarks.windows [--records 20] [--seed 20261207] [--backbone cubic]
                                             [--methods pem pem:record]

A practitioner's record, as far as a simulation can make it one: the steel strip of
``experiments.simulate.impact`` lengthened to 0.8 m (three bending modes at 6.5, 40.9 and 114.5 Hz),
sampled by the logger at 2048 Hz in white sensor noise of 3 mg, every mode a softening oscillator whose
frequency falls by ``--shift`` (0.2 %) at the blow's amplitude, decimated by 5 to 409.6 Hz (the
anti-alias FIR of ``experiments.recordings.spectral.decimate``), and fitted by pem on two disjoint
windows of ``--window-s`` (2.5 s) from the blow, with the residual check judging the filter's flat band
only (as the measurement job does). The backbone is the Duffing one (``cubic``: restoring force
ω²x + εx³, frequency shift ∝ A²) or a quadratic stiffness (``quadratic``: ω²x + ε|x|x, shift ∝ A, the
shape of a loose clamp), which the amplitude line ω₀ + βa² does not describe. ``--ar1`` colours the sensor
noise (a real logger's is rarely white).

The truth is unknown to the score on purpose: two windows of one record must give the same answer for
the same quantity, whatever it is; the table gives, per mode, the share of records whose windows differ
by at most 3 combined reported σ, √(σ₁² + σ₂²), and the largest ratio. Seeds: records draw from
``default_rng([seed, record])``; the default seed is a scoring seed, nothing was tuned on it.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import methods
from experiments.benchmarks.mismatch import method_setup
from experiments.recordings.spectral import decimate, flat_band
from experiments.simulate.beam import BeamGeometry, cantilever_beta_l
from experiments.simulate.mismatch import ar1_noise

__all__ = ["STRIP", "FS_HZ", "DECIMATION", "DAMPING", "AMPLITUDE_G", "NOISE_G", "SEED", "softening_modes",
           "simulate", "agreement", "main"]

G = 9.80665
STRIP = BeamGeometry(length_m=0.8, width_m=0.03, height_m=0.005, density_kg_m3=7850.0, youngs_modulus_pa=210e9)
FS_HZ = 2048.0
DECIMATION = 5
DAMPING = np.array([0.006, 0.003, 0.002])
AMPLITUDE_G = np.array([0.6, -1.5, 1.0])
NOISE_G = 0.003
SEED = 20261207


def softening_modes(t: np.ndarray, freq_rad_s, damping, amplitude, shift: float, backbone: str) -> np.ndarray:
    """Σᵢ aᵢxᵢ(t), each xᵢ(0) = 0, ẋᵢ(0) = ω_dᵢ (an impulse), of ẍ + 2ζωẋ + ω²x + f(x) = 0 with
    f = εx³ (``cubic``, backbone ω(A)² ≈ ω²(1 + 3εA²/(4ω²))) or f = ε|x|x (``quadratic``, ω(A)² ≈
    ω²(1 + 8εA/(3πω²))), ε set so that the frequency at A = 1 is (1 + ``shift``)ω.
    scipy.integrate.solve_ivp (DOP853, rtol 1e-10)."""
    import scipy.integrate  # the benchmark's only use of it

    out = np.zeros(t.size)
    for w, z, a in zip(freq_rad_s, damping, amplitude, strict=True):
        ratio = (1.0 + shift) ** 2 - 1.0                     # ω(1)²/ω² − 1
        if backbone == "cubic":
            eps, power = 4.0 * w * w * ratio / 3.0, 3
        else:
            eps, power = 3.0 * math.pi * w * w * ratio / 8.0, 2
        wd = w * math.sqrt(1.0 - z * z)

        def rhs(_, s, w=w, z=z, eps=eps, power=power):
            x = s[0]
            return [s[1], -2 * z * w * s[1] - w * w * x - eps * np.abs(x) ** (power - 1) * x]

        sol = scipy.integrate.solve_ivp(rhs, (0.0, float(t[-1])), [0.0, wd], method="DOP853", t_eval=t,
                                        rtol=1e-10, atol=1e-12)
        if not sol.success:
            raise ValueError(f"the oscillator at {w:.4g} rad/s did not integrate ({sol.message})")
        out += a * sol.y[0]
    return out


def simulate(seed: int, record: int, window_s: float, shift: float, backbone: str,
             ar1: float = 0.0) -> tuple[np.ndarray, float]:
    """One decimated record from the blow, two windows long, m/s², and its sample interval; ``ar1`` = φ:
    the sensor noise AR(1) at the logger's rate (``experiments.simulate.mismatch.ar1_noise``), else white."""
    rng = np.random.default_rng([seed, record])
    w = np.array([cantilever_beta_l(k) ** 2 for k in (1, 2, 3)]) * STRIP.frequency_scale
    w = w * np.exp(rng.normal(0.0, 0.01, 3))                  # the strip's tolerances: each record its own
    t = np.arange(int(math.ceil(2 * window_s * FS_HZ)) + 20 * DECIMATION) / FS_HZ
    noise = ar1_noise(rng, t.size, NOISE_G, ar1) if ar1 else NOISE_G * rng.standard_normal(t.size)
    y = G * (softening_modes(t, w, DAMPING, AMPLITUDE_G, shift, backbone) + noise)
    return decimate(y, DECIMATION), DECIMATION / FS_HZ


def agreement(names, seed: int, records: int, window_s: float, shift: float, backbone: str,
              ar1: float = 0.0) -> dict:
    """Per method: (records × 3) |ω̂₁ − ω̂₂|/√(σ₁² + σ₂²) of the two windows (NaN where either window did
    not determine the mode), the σ of each window (Hz) and whether each window's residual was white."""
    out = {name: {"ratio": [], "std_hz": [], "white": []} for name in names}
    prior = np.array([cantilever_beta_l(k) ** 2 for k in (1, 2, 3)]) * STRIP.frequency_scale * 1.05
    band = flat_band(DECIMATION)
    for r in range(records):
        y, dt = simulate(seed, r, window_s, shift, backbone, ar1)
        n = int(round(window_s / dt))
        for name in names:
            base, _, options = method_setup(name)
            options = {**options, "whiteness_band_rad_s": band * math.pi / dt}
            a, b = (methods.get(base)(part, dt, prior, **options) for part in (y[:n], y[n:2 * n]))
            ok = a.converged_per_mode & b.converged_per_mode
            diff = np.where(ok, np.abs(a.frequencies - b.frequencies), np.nan)
            out[name]["ratio"].append(diff / np.hypot(a.std, b.std))
            out[name]["std_hz"].append(np.stack([a.std, b.std]) / (2 * math.pi))
            out[name]["white"].append([e.extra["residual_check"]["white"] for e in (a, b)])
    return {name: {k: np.array(v) for k, v in d.items()} for name, d in out.items()}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--records", type=int, default=20)
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--window-s", type=float, default=2.5)
    parser.add_argument("--shift", type=float, default=-0.002)
    parser.add_argument("--backbone", choices=("cubic", "quadratic"), default="cubic")
    parser.add_argument("--ar1", type=float, default=0.0, help="AR(1) φ of the sensor noise (0: white)")
    parser.add_argument("--methods", nargs="+", default=["pem", "pem:record"])
    args = parser.parse_args(argv)
    if args.records < 1 or not args.window_s > 0 or not -0.2 < args.shift < 0.2 or not -1 < args.ar1 < 1:
        parser.exit(2, f"error: --records = {args.records} must be ≥ 1, --window-s = {args.window_s} positive, "
                    f"--shift = {args.shift} inside (−0.2, 0.2) and --ar1 = {args.ar1} inside (−1, 1)\n")
    try:
        for name in args.methods:
            method_setup(name)
    except (OSError, KeyError) as exc:
        parser.exit(2, f"error: {exc}\n")
    t0 = time.perf_counter()
    res = agreement(args.methods, args.seed, args.records, args.window_s, args.shift, args.backbone, args.ar1)
    noise = f"AR(1) φ = {args.ar1:g}" if args.ar1 else "white"
    print(f"two {args.window_s:g} s windows of a softening cantilever ({args.backbone} backbone, shift "
          f"{100 * args.shift:g} % at the blow, {noise} noise), "
          f"{args.records} records, seed {args.seed}, {time.perf_counter() - t0:.0f} s")
    print("| method | share ≤ 3σ, modes 1–3 | largest ratio | median 1σ (Hz), modes 1–3 | white residual, "
          "window 1 / 2 |")
    print("|---|---|---|---|---|")
    for name, d in res.items():
        r = d["ratio"]
        share = ", ".join(f"{100 * np.mean(r[np.isfinite(r[:, i]), i] <= 3):.0f} %" for i in range(3))
        big = ", ".join(f"{np.nanmax(r[:, i]):.2g}" if np.isfinite(r[:, i]).any() else "–" for i in range(3))
        med = ", ".join(f"{np.nanmedian(d['std_hz'][:, :, i]):.2g}" for i in range(3))
        white = np.mean(d["white"], axis=0)
        print(f"| `{name}` | {share} | {big} | {med} | {100 * white[0]:.0f} % / {100 * white[1]:.0f} % |")


if __name__ == "__main__":
    main()
