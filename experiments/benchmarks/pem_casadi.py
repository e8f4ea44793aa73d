"""Whether ``pem``'s search iteration pays as one compiled CasADi Function: CPU per iteration, side by side.

    python -m experiments.benchmarks.pem_casadi                  # writes results/bench/pem_casadi.md
    python -m experiments.benchmarks.pem_casadi --n-samples 256 2048 --repeats 40 --jit

One iteration of the output-error search (:mod:`methods.pem`'s default path) at the point ``pem`` accepts on
``experiments.benchmarks.pem_speed.record(N)`` (1 mg, the paper plant, Table 4 prior): the basis Φ(ω, ζ), the
linear solve c = (ΦᵀΦ)⁻¹Φᵀy, the residual ε = y − Φc and its loss, Kaufman's reduced Jacobian
J_r = P⊥ ∂ε/∂(ω, ζ), its normal equations J_rᵀJ_r, J_rᵀε and the Gauss–Newton step with the std of ω. Rows:

- numpy: :class:`methods.pem.SeparableModel` (``fit``, ``reduced_jacobian``) and
  :class:`methods.pem.search.NormalEquations`, as the search runs them;
- CasADi: everything up to J_rᵀJ_r and J_rᵀε as one MX Function (built once per (m, N): CasADi's dimensions
  are fixed when a Function is built, so N is a build argument, not data), called through
  ``Function.buffer()`` (≈ 1 µs a call; the ordinary call converts every numpy argument, 50–200 µs), the
  8 × 8 normal equations then as in the numpy row (CasADi's MX has no symmetric eigendecomposition, which
  the Levenberg–Marquardt rule scales by); the Function alone in its own row;
- with ``--jit``: the same Function compiled to C by CasADi (``jit``, compiler ``shell``: needs a C compiler
  on the path; the build takes seconds).

Times: thread CPU (``time.thread_time``) per iteration, median over ``--repeats`` rounds of 50 iterations,
the rows interleaved in each round. ``agree``: the largest difference from the numpy row of the
Gauss–Newton step (in std of the unknowns) and of the std (relative). Run with one BLAS thread.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import tempfile
import time

import casadi as ca
import numpy as np

from experiments.benchmarks import pem_speed
from methods import pem
from methods.pem import search

__all__ = ["iteration_function", "main"]

DT_S = pem_speed.DT_S
ROUND = 50           # iterations per timed call


def iteration_function(n: int, m: int, jit: bool = False) -> ca.Function:
    """The MX Function (x = (ω, ζ), y, t) → (c, ε, loss, J_rᵀJ_r, J_rᵀε, J_r) of one search iteration with
    ζ and the offset free (the default options), for N = ``n`` samples and m = ``m`` modes.

    Φ = [e^{−σt}cos ω_dt, e^{−σt}sin ω_dt, 1] (σ = ζω, ω_d = ω√(1 − ζ²)); c from the column-scaled normal
    equations (CasADi's ``ldl`` linear solver); Jₙ's columns t·(Re pᵢ Re fⱼ − Im pᵢ Im fⱼ) with the chain
    rule's factors f = α(ζ − j√(1 − ζ²)) for ω and α(ω + jωζ/√(1 − ζ²)) for ζ, α = A − jB (the docstring
    of :meth:`methods.pem.SeparableModel.reduced_jacobian`); J_r = Jₙ − Φ(ΦᵀΦ)⁻¹ΦᵀJₙ."""
    x, y, t = ca.MX.sym("x", 2 * m), ca.MX.sym("y", n), ca.MX.sym("t", n)
    w, z = x[:m], x[m:]
    r = ca.sqrt(1 - z * z)
    T = ca.repmat(t, 1, m)
    E = ca.exp(-ca.mtimes(t, (z * w).T))
    C, S = E * ca.cos(ca.mtimes(t, (w * r).T)), E * ca.sin(ca.mtimes(t, (w * r).T))
    phi = ca.horzcat(C, S, ca.MX.ones(n, 1))
    H = ca.mtimes(phi.T, phi)
    norms = ca.sqrt(ca.diag(H))
    Hs = H / ca.mtimes(norms, norms.T)
    c = ca.solve(Hs, ca.mtimes(phi.T, y) / norms, "ldl") / norms
    e = y - ca.mtimes(phi, c)
    a, b = c[:m], c[m:2 * m]

    def columns(f_re, f_im):
        return T * (C * ca.repmat(f_re.T, n, 1) - S * ca.repmat(f_im.T, n, 1))

    jn = ca.horzcat(columns(a * z - b * r, -a * r - b * z), columns(a * w + b * w * z / r, a * w * z / r - b * w))
    scale = ca.repmat(norms, 1, 2 * m)
    jr = jn - ca.mtimes(phi, ca.solve(Hs, ca.mtimes(phi.T, jn) / scale, "ldl") / scale)
    # (the caller's working directory gets the C file and the library; the caller removes them)
    opts = {"jit": True, "compiler": "shell", "jit_cleanup": False,
            "jit_options": {"flags": ["-O3"], "verbose": False, "cleanup": False}} if jit else {}
    return ca.Function("pem_iteration", [x, y, t], [c, e, ca.dot(e, e) / n, ca.mtimes(jr.T, jr),
                                                    ca.mtimes(jr.T, e), jr], opts)


def _buffered(fn: ca.Function, x: np.ndarray, y: np.ndarray, t: np.ndarray):
    """``fn`` bound to numpy buffers (``Function.buffer``): (call, outputs). The closure keeps the buffer
    object alive; CasADi reads and writes the arrays in place."""
    buf, call = fn.buffer()
    outs = [np.zeros(fn.nnz_out(i)) for i in range(fn.n_out())]
    args = [np.ascontiguousarray(v, dtype=float) for v in (x, y, t)]
    for i, v in enumerate(args):
        buf.set_arg(i, memoryview(v))
    for i, v in enumerate(outs):
        buf.set_res(i, memoryview(v))
    keep = (buf, args)

    def run():
        call()
        return keep

    return run, outs


def _rows(n: int, jit: bool):
    """{row: (iteration fn returning its NormalEquations or None, build seconds)} at pem's optimum on
    ``pem_speed.record(n)``."""
    y = pem_speed.record(n)
    fit = pem.identify(y, DT_S, pem_speed.PRIOR)
    m = fit.frequencies.size
    x = np.r_[fit.frequencies, fit.extra["damping"]]
    p = 4 * m + 1                                  # every unknown free: ω, ζ, x₀, b
    model = pem.SeparableModel(y, DT_S, m, True, 0.0)

    def numpy_iteration():
        c, e, loss, solver = model.fit(x[:m], x[m:])
        jr = model.reduced_jacobian(x[:m], x[m:], c, solver, True)
        system = search.NormalEquations(None, None, (jr.T @ jr, jr.T @ e, loss * n, n - p + 2 * m))
        system.step(0.0)
        return system

    rows = {"numpy (methods.pem, as shipped)": (numpy_iteration, 0.0)}
    for label, compiled in [("CasADi MX Function", False)] + ([("CasADi MX Function, JIT C (gcc -O3)", True)]
                                                                if jit else []):
        t0 = time.perf_counter()
        # the JIT writes its C file and library to the working directory: a scratch one, removed here
        # (the loaded library outlives its file)
        with tempfile.TemporaryDirectory() as scratch, contextlib.chdir(scratch):
            fn = iteration_function(n, m, compiled)
            run, outs = _buffered(fn, x, y, np.arange(n) * DT_S)
            run()
        build = time.perf_counter() - t0

        def casadi_iteration(run=run, outs=outs):
            run()
            system = search.NormalEquations(None, None, (outs[3].reshape(2 * m, 2 * m), outs[4],
                                                         outs[2][0] * n, n - p + 2 * m))
            system.step(0.0)
            return system

        rows[label + " + normal equations"] = (casadi_iteration, build)
        rows[label + " alone"] = (run, build)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-samples", type=int, nargs="+", default=[256, 2048])
    ap.add_argument("--repeats", type=int, default=40)
    ap.add_argument("--jit", action="store_true", help="also the Function compiled to C (needs a C compiler)")
    args = ap.parse_args(argv)
    if args.repeats < 1 or min(args.n_samples) < 64:
        print(f"error: --repeats {args.repeats} must be ≥ 1 and --n-samples {args.n_samples} ≥ 64 (the "
              "search's fast path needs determined modes)", file=sys.stderr)
        return 2
    print("| N | iteration | µs CPU | / numpy | build ms | agree: GN step (std), std (rel.) |")
    print("|---|---|---|---|---|---|")
    for n in args.n_samples:
        rows = _rows(n, args.jit)
        times = {label: [] for label in rows}
        for _ in range(args.repeats):
            for label, (fn, _) in rows.items():
                t0 = time.thread_time()
                for _ in range(ROUND):
                    fn()
                times[label].append((time.thread_time() - t0) / ROUND)
        med = {label: statistics.median(v) for label, v in times.items()}
        base_label = next(iter(rows))
        ref = rows[base_label][0]()
        for label, (fn, build) in rows.items():
            system = fn()
            agree = "—"
            if isinstance(system, search.NormalEquations):
                step = np.max(np.abs(system.step(0.0) - ref.step(0.0)) / ref.std)
                agree = f"{step:.1e}, {np.max(np.abs(system.std / ref.std - 1)):.1e}"
            print(f"| {n} | {label} | {1e6 * med[label]:.0f} | {med[label] / med[base_label]:.2f} | "
                  f"{1e3 * build:.0f} | {agree} |")
    return 0


if __name__ == "__main__":
    from experiments.benchmarks import one_blas_thread, run_with_page

    with one_blas_thread():
        raise SystemExit(run_with_page(main, "pem_casadi"))   # prints, and writes results/bench/pem_casadi.md
