"""Mode labels that never cross: which found frequency answers for which prior entry.

Every method returns one frequency per prior entry, in prior order. When it finds every mode, the answer
in prior order is the sorted one: the i-th lowest found frequency is mode i (the prior names the modes
counted from the lowest). When it finds fewer, the slots of the missing modes are unknown, and guessing them
from the distance to the prior alone crosses labels whenever the prior is off by more than half the gap of
two neighbouring modes — which a common mass or stiffness error of 20–30 % does to any pair closer than
that. This module writes the rule once; :mod:`methods.pem` and the peers' mode picker
(:mod:`methods.peers._mode_picker`) use it.

**Model of the prior.** The log of each true frequency is the log of its prior entry plus a common log
scale factor (mass or stiffness error: every mode moves alike) plus an independent error per mode,

    log ωᵢ = log pᵢ + c + uᵢ,    c ~ N(0, s_c²),    uᵢ ~ N(0, τᵢ²).

**Assignment.** The k ≤ m confident frequencies w₁ < … < w_k go to prior entries S₁ < … < S_k (an
order-preserving injection: labels never cross). With rⱼ = log wⱼ − log p_{Sⱼ} the residuals of one
injection S, the model says r ~ N(0, Σ_S), Σ_S = diag(τ_S²) + s_c² 11ᵀ, so its evidence is

    cost(S) = rᵀ Σ_S⁻¹ r + log det Σ_S,    P(S | w) ∝ exp(−cost(S)/2)

(uniform over injections). The common scale is thereby estimated from all the confident modes together
(its posterior mean ĉ = s_c² 1ᵀ Σ_S⁻¹ r is returned), and it is what places the rest: a mode at 0.7 × its
prior is matched to the entry 0.7 × away when the other found modes are also at 0.7 ×. The injection of
least cost wins. Each confident frequency is **placed** when the injections that give it the same slot
carry posterior probability ≥ 1 − ``alpha`` (0.99) and it lies within the search band of its entry
(|rⱼ| ≤ log(1 + band)); otherwise it is *not placed*: the caller flags the mode not determined instead of
guessing. With k = m there is one injection (the sorted one), and every mode is placed unless out of band.

With k = m the answer is closed: the sorted injection, probability 1, ĉ from its sums. Otherwise the m ≤ 20
of this problem make the enumeration of the C(m, k) injections cheap (≤ 184 756; made once per (m, k)); it is
done by hand (itertools) because scipy's ``linear_sum_assignment`` has no order constraint and no common scale,
and the normalisation is a log-sum-exp with the winner's cost taken out (a call of
``scipy.special.logsumexp`` per slot cost more than a whole pem fit on a 256-sample record).
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["COMMON_LOG_STD", "INDEPENDENT_LOG_STD", "ALPHA", "MAX_MODES", "Labels", "assign"]

COMMON_LOG_STD = 0.2          # s_c: a common error of ±20 % at 1σ (the paper's ~30 % a-priori uncertainty)
# τ: the prior's ratios are better known than its scale. The paper's own prior (Table 4 against Table 3) is
# off by log-factors −0.20, −0.19, −0.24, −0.07: a common −0.17 and independent +0.02, +0.03, −0.02, +0.10
INDEPENDENT_LOG_STD = 0.05
ALPHA = 0.01                  # a placement must carry posterior probability ≥ 1 − α
MAX_MODES = 20


@dataclass(frozen=True)
class Labels:
    """The answer of :func:`assign`.

    Attributes
    ----------
    slot : ndarray of int, shape (k,)
        Prior entry given to each confident frequency (in the caller's order of ``freq``).
    placed : ndarray of bool, shape (k,)
        Whether that slot is certain (probability ≥ 1 − α, within the band); False: flag not determined.
    probability : ndarray, shape (k,)
        Posterior probability of each frequency's slot.
    log_scale : float
        ĉ, the posterior mean of the common log scale factor under the winning injection (0 if k = 0).
    """

    slot: np.ndarray
    placed: np.ndarray
    probability: np.ndarray
    log_scale: float


def assign(freq, prior, *, band: float = 0.5, prior_rel_std=None, common_log_std: float = COMMON_LOG_STD,
           alpha: float = ALPHA) -> Labels:
    """Give each confident frequency a prior entry, order-preserving, with a common scale (module docstring).

    Parameters
    ----------
    freq : array_like, shape (k,)
        Frequencies the record determines, rad/s, any order, k ≤ m.
    prior : array_like, shape (m,)
        A-priori frequencies, rad/s, strictly increasing.
    band : float
        A frequency is placed only within pᵢ·(1 + band)^±1 of its entry.
    prior_rel_std : float or array_like of shape (m,), optional
        τᵢ, the independent 1σ error of each prior entry, relative (a ``prior_std_rad_s / prior``);
        default :data:`INDEPENDENT_LOG_STD`.
    common_log_std : float
        s_c, the 1σ of the common log scale factor.
    alpha : float
        A slot is placed when its posterior probability is at least 1 − alpha.

    Returns
    -------
    Labels
    """
    w = np.asarray(freq, dtype=float).reshape(-1)
    p = np.asarray(prior, dtype=float).reshape(-1)
    k, m = w.size, p.size
    if k > m:
        raise ValueError(f"{k} frequencies for {m} prior entries: at most one per entry")
    if m > MAX_MODES:
        raise ValueError(f"prior of {m} modes: at most {MAX_MODES} are supported by the enumeration")
    # the checks over the ≤ 20 values as Python floats: a pem fit calls this once or twice, and a dozen numpy
    # reductions on 4-vectors cost as much as the assignment itself
    wl, pl = w.tolist(), p.tolist()
    if not all(math.isfinite(v) and v > 0 for v in wl):
        raise ValueError(f"freq = {wl} must be positive finite frequencies")
    if not (all(b > a for a, b in zip(pl[:-1], pl[1:], strict=True)) and all(v > 0 for v in pl)):
        raise ValueError(f"prior = {pl} must be positive and strictly increasing")
    if prior_rel_std is None:
        tau, tau_ok = _default_tau(m), True
    else:
        tau = np.broadcast_to(np.asarray(prior_rel_std, float), (m,))
        tau_ok = bool((tau > 0).all())
    if not (tau_ok and common_log_std >= 0 and band > 0 and 0 < alpha < 1):
        raise ValueError(f"prior_rel_std = {tau.tolist()}, common_log_std = {common_log_std}, band = {band}, "
                         f"alpha = {alpha}: spreads and band must be positive, 0 < alpha < 1")
    t2 = tau**2
    if k == 0:
        return Labels(np.zeros(0, int), np.zeros(0, bool), np.zeros(0), 0.0)
    s2 = common_log_std**2
    if k == m:
        # closed form: one injection, the sorted one, with all the probability; only ĉ and the band remain
        # (ĉ = s² a/b of the Sherman–Morrison sums below), over the m ≤ 20 values as Python floats (the
        # sums in the same order as numpy's below eight terms)
        order = sorted(range(k), key=wl.__getitem__)                   # stable, as argsort(kind="stable")
        t2l = t2.tolist()
        r = [math.log(wl[i]) - math.log(pj) for i, pj in zip(order, pl, strict=True)]
        a = sum(ri / ti for ri, ti in zip(r, t2l, strict=True))
        b = 1.0 + s2 * sum(1.0 / ti for ti in t2l)
        reach = math.log1p(band)
        slot, placed = [0] * k, [False] * k                # the inverse permutation, as Python lists
        for j, i in enumerate(order):
            slot[i], placed[i] = j, abs(r[j]) <= reach
        return Labels(np.array(slot), np.array(placed), np.ones(k), float(s2 * a / b))
    order = np.argsort(w, kind="stable")
    lw, lp = np.log(w[order]), np.log(p)
    slot, placed, probability = np.empty(k, int), np.empty(k, bool), np.empty(k)
    slots = _injections(m, k)                                           # (n_injections, k), rows sorted
    r = lw - lp[slots]
    t2 = t2[slots]
    # Σ = D + s² 11ᵀ, D = diag(τ²): Sherman–Morrison, rᵀΣ⁻¹r = Σr²/τ² − s²(Σr/τ²)²/(1 + s²Σ1/τ²), and
    # log det Σ = Σ log τ² + log(1 + s² Σ 1/τ²)
    a = (r / t2).sum(axis=1)
    b = 1.0 + s2 * (1.0 / t2).sum(axis=1)
    cost = (r**2 / t2).sum(axis=1) - s2 * a**2 / b + np.log(t2).sum(axis=1) + np.log(b)
    best = int(cost.argmin())
    # P(S | w) ∝ exp(−(cost − cost_min)/2): the log-sum-exp with its maximum taken out by hand (every weight
    # ≤ 1, the winner's = 1: no overflow); scipy.special.logsumexp's array checks cost more than these sums.
    # A frequency's probability sums the injections that give it the winner's slot.
    weight = np.exp(-0.5 * (cost - cost[best]))
    prob = (weight @ (slots == slots[best])) / weight.sum()
    in_band = np.abs(r[best]) <= np.log1p(band)
    slot[order], placed[order], probability[order] = slots[best], (prob >= 1.0 - alpha) & in_band, prob
    return Labels(slot, placed, probability, float(s2 * a[best] / b[best]))


@functools.lru_cache(maxsize=64)
def _default_tau(m: int) -> np.ndarray:
    """τ = :data:`INDEPENDENT_LOG_STD` for each of m entries (made once per m, read-only)."""
    tau = np.full(m, INDEPENDENT_LOG_STD)
    tau.flags.writeable = False
    return tau


@functools.lru_cache(maxsize=256)
def _injections(m: int, k: int) -> np.ndarray:
    """The C(m, k) order-preserving injections of k sorted frequencies into m entries, one per row (made
    once per (m, k), read-only)."""
    slots = np.array(list(itertools.combinations(range(m), k)), dtype=int).reshape(-1, k)
    slots.flags.writeable = False
    return slots
