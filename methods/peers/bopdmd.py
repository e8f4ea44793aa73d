"""Optimized DMD by variable projection (``pydmd.BOPDMD``) on the record's delay embedding.

``pydmd.BOPDMD`` fits continuous-time exponentials to the snapshots by variable projection (a nonlinear
least-squares fit of eigenvalues and amplitudes), which removes the noise bias of exact DMD. The eigenvalues
are continuous-time poles s, constrained to conjugate pairs (the record is real) and to the left half-plane
(the record is a free decay; without it, variable projection on a short noisy record can diverge to
eigenvalues with Re s ~ 10⁴ whose exponentials overflow, and LAPACK's least squares on the resulting
inf/NaN never returns — seen at 10 µg, N = 20), and :func:`methods.peers._mode_picker.pick_modes` picks
the m modes.

What the library is given (``start: dmd``, the default): the d × (N − d + 1) delay embedding in the
coordinates of its r leading left singular vectors (ARPACK, :func:`methods.peers.hdmd.leading_subspace`;
the projection BOPDMD makes itself, without its two full SVDs), the start s₀ = log(λ)/Δt of the exact
DMD of those snapshots (Hankel DMD's poles), and pydmd's stall test ``eps_stall``: stop when an iteration
lowers the relative residual by less than this fraction (1e-4, chosen on design seed 7 against 1e-3 and
pydmd's 1e-12; docs/notes/sweep-cost.md), and Kaufman's approximation of the variable projection's Jacobian
(``full_jacobian: false``, pydmd's ``use_fulljac``; Kaufman 1975, the Golub–Pereyra Jacobian without its second
term, which pydmd builds with an extra sparse product per eigenvalue per iteration): a quarter to a third less
CPU, the same median RMSE/CRLB and failures on design seed 7 (every cell of the full grid, R = 10; the
full Jacobian is ``full_jacobian: true``). pydmd's own start (``start: trapezoid``: the
record through ``pydmd.preprocessing.hankel_preprocessing``) is a trapezoidal-rule DMD whose Tustin map
warps the frequencies, and with pydmd's ``eps_stall`` = 1e-12 every fit ran its 30 iterations, the last
~20 creeping along the noise floor (the relative residual changing by ~1e-5 per step).

Settings (methods/peers/README.md): rank 2m + 1 + ``extra_order``, d = ``delays_fraction``·N delays,
chosen on tuning seed 1 (never the scoring seed). Uncertainty: with ``num_trials`` > 0 BOPDMD bags
(refits on random subsets of ``trial_size`` of the snapshots) and ``std`` is the library's spread of the
picked eigenvalue, |std(s)|, over the bags — the library's own uncertainty, not a calibrated one; with
``num_trials`` = 0 (the default: plain optimized DMD, 3–10× faster) ``std`` is NaN.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from methods.peers import hdmd
from methods.peers._mode_picker import check_peer_options, identify_peer, too_short

__all__ = ["Options", "STARTS", "check_options", "identify"]

STARTS = ("dmd", "trapezoid")


@dataclass
class Options(hdmd.Options):
    # extra_order (1) and delays_fraction (0.5, delays d / N) as hdmd's, tuned on seed 1
    rows_periods: float | None = 2.0  # delays capped at two of the prior's longest periods (_hankel)
    num_trials: int = 0              # BOPDMD bags; > 0 gives the library's eigenvalue std
    trial_size: float = 0.6          # fraction of the snapshots per bag
    seed: int = 0                    # numpy's global seed for the bags (pydmd draws from np.random)
    start: str = "dmd"               # eigenvalues the variable projection starts from: "dmd" or "trapezoid"
    eps_stall: float = 1e-4          # pydmd's stall test (its default 1e-12), chosen on design seed 7
    full_jacobian: bool = False      # pydmd's use_fulljac: False is Kaufman's Jacobian, chosen on design seed 7

    def check(self) -> None:
        super().check()
        if self.num_trials < 0:
            raise ValueError(f"num_trials = {self.num_trials} must be ≥ 0")
        if self.start not in STARTS:
            raise ValueError(f"start = {self.start!r} must be one of {', '.join(map(repr, STARTS))}")
        if not 0 <= self.eps_stall < 1:
            raise ValueError(f"eps_stall = {self.eps_stall} must be in [0, 1)")
        if not isinstance(self.full_jacobian, bool | np.bool_):
            raise ValueError(f"full_jacobian = {self.full_jacobian!r} must be true or false")


def check_options(prior, dt, **options) -> Options:
    """The options contract of :mod:`methods`: every check that needs no record, before any work."""
    return check_peer_options(Options, options, "bopdmd")


def _dmd_start(X: np.ndarray, dt: float) -> np.ndarray:
    """Initial continuous-time eigenvalues for ``pydmd.BOPDMD``: log(λ)/Δt of the exact DMD of the projected
    delay snapshots X (r × M), Ã = X₂X₁⁺ (least squares) — Hankel DMD's poles, the noise bias included.
    Written here because pydmd's own start is a trapezoidal-rule (Tustin) DMD, whose map
    s = (2/Δt)(λ − 1)/(λ + 1) warps every frequency (by 8 % at ωΔt = 0.9), and the variable projection then
    spent about ten of its iterations getting back (relative error 0.70 at the start against 1e-4 after:
    100 µg, N = 1024)."""
    A = np.linalg.lstsq(X[:, :-1].T, X[:, 1:].T, rcond=None)[0].T
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = np.log(np.linalg.eigvals(A).astype(complex)) / dt
    # a pole at z = 0 has no continuous-time image: a fast decay instead, which the constraints keep stable
    return np.where(np.isfinite(alpha), alpha, -1.0 / dt)


def _fit(y, dt, prior, opts: Options):
    d, order = hdmd.delays_and_order(y.size, prior, dt, opts)
    if order < 2 * prior.size:
        return too_short(prior, y.size, "BOPDMD")
    from pydmd import BOPDMD  # optional extra (.[peers])
    from pydmd.preprocessing import hankel_preprocessing  # optional extra (.[peers])

    varpro = {"eps_stall": opts.eps_stall, "use_fulljac": bool(opts.full_jacobian)}
    settings = dict(svd_rank=order, eig_constraints={"stable", "conjugate_pairs"}, num_trials=opts.num_trials,
                    trial_size=opts.trial_size, varpro_opts_dict=varpro)
    t = np.arange(y.size - d + 1) * dt
    if opts.start == "dmd":
        # the delay embedding projected on its r leading left singular vectors (the basis BOPDMD would
        # compute with two full SVDs; ARPACK's here), fitted in those coordinates (identity basis)
        H = hdmd.delay_embedding(y, d)
        U = hdmd.leading_subspace(H, order, shifted=False)
        if U is None:
            U = np.linalg.svd(H, full_matrices=False)[0][:, :order]
        X = U.T @ H
        dmd = BOPDMD(proj_basis=np.eye(order), init_alpha=_dmd_start(X, dt), **settings)
    else:                                            # pydmd's own path, its trapezoidal-rule start
        dmd, X = hankel_preprocessing(BOPDMD(**settings), d=d), y[None, :]
    if opts.num_trials:
        np.random.seed(opts.seed)  # noqa: NPY002 - pydmd draws its bags from numpy's global generator
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dmd.fit(X, t=t)
    s = np.asarray(dmd.eigs, dtype=complex)
    est = opts.estimate(s, y, dt, prior, order=order, delays=d)
    if opts.num_trials and dmd.eigenvalues_std is not None:
        spread = np.abs(np.asarray(dmd.eigenvalues_std))
        std = np.array([spread[np.argmin(np.abs(np.abs(s) - w))] if np.isfinite(w) else np.nan
                        for w in est.frequencies])
        est = type(est)(est.frequencies, std, converged=est.converged, message=est.message, extra=est.extra)
    return est


def identify(y, dt, prior, **options):
    """Frequencies of the m most energetic physical poles of an optimized DMD of the record."""
    return identify_peer(check_options, _fit, y, dt, prior, options)
