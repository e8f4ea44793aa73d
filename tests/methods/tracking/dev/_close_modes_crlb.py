"""What the six-mode stepped records allow: the Cramér–Rao bound of every frequency after each step, from a
window of ``--periods`` periods of the slowest mode at the record's noise — a development table, not a test
(pytest does not collect it).

    python tests/methods/tracking/dev/_close_modes_crlb.py [--seeds 1,3,21,23] [--dts 0.004,0.1] [--periods 10,20]

Records: ``anyrate_record(dt, 6, seed, duration_periods=120)`` (tests/methods/_tracking_signals.py), the ones
of ``_anyrate_table.py``. After each step the window [step + 1, step + 1 + N) (N samples = that many periods of
the new slowest mode, cut at the dwell's end) is, between the blows of the record's force, a free decay: the
model is the piecewise free decay the segment fit of ``gated_pencil`` fits — ω and ζ shared by the runs, each
run its own amplitudes, phases and offset (a blow's own sample belongs to no run). Its Fisher information
J = GᵀG/σ² (G the Jacobian of the noise-free response, each run's columns from
:func:`experiments.simulate.crlb.signal_jacobian` at the run's own time origin, the ω and ζ columns summed over
the runs), σ the record's noise std, the amplitudes and phases those of the noise-free record (a least-squares
fit of each run at the true poles). The weak white force is left out: the bound is optimistic, so a bound
above the target says that no tracker reaches it.

Printed per step: the closest pair's relative gap, the largest 2σ/ω over the six modes, and 2σ/ω of the
closest pair's two modes, for each window length.
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[2]), str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _tracking_signals import anyrate_record, modal_response  # noqa: E402

from experiments.simulate.crlb import signal_jacobian  # noqa: E402
from methods.tracking import _segments  # noqa: E402


def piecewise_crlb(clean: np.ndarray, dt: float, w: np.ndarray, zeta: float, runs, noise_std: float) -> np.ndarray:
    """1σ (rad/s) of each ω from the runs [a, b) of ``clean`` (module docstring)."""
    m = w.size
    z = np.full(m, zeta)
    blocks, shared = [], []
    for a, b in runs:
        t = np.arange(b - a) * dt
        X = _segments.free_decay_basis(b - a, dt, w, z)
        c = np.linalg.lstsq(X, clean[a:b], rcond=None)[0]
        amp = np.hypot(c[:m], c[m:2 * m])
        phase = np.arctan2(-c[m:2 * m], c[:m])             # a cos(ω_d t + φ) = a cos φ cos − a sin φ sin
        G = signal_jacobian(w, z, amp, phase, t, offset=True)
        own = np.concatenate([[4 * i, 4 * i + 1] for i in range(m)] + [[4 * m]])
        blocks.append(G[:, own])
        shared.append(G[:, np.concatenate([[4 * i + 2, 4 * i + 3] for i in range(m)])])
    n_own = sum(g.shape[1] for g in blocks)
    rows = sum(g.shape[0] for g in blocks)
    J = np.zeros((rows, n_own + 2 * m))
    r = c0 = 0
    for g, s in zip(blocks, shared, strict=True):
        J[r:r + g.shape[0], c0:c0 + g.shape[1]] = g
        J[r:r + g.shape[0], n_own:] = s
        r, c0 = r + g.shape[0], c0 + g.shape[1]
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0
    _, sv, vt = np.linalg.svd(J / norms, full_matrices=False)
    if sv[-1] <= sv[0] * 1e-14:
        return np.full(m, np.inf)
    cov = (vt.T / sv ** 2) @ vt
    idx = n_own + 2 * np.arange(m)
    return noise_std * np.sqrt(np.diag(cov)[idx]) / norms[idx]


def main(argv=None):
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", default="1,3,21,23")
    parser.add_argument("--dts", default="0.004,0.1")
    parser.add_argument("--periods", default="10,20")
    args = parser.parse_args(argv)
    periods = [float(p) for p in args.periods.split(",")]
    print("dt, seed, step: closest pair's gap %; then per window: max 2σ/ω % over the modes, the pair's 2σ/ω %")
    for dt in (float(d) for d in args.dts.split(",")):
        for seed in (int(s) for s in args.seeds.split(",")):
            y, truth, steps, prior, u, noise_std, zeta = anyrate_record(dt, 6, seed, duration_periods=120.0,
                                                                        parts=True)
            clean = modal_response(truth, u, zeta=zeta, gain=np.ones(6), dt=dt)
            blows = np.flatnonzero(np.abs(u) > 0.004 / dt)     # blows ≥ 0.01/Δt; the white force ≪ that
            ends = np.concatenate((steps[1:], [y.size]))
            for s, e in zip(steps, ends, strict=True):
                w = truth[s]
                gaps = np.diff(w) / w[:-1]
                k = int(np.argmin(gaps))
                cells = []
                for p in periods:
                    want = int(round(p * 2 * np.pi / w.min() / dt))
                    stop = min(e, s + 1 + want)
                    flags = np.zeros(stop - s - 1, dtype=bool)
                    inside = blows[(blows > s) & (blows < stop)] - s - 1
                    flags[inside] = True
                    runs = [(a + s + 1, b + s + 1) for a, b in _segments.segments(flags, 2 * (2 * 6 + 1))]
                    sd = piecewise_crlb(clean, dt, w, zeta, runs, noise_std)
                    rel = 2 * sd / w
                    cut = "" if stop - s - 1 == want else " (dwell)"
                    cells.append(f"{p:g} periods{cut}: max {100 * rel.max():.3f} %, "
                                 f"pair {100 * rel[k]:.3f}/{100 * rel[k + 1]:.3f} %")
                print(f"dt {dt:g}, seed {seed}, step at {s}: gap {100 * gaps[k]:.1f} % (modes {k + 1}/{k + 2})  "
                      + "; ".join(cells), flush=True)


if __name__ == "__main__":
    main()
