"""Does the model explain the record? The residual's whiteness, and a std that survives a wrong noise model.

Two questions about a fit's residual ε (N samples, p free unknowns):

**Is ε white?** (:func:`residual_check`)

- Ljung–Box portmanteau test on the first h = min(10, N/5) autocorrelations ρ̂ₖ of ε,

      Q = N(N + 2) Σₖ₌₁ʰ ρ̂ₖ² / (N − k)  ~  χ²_h  under white noise,

  with ρ̂ₖ less its expectation for the residual of a fit to white noise (:func:`fitted_autocorrelation`);

- the periodogram Pⱼ = |Σₖ εₖ e^{−2πijk/N}|²/N against the white-noise floor σ̂²_w = median(P)/ln 2 (for
  white noise Pⱼ/σ² is exponential with mean 1, whose median is ln 2; the median ignores a few peaks):
  the largest of the M = N/2 − 1 ratios Pⱼ/σ̂²_w exceeds ln(M/α) with probability ≈ α (F(2, ν) in place of
  the exponential, for the estimated floor: :func:`residual_check`);
- ``variance_ratio`` = var(ε)/σ̂²_w: 1 for white noise, above 1 when the residual's power sits in a few
  bands (coloured noise, an unmodelled mode, a drifting frequency);
- ``white``: both tests pass at level α each.

**Only a band** (``band_rad_s``). A decimated record's noise is white only in the anti-alias filter's pass
band: above it the filter's roll-off and the aliases halve the noise power at the new Nyquist frequency, and
Ljung–Box reads that as colour. Given the band's top ω_b, both tests judge the residual's content below it
only: the rfft bins j ≤ K = ⌊ω_b N dt/2π⌋ resynthesised as a record of N' = 2K samples (Fourier
resampling to the rate 2ω_b, :func:`band_limited`), in which noise white in the band is white; the fit's
basis is resampled alike. A residual coloured inside the band still fails.

Hand-written with ``scipy.special.chdtrc`` (the χ² survival function) rather than statsmodels'
``acorr_ljungbox``: the statistic is the one line above, and statsmodels (with patsy) would be a large
dependency for it.

**A model-robust std** (:func:`sandwich_std`). The white-noise covariance σ̂²(JᵀJ)⁻¹ assumes ε white with
constant variance. The sandwich with a Newey–West (Bartlett-kernel) estimate of the scores' long-run
covariance does not:

    Cov(θ̂) = (JᵀJ)⁻¹ S (JᵀJ)⁻¹ · N/(N − p),
    S = Γ₀ + Σₗ₌₁ᴸ (1 − l/(L + 1)) (Γₗ + Γₗᵀ),   Γₗ = Σₖ gₖ gₖ₋ₗᵀ,   gₖ = Jₖᵀ εₖ,

with the bandwidth L from Andrews' (1991) AR(1) plug-in rule for the Bartlett kernel,
L = 1.1447 (α̂ N)^{1/3}, α̂ = 4ρ̂²/((1 − ρ̂)²(1 + ρ̂)²), ρ̂ the residual's lag-1 autocorrelation (L ≤ N/4).
O(N p L) here (L products of N × p matrices); statsmodels' ``cov_hac`` computes the same thing but needs
the full regression result object. For the variable-projection fit J is Kaufman's reduced Jacobian
P⊥∂ε/∂(ω, ζ): the (ω, ζ) rows of the full (JᵀJ)⁻¹Jᵀ are exactly (J_rᵀJ_r)⁻¹J_rᵀ (partitioned inverse), so
the sandwich on J_r is the (ω, ζ) block of the full one.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import scipy.ndimage
import scipy.special

from methods.pem.predictor import modal_basis, symmetric_eigh

ALPHA = 0.001           # level of each whiteness test (measured false alarms on white records: see README)
MAX_LB_LAGS = 10        # Ljung–Box lags: min(10, N/5) (the common default, e.g. statsmodels')
_LAGS = np.arange(1.0, MAX_LB_LAGS + 1)


def autocorrelation(e: np.ndarray, lags: int) -> np.ndarray:
    """ρ̂ₖ = Σ ε̃ᵢε̃ᵢ₊ₖ / Σ ε̃ᵢ², k = 1…lags, ε̃ = ε − mean(ε) (the biased estimator; FFT, O(N log N))."""
    x = np.asarray(e, float) - np.mean(e)
    n = x.size
    spec = np.fft.rfft(x, 2 * n)
    acov = np.fft.irfft(spec * spec.conj(), 2 * n)[:lags + 1]
    return acov[1:] / acov[0] if acov[0] > 0 else np.zeros(lags)


def fitted_autocorrelation(basis: np.ndarray, lags: int, gram_inverse: np.ndarray | None = None) -> np.ndarray:
    """E[ρ̂ₖ] of a fit's residual under white noise, k = 1…lags: ε = (I − P)n with P the projection on the
    p columns of ``basis`` (the model's tangent space), so E[ε̃ᵢε̃ᵢ₊ₖ] = −σ²Σᵢ Pᵢ,ᵢ₊ₖ and
    E[ρ̂ₖ] ≈ −Σᵢ Pᵢ,ᵢ₊ₖ/(N − p): the fit removes a band around every mode, which a plain Ljung–Box reads as
    colour (measured on white 256-sample plant records: 4.7 % below p = 0.01 without this correction).

    With P = B G⁻¹Bᵀ, G = BᵀB, Σᵢ Pᵢ,ᵢ₊ₖ = Σᵢ aᵢ·bᵢ₊ₖ with the rows aᵢ of A = B G⁻¹: ``lags`` (≤ 10) lagged
    dot products, O(N p) each (one BLAS dot of contiguous rows each). G⁻¹ from the eigendecomposition
    of the column-scaled G (a p × p problem, :func:`methods.pem.predictor.symmetric_eigh`) where its
    condition number is below 1e10 (B's below 1e5: the error of Σ stays ~1e-6 relative, and E[ρ̂ₖ] is a
    correction of ~1e-2); otherwise (a nearly rank-deficient basis) A = Q from ``numpy.linalg.qr``, P = QQᵀ.
    At N = 256, p = 17 this is a third of a Householder QR with ten separate products. ``gram_inverse``:
    G⁻¹ when the caller already has it (a fit's factorisations, :func:`tangent_gram_inverse`): A = B G⁻¹
    without the Gram and its eigendecomposition."""
    basis = np.asarray(basis, float)
    n, p = basis.shape
    a = None
    if gram_inverse is not None:
        a, b = basis @ gram_inverse, basis
    else:
        norms = np.sqrt(np.einsum("ij,ij->j", basis, basis))
        if p <= n and norms.min() > 0 and np.isfinite(norms).all():
            lam, V = symmetric_eigh((basis.T @ basis) / np.multiply.outer(norms, norms))
            if lam[0] > 1e-10 * lam[-1]:
                a, b = basis @ _unscaled_inverse(norms, lam, V), basis
    if a is None:
        a = b = np.linalg.qr(basis)[0]
        p = a.shape[1]
    # Σᵢ aᵢ·bᵢ₊ₖ: rows 0…N−k−1 of A against rows k…N−1 of B, both C-ordered, so each is one BLAS dot
    # of two contiguous (N − k)·p vectors, sliced from the flattened buffers (a[:N − k].ravel() and
    # b[k:].ravel() without their two calls a lag)
    a, b = np.ascontiguousarray(a).ravel(), np.ascontiguousarray(b).ravel()
    lagged = np.array([np.dot(a[:(n - k) * p], b[k * p:]) for k in range(1, lags + 1)])
    return -lagged / max(n - p, 1)


def _median(x: np.ndarray) -> float:
    """``numpy.median`` of a 1-D array, the same value (the middle one, or the mean of the two middle ones),
    through one ``numpy.partition``: a tenth of the wrapper's time on the ~100 bins of a short record."""
    k = x.size // 2
    part = x.copy()                                   # numpy.partition's copy, without its wrapper
    if x.size % 2:
        part.partition(k)
        return float(part[k])
    part.partition((k - 1, k))
    return float((part[k - 1] + part[k]) / 2.0)


def band_limited(x: np.ndarray, dt: float, band_rad_s: float | None) -> tuple[np.ndarray, float]:
    """(x', dt'): the content of ``x`` (along axis 0) below ``band_rad_s`` as a record sampled at twice that
    frequency — its rfft bins 0…K, K = ⌊band·N·dt/2π⌋, inverse-transformed to N' = 2K samples, scaled so
    that each bin's periodogram value |X_j|²/N is kept (the same noise floor in the same units); dt' =
    dt·N/N', so bin j is the same frequency 2πj/(N dt). ``x`` as it is (and dt) when the band reaches
    Nyquist or is None, or leaves fewer than 10 samples."""
    x = np.asarray(x, float)
    n = x.shape[0]
    if band_rad_s is None:
        return x, dt
    k = int(math.floor(float(band_rad_s) * n * dt / (2 * np.pi)))
    if 2 * k >= n - 1 or 2 * k < 10:
        return x, dt
    spec = np.fft.rfft(x, axis=0)[:k + 1]
    m = 2 * k
    return np.fft.irfft(spec, m, axis=0) * math.sqrt(m / n), dt * n / m


def residual_check(e, dt: float, alpha: float = ALPHA, basis=None, band_rad_s: float | None = None,
                   gram_inverse=None, spectrum=None) -> dict:
    """Whiteness of a residual: Ljung–Box, the periodogram's largest peak against the floor, the variance
    ratio and the verdict (see the module docstring for the equations).

    Parameters
    ----------
    e : array_like, shape (N,)
        The fit's residual (prediction errors), m/s².
    dt : float
        Sample interval, s (gives the peak's frequency in rad/s).
    alpha : float
        False-alarm rate of each test on a white residual.
    basis : array_like, shape (N, p), optional
        Columns spanning the fit's tangent space (its Jacobian): the Ljung–Box statistic is then taken on
        ρ̂ₖ − E[ρ̂ₖ] (:func:`fitted_autocorrelation`).
    band_rad_s : float, optional
        Judge only the residual's content below this frequency (:func:`band_limited`): a decimated
        record's pass band. None: up to Nyquist.
    gram_inverse : array_like, shape (p, p), optional
        (BᵀB)⁻¹ of ``basis`` when the caller has it (:func:`fitted_autocorrelation`); ignored with a band
        (the band-limited basis has another Gram).
    spectrum : array_like, shape (N + 1,), optional
        ``numpy.fft.rfft(e, 2N)`` when the caller has it (pem's acceptance test): its even bins are the
        N-point DFT of ε, which the centring changes in bin 0 only, so the periodogram is read from it
        without a transform of its own; ignored with a band.

    Returns
    -------
    dict
        ``white`` (bool), ``ljung_box_q``, ``ljung_box_lags``, ``ljung_box_p``, ``noise_floor_m_s2``
        (σ̂_w), ``variance_ratio``, ``peak_over_floor``, ``peak_over_neighbours`` (the peak against the
        median of its ±max(8, N/64) neighbouring bins: large for a line, not for a broad hump),
        ``peak_threshold``, ``peak_rad_s``, ``band_rad_s`` (the top of the band judged, None: all).

    Notes
    -----
    The peak threshold allows for the floor being estimated: Pⱼ/σ̂²_w is F(2, ν)-distributed with
    ν ≈ 0.96M (the median of M exponentials has relative variance 1/(M ln²2) ≈ 2/ν), and the largest of M
    exceeds x = (ν/2)((M/α)^{2/ν} − 1) — where F(2, ν)'s survival (1 + 2x/ν)^{−ν/2} is α/M — with probability ≈ α.
    """
    e = np.asarray(e, float)
    n = e.size
    if n < 10 or not np.isfinite(e).all():
        raise ValueError(f"a residual of {n} samples (finite: {bool(np.isfinite(e).all())}) cannot be tested")
    band = None
    if band_rad_s is not None:
        e, dt_band = band_limited(e, dt, band_rad_s)
        if e.size != n:
            band = float(np.pi / dt_band)              # the top of what is judged: the bins kept
            if basis is not None:
                basis = band_limited(np.asarray(basis, float), dt, band_rad_s)[0]
                gram_inverse = None
        dt, n = dt_band, e.size
    if spectrum is not None and (band is not None or len(spectrum) != n + 1):
        spectrum = None                                # (another residual's, or the band-limited one's)
    h = max(1, min(MAX_LB_LAGS, n // 5))
    x = e - e.sum() / n                               # e.mean()'s value (the same sum and division)
    # the autocovariance at lags 0…h (≤ 10) as h + 1 dot products, O(hN): cheaper than the zero-padded
    # transforms at every N; the periodogram from the N-point DFT of the centred residual (bins 1…⌊(N−1)/2⌋:
    # no DC, no Nyquist), or from the even bins of the caller's 2N-point transform of ε (bin 2j is frequency
    # 2πj/N, and the centring changes bin 0 only)
    acov = np.array([float(x[:n - k] @ x[k:]) for k in range(h + 1)])
    if spectrum is None:
        power = np.abs(np.fft.rfft(x)[1:(n - 1) // 2 + 1]) ** 2 / n
    else:
        power = np.abs(spectrum[2:2 * ((n - 1) // 2) + 1:2]) ** 2 / n
    variance = float(acov[0] / n)
    del x
    rho = acov[1:] / acov[0] if acov[0] > 0 else np.zeros(h)
    if basis is not None:
        rho = rho - fitted_autocorrelation(np.asarray(basis, float), h, gram_inverse)
    q = float(n * (n + 2) * (rho ** 2 / (n - _LAGS[:h])).sum())
    p_lb = float(scipy.special.chdtrc(float(h), q))   # χ²_h survival (scipy.stats.chi2.sf, without its overhead;
                                                      # h as the double the ufunc takes: no type resolution)
    floor = float(_median(power) / math.log(2.0))
    if floor > 0:
        ratio = power / floor
        j = int(np.argmax(ratio))
        peak, var_ratio = float(ratio[j]), variance / floor
        # the same peak against its neighbourhood (±K bins, the peak's ±1 left out): a line stands out of
        # it, a broad hump of coloured noise does not
        k = max(8, n // 64)
        near = np.concatenate((power[max(j - k, 0):max(j - 1, 0)], power[j + 2:j + k + 1]))
        local = float(_median(near) / math.log(2.0)) if near.size else floor
        peak_local = float(power[j] / local) if local > 0 else np.inf
    else:                                   # a residual at rounding level: nothing left to explain
        j, peak, var_ratio, peak_local = 0, 0.0, 1.0, 0.0
    bins = max(power.size, 1)
    nu = max(0.96 * bins, 2.0)
    threshold = float(nu / 2 * ((bins / alpha) ** (2 / nu) - 1))     # F(2, ν) survival (1 + 2x/ν)^(−ν/2) = α/M
    return {"white": bool(p_lb >= alpha and peak <= threshold), "ljung_box_q": q, "ljung_box_lags": h,
            "ljung_box_p": p_lb, "noise_floor_m_s2": math.sqrt(max(floor, 0.0)), "variance_ratio": var_ratio,
            "peak_over_floor": peak, "peak_over_neighbours": peak_local, "peak_threshold": threshold,
            "peak_rad_s": float(2 * np.pi * (j + 1) / (n * dt)), "band_rad_s": band}


def bartlett_bandwidth(e: np.ndarray) -> int:
    """Andrews' (1991) AR(1) plug-in bandwidth for the Bartlett kernel, L = ⌈1.1447 (α̂N)^{1/3}⌉ with
    α̂ = 4ρ̂²/((1 − ρ̂)²(1 + ρ̂)²) and ρ̂ the lag-1 autocorrelation (clipped to ±0.97); 1 ≤ L ≤ N/4."""
    n = e.size
    rho = float(np.clip(autocorrelation(e, 1)[0], -0.97, 0.97))
    a = 4 * rho ** 2 / ((1 - rho) ** 2 * (1 + rho) ** 2)
    return int(min(max(math.ceil(1.1447 * (a * n) ** (1 / 3)), 1), max(n // 4, 1)))


def sandwich_std(J, e, n_params: int | None = None, bandwidth: int | None = None) -> tuple[np.ndarray, int]:
    """Newey–West sandwich std of the unknowns of J: √diag((JᵀJ)⁻¹ S (JᵀJ)⁻¹ · N/(N − p)).

    Parameters
    ----------
    J : array_like, shape (N, q)
        ∂ε/∂θ at the optimum (or the reduced Jacobian of a separable fit).
    e : array_like, shape (N,)
        The residual at the optimum.
    n_params : int, optional
        p of the degrees-of-freedom factor N/(N − p) (all free unknowns of the fit); default q.
    bandwidth : int, optional
        L; default :func:`bartlett_bandwidth` of ``e``.

    Returns
    -------
    std : ndarray, shape (q,)
        NaN for a column the record does not determine.
    bandwidth : int
        The L used.
    """
    J, e = np.asarray(J, float), np.asarray(e, float)
    n, q = J.shape
    if e.shape != (n,):
        raise ValueError(f"residual of shape {e.shape} does not match a Jacobian of {n} rows")
    L = bartlett_bandwidth(e) if bandwidth is None else int(bandwidth)
    g = J * e[:, None]
    S = g.T @ g
    for lag in range(1, min(L, n - 1) + 1):
        gamma = g[lag:].T @ g[:-lag]
        S += (1.0 - lag / (L + 1.0)) * (gamma + gamma.T)
    return _sandwich(J, S, n_params), L


def assess_fit(fit: dict, slot: np.ndarray, n_params: int, dt: float, alpha: float = ALPHA,
               band_rad_s: float | None = None) -> dict | None:
    """:func:`residual_check` of a pem fit's residual and the robust std of its frequencies in prior order
    (``slot`` as in ``methods.pem._fit._label_modes``); None when the fit kept no residual or Jacobian (a
    failed start). When the residual is not white, ``robust_std_rad_s`` is the larger of
    :func:`sandwich_std` (``hac_std_rad_s``) and :func:`spectral_sandwich_std` (``spectral_std_rad_s``);
    a white residual's check carries no robust std (the white-noise one is honest there, and the two
    sandwiches would double the estimate's cost). The Jacobian is the fast path's reduced one
    (``fit["Jr"]``) or the reference search's full one (``fit["J"]``); ω is its first m columns either way.
    ``band_rad_s``: the whiteness is judged below it only (:func:`residual_check`); the robust std uses the
    whole residual."""
    e = fit.get("e")
    J = fit.get("Jr") if fit.get("Jr") is not None else fit.get("J")
    m = slot.size
    if e is None or J is None or e.size < 10 or J.shape[1] < m or not (np.isfinite(e).all()
                                                                     and np.isfinite(J).all()):
        return None
    inverse = None
    if fit.get("Jr") is not None:          # the tangent space: the modal basis and the reduced Jacobian
        phi = fit.get("basis")             # the fast search's own Φ at the optimum (its column order), if kept
        interleaved = phi is None or phi.shape[1] != 2 * m + 1
        if interleaved:
            th = fit["theta"]
            phi = modal_basis(th[:m], th[m:2 * m], dt, e.size)
        basis = np.column_stack([phi, J])
        del phi                            # (N × (2m + 1): not held through the check)
        inverse = tangent_gram_inverse(fit, m, interleaved)
    else:
        basis = J
    check = residual_check(e, dt, alpha, basis, band_rad_s, inverse, fit.get("spectrum_2n"))
    if check["white"]:          # the white-noise std is the honest one: the sandwich is not needed (cost)
        return check
    std, bandwidth = sandwich_std(J, e, n_params)
    spectral = spectral_sandwich_std(J, e, n_params, basis=basis)
    # the larger of two kernel estimates: the lag window copes with a residual whose size changes over the
    # record (clipping, a decaying mismatch), the tapered spectrum with strong lines away from the modes
    robust = np.fmax(std, spectral)
    check.update(robust_std_rad_s=robust[:m][slot], hac_std_rad_s=std[:m][slot], hac_bandwidth=bandwidth,
                 spectral_std_rad_s=spectral[:m][slot])
    return check


def tangent_gram_inverse(fit: dict, m: int, interleaved: bool = True) -> np.ndarray | None:
    """(BᵀB)⁻¹ of the fast path's tangent space B = [Φ, J_r] (Φ in :func:`modal_basis`'s column order, or
    with ``interleaved`` False in the search's own: the m cosines, the m sines, then 1) from the
    factorisations its search already made at the optimum, or None (the caller then forms BᵀB).

    J_r = P⊥J_n is orthogonal to Φ, so BᵀB is block diagonal: (ΦᵀΦ)⁻¹ from the linear solve's
    eigendecomposition of the column-scaled ΦᵀΦ (``fit["basis_solver"]``: norms, eigenvalues, vectors; Φ's
    columns there are the m cosines, the m sines, then 1) and (J_rᵀJ_r)⁻¹ from the normal equations'
    (``fit["jr_system"]``, :meth:`methods.pem.search.NormalEquations.inverse`). Either condition number
    above 1e10 (scaled): None, as :func:`fitted_autocorrelation` would switch to a QR there."""
    solver, system = fit.get("basis_solver"), fit.get("jr_system")
    if solver is None or system is None or not system.well_conditioned:
        return None
    norms, lam, V = solver
    q = 2 * m + 1
    if V.shape[0] != q or not lam[0] > 1e-10 * lam[-1]:     # (a fit without the offset's column: the
        return None                                          # modal basis has one column more)
    out = np.zeros((q + system.size, q + system.size))
    inverse = _unscaled_inverse(norms, lam, V)
    out[:q, :q] = inverse[_interleaved(m)] if interleaved else inverse
    out[q:, q:] = system.inverse()
    return out


def _unscaled_inverse(norms: np.ndarray, lam: np.ndarray, V: np.ndarray) -> np.ndarray:
    """G⁻¹ = W Λ⁻¹ Wᵀ, W = V/norms, from the eigendecomposition V Λ Vᵀ of the column-scaled Gram
    G/(norms·normsᵀ)."""
    W = V / norms[:, None]
    return (W / lam) @ W.T


@functools.lru_cache(maxsize=32)
def _interleaved(m: int) -> tuple[np.ndarray, np.ndarray]:
    """np.ix_ of the columns of [cos₁…cosₘ, sin₁…sinₘ, 1] in :func:`modal_basis`'s order [cos₁, sin₁, …, 1]
    (made once per m)."""
    order = np.r_[np.column_stack([np.arange(m), np.arange(m, 2 * m)]).ravel(), 2 * m]
    return np.ix_(order, order)


def spectral_sandwich_std(J, e, n_params: int | None = None, half_width: int | None = None,
                          basis=None, prewhiten: bool = True) -> np.ndarray:
    """The sandwich with the meat in the frequency domain: √diag((JᵀJ)⁻¹ M (JᵀJ)⁻¹ · N/(N − p)),

        M = (1/N) Σⱼ cⱼ Re(Ĵⱼᴴ Ĵⱼ) Ŝⱼ,   Ĵⱼ = Σₖ Jₖ e^{−2πijk/N}  (rfft bins j, cⱼ = 2 but 1 at 0 and N/2),

    Ŝ the residual's spectral density: its Hann-tapered periodogram averaged over 2K + 1 bins (Daniell,
    K = ``half_width``, default max(4, N/64)). For white ε (Ŝ ≡ σ²) M = σ²JᵀJ (Parseval). A kernel HAC
    like the Newey–West one, smoothing the spectrum instead of weighting lags: J's columns for ω are narrow-band
    at the modes, so M needs the residual's spectrum there only, and the taper keeps a strong line elsewhere
    (an unmodelled mode) from leaking in, which the Bartlett lag window's sidelobes do not.

    Two corrections of Ŝ where it is read, at the modes (both measured on mode 1 of the mismatch grid, five
    bins from 0 Hz, in AR(1) noise φ = 0.9: the plain estimate was 22 % low, tests/methods/pem/
    test_pem_residual.py):

    - ``prewhiten`` (default): the residual is filtered by its AR(1) fit, 1 − φ̂z⁻¹ (φ̂ its lag-1
      autocorrelation, clipped to ±0.97), smoothed, and the smoothed periodogram divided by |1 − φ̂e^{−iωⱼ}|²
      (Andrews & Monahan 1992): averaging 2K + 1 bins of a spectrum as steep as red noise's near 0 Hz is
      biased, averaging a flattened one is not;
    - ``basis`` (N × p, the fit's tangent space): the fit removed the noise in its columns' span, which
      lies around each mode, so the residual's periodogram there is low by the share hⱼ
      (:func:`tapered_leverage`): Ŝ = P̄/(1 − h)‾, with the factor N/(N − p) then left out (it spreads the
      same p degrees of freedom evenly over all bins). None: the global factor, as without it."""
    J, e = np.asarray(J, float), np.asarray(e, float)
    n, q = J.shape
    k = max(4, n // 64) if half_width is None else int(half_width)
    x = e - e.mean()
    win = np.hanning(n + 1)[:n]                  # periodic Hann
    # prewhitened by its AR(1) fit (Andrews & Monahan 1992), smoothed, recoloured: the average over 2K + 1
    # bins of a spectrum as steep as AR(1) noise near 0 Hz is biased, of a flattened one not
    phi = float(np.clip(autocorrelation(e, 1)[0], -0.97, 0.97)) if prewhiten else 0.0
    xw = np.r_[x[0], x[1:] - phi * x[:-1]]
    power = np.abs(np.fft.rfft(xw * win)) ** 2 / (win @ win)
    colour = np.abs(1.0 - phi * np.exp(-2j * np.pi * np.arange(power.size) / n)) ** 2
    density = scipy.ndimage.uniform_filter1d(power, 2 * k + 1, mode="mirror") / colour
    if basis is not None:
        # the fit's own dof, where they are: E[Pⱼ] = S(1 − hⱼ) (locally flat S), so Ŝ = P̄/(1 − h)‾
        kept = scipy.ndimage.uniform_filter1d(1.0 - tapered_leverage(basis, win), 2 * k + 1, mode="mirror")
        density = density / np.maximum(kept, MIN_KEPT)
        n_params = 0
    c = np.full(power.size, 2.0)
    c[0] = 1.0
    if n % 2 == 0:
        c[-1] = 1.0
    F = np.fft.rfft(J, axis=0)
    M = ((F.conj().T * (c * density)) @ F).real / n
    return _sandwich(J, M, n_params)


MIN_KEPT = 0.1      # the share of a band's noise a fit may remove before its density is not read from it


def tapered_leverage(basis, win: np.ndarray) -> np.ndarray:
    """hⱼ = ‖Qᵀvⱼ‖²/‖w‖², vⱼ = w ⊙ e^{2πijk/N}, per rfft bin j: the share of the tapered periodogram's
    expected noise power at bin j that a least-squares fit on the columns of ``basis`` (orthonormal basis Q,
    ``numpy.linalg.qr``) removes, E[Pⱼ(ε)] = Sⱼ(1 − hⱼ) for a density S flat over the taper's window.
    Σⱼ hⱼ ≈ p: the frequency-domain form of the N/(N − p) factor, at the bins where the fit's columns live
    (around each mode), which a global factor spreads over all of them."""
    q = np.linalg.qr(np.asarray(basis, float))[0]
    return (np.abs(np.fft.rfft(q * win[:, None], axis=0)) ** 2).sum(axis=1) / (win @ win)


def _sandwich(J: np.ndarray, meat: np.ndarray, n_params: int | None) -> np.ndarray:
    """√diag(B·meat·B · N/(N − p)), B = (JᵀJ)⁻¹ through the column-scaled Gram matrix: ``inv`` when it is
    well conditioned (the usual case, a q × q matrix), the pseudo-inverse (eigenvalues below 1e-13 of the
    largest dropped) when not."""
    n, q = J.shape
    norms = np.sqrt(np.einsum("ij,ij->j", J, J))
    norms = np.where(norms > 0, norms, 1.0)
    G = (J.T @ J) / np.outer(norms, norms)
    lam, V = np.linalg.eigh(G)
    keep = lam > 1e-13 * lam[-1] if lam.size and lam[-1] > 0 else np.zeros(lam.size, bool)
    bread = (V * np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)) @ V.T / np.outer(norms, norms)
    p = q if n_params is None else int(n_params)
    var = np.einsum("ij,jk,ki->i", bread, meat, bread) * n / max(n - p, 1)
    return np.where(var > 0, np.sqrt(np.abs(var)), np.nan)
