"""Two tests of the sine fit's noise model that the whiteness test cannot see.

1. **Variance that follows the phase** (sample-clock or aperture jitter): a
   timing error ``delta`` turns into a signal error ``A w cos(theta) delta``,
   so the residual stays white but its variance grows with ``cos^2`` of the
   phase ``theta``.  The least-squares covariance assumes one variance for
   every sample and is too small for the phase and the frequency, which the
   samples near the zero crossings (where the jitter bites) determine.
   :func:`phase_variance` regresses the squared residual on ``cos 2 theta``
   and ``sin 2 theta`` (Koenker's studentised Breusch-Pagan test: ``N R^2`` is
   chi-square with 2 degrees of freedom when the variance is constant) and
   returns the fitted variance of every sample, from which
   :func:`sandwich_covariance` gives the heteroscedasticity-consistent
   covariance ``G^-1 (A^T V A) G^-1``.  Jitter also shrinks the fitted
   amplitude by ``exp(-w^2 delta^2 / 2)`` (the mean of ``sin(theta + w
   delta)``); the ``cos 2 theta`` coefficient ``c = A^2 w^2 delta^2 / 2``
   measures it, so the amplitude is corrected by ``exp(c / A^2)``.
2. **Noise below 1/T** (1/f noise, wander): the offset's u rests on the noise
   level near 0 Hz as seen *inside* the record.  :func:`low_frequency_test`
   compares the residual's lowest Fourier bins with the level that u
   implies (``N u(offset)^2``) by a chi-square test.

References
----------
.. [1] R. Koenker, "A note on studentizing a test for heteroscedasticity",
   J. Econometrics 17 (1981) 107-112.
.. [2] H. White, "A heteroskedasticity-consistent covariance matrix estimator
   and a direct test for heteroskedasticity", Econometrica 48 (1980) 817-838.
.. [3] IEEE Std 1057-2017, 4.1 and annex on jitter (the amplitude of a
   jittered sine is reduced by ``exp(-w^2 sigma_t^2 / 2)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PhaseVariance", "phase_variance", "phase_variance_batch", "sandwich_covariance", "low_frequency_test",
           "low_frequency_power", "VARIANCE_ALPHA", "LOWFREQ_BINS"]

#: False-alarm probability of each test on white, homoscedastic noise (as the whiteness test).
VARIANCE_ALPHA = 0.01
_BLOCK = 1 << 14  # samples per block of the sandwich's weighted design (1 MiB at eight columns)
#: Fourier bins (k / T, k = 1..8) of the low-frequency test: more add little power against 1/f noise,
#: whose excess falls as 1/k (measured: 94 % of records at a 1/f corner of 20/T, as with 4 or 16 bins).
LOWFREQ_BINS = 8


@dataclass(frozen=True)
class PhaseVariance:
    """The squared residual regressed on the phase of the fitted fundamental.

    Attributes
    ----------
    statistic : float
        Koenker's ``N R^2`` (chi-square, 2 dof, under constant variance).
    limit : float
        Its ``1 - VARIANCE_ALPHA`` quantile.
    significant : bool
    mean, cos2, sin2 : float
        ``r^2 = mean + cos2 cos(2 theta) + sin2 sin(2 theta)`` (unit^2).
    u_cos2 : float
        Standard uncertainty of ``cos2``.
    variance : ndarray, shape (N,)
        Fitted variance of each sample (floored at 1 % of ``mean``).
    """

    statistic: float
    limit: float
    significant: bool
    mean: float
    cos2: float
    sin2: float
    u_cos2: float
    variance: np.ndarray


def phase_variance(resid: np.ndarray, sin_theta: np.ndarray, cos_theta: np.ndarray) -> PhaseVariance:
    """Test whether the residual variance depends on the phase of the fundamental.

    Parameters
    ----------
    resid : ndarray, shape (N,)
        Fit residuals (unit of y).
    sin_theta, cos_theta : ndarray, shape (N,)
        Sine and cosine of the fitted fundamental's phase at each sample.

    Returns
    -------
    PhaseVariance
    """
    from scipy.stats import chi2

    c2 = cos_theta * cos_theta - sin_theta * sin_theta
    s2 = 2.0 * sin_theta * cos_theta
    stat, coef, xinv, s2e = phase_variance_batch(np.asarray(resid, dtype=float)[None, :], c2, s2)
    u_c = math.sqrt(max(float(xinv[1, 1] * s2e[0]), 0.0)) if np.all(np.isfinite(xinv)) else math.nan
    lim = float(chi2.isf(VARIANCE_ALPHA, 2))
    a, c, d = (float(v) for v in coef[0])
    var = np.maximum(a + c * c2 + d * s2, 0.01 * max(a, 0.0))
    return PhaseVariance(float(stat[0]), lim, bool(stat[0] > lim), a, c, d, u_c, var)


def phase_variance_batch(resid: np.ndarray, cos2: np.ndarray, sin2: np.ndarray):
    """Koenker's test for many channels that share the regressors ``cos 2 theta``, ``sin 2 theta``.

    Parameters
    ----------
    resid : ndarray, shape (C, N)
        Residuals of C channels.
    cos2, sin2 : ndarray, shape (N,)
        The regressors (any common phase reference: the statistic does not
        depend on it, the coefficients rotate with it).

    Returns
    -------
    (statistic, coef, xtx_inv, s2e)
        ``N R^2`` per channel (C,); coefficients (C, 3) of ``1, cos2, sin2``;
        ``(X^T X)^-1`` (3, 3); residual variance of the regression per channel
        (C,): the coefficients' covariance is ``s2e xtx_inv``.
    """
    r2 = np.asarray(resid, dtype=float) ** 2
    n = r2.shape[-1]
    cos2, sin2 = np.asarray(cos2, dtype=float), np.asarray(sin2, dtype=float)
    # X = [1, cos2, sin2]: X'X and r2 X from sums and dot products of the rows (no (N, 3) copy)
    sc, ss = float(cos2.sum()), float(sin2.sum())
    xtx = np.array([[n, sc, ss], [sc, cos2 @ cos2, cos2 @ sin2], [ss, cos2 @ sin2, sin2 @ sin2]], dtype=float)
    try:
        xinv = np.linalg.inv(xtx)
    except np.linalg.LinAlgError:
        xinv = np.full((3, 3), np.nan)
    # Residuals near the float range (|r| > 1e77) overflow the fourth powers below: the statistic is then not
    # finite, and np.where gives 0 (no evidence of heteroscedasticity), so the overflow is not news to print.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        r2x = np.stack([r2.sum(axis=1), r2 @ cos2, r2 @ sin2], axis=1)
        coef = r2x @ xinv
        # Residual sum of squares without forming the (C, N) fit: |r2|^2 - b' X'X b; the sum of r2 is r2x[:, 0].
        r4 = np.einsum("ij,ij->i", r2, r2)
        rss = r4 - np.einsum("ij,jk,ik->i", coef, xtx, coef)
        tss = r4 - r2x[:, 0] ** 2 / n
        stat = np.where(np.isfinite(tss) & np.isfinite(rss) & (tss > 0), n * (1.0 - rss / tss), 0.0)
    return stat, coef, xinv, np.maximum(rss, 0.0) / max(n - 3, 1)


def sandwich_covariance(design: np.ndarray, ginv: np.ndarray, variance: np.ndarray, n_params: int) -> np.ndarray:
    """``G^-1 (A^T V A) G^-1`` with ``V = diag(variance)``, scaled by ``N / (N - p)``.

    Parameters
    ----------
    design : ndarray, shape (N, p)
    ginv : ndarray, shape (p, p)
        ``(A^T A)^-1``.
    variance : ndarray, shape (N,)
        Variance of each sample (unit^2).
    n_params : int
        Parameters fitted (the residual-based variance is rescaled for them, as the white formula is).
    """
    n = design.shape[0]
    # in blocks of samples: the weighted copy of the design stays in cache instead of a second (N, p) array
    # (64 MB at a million samples and eight columns)
    meat = np.zeros((design.shape[1], design.shape[1]))
    for s in range(0, n, _BLOCK):
        d = design[s:s + _BLOCK]
        meat += (d * variance[s:s + _BLOCK, None]).T @ d
    cov = ginv @ meat @ ginv * (n / max(n - n_params, 1))
    return 0.5 * (cov + cov.T)


def low_frequency_power(resid: np.ndarray, bins: int = LOWFREQ_BINS) -> np.ndarray:
    """``sum_{k=1..K} I_k`` of the residual periodogram, per channel (rows of ``resid``), unit^2.

    The K bins are ``X_k = sum_i r_i exp(-2 pi j k i / N)``. With ``i = m L + l`` the kernel factors,
    ``exp(-2 pi j k l / N) exp(-2 pi j k m L / N)``, so the record reshaped to (M, L) is multiplied by an
    (L, 2K) table (one matrix product over the record) and the (M, 2K) result weighted by an (M, 2K) table:
    the same sums as an (N, 2K) table of the whole record (128 MB at a million samples, a memory-bound pass)
    with two tables of about sqrt(N) rows. Angles are reduced modulo N in integers, so they are exact before
    the one rounding of the sine and cosine.
    """
    r = np.atleast_2d(np.asarray(resid, dtype=float))
    n = r.shape[-1]
    r = r.reshape(-1, n)
    c = r.shape[0]
    lb, m = _factor(n)
    if lb * m != n:
        rp = np.zeros((c, lb * m))
        rp[:, :n] = r
        r = rp
    k = np.arange(1, bins + 1)
    pq = (r.reshape(c * m, lb) @ _angle_table(k, np.arange(lb), n)).reshape(c, m, 2 * bins)
    em = _angle_table(k, np.arange(m) * lb, n)   # (M, 2K): cos, then sin of 2 pi k m L / N
    p, q = pq[..., :bins], pq[..., bins:]
    cm, sm = em[:, :bins], em[:, bins:]
    # sum_l r exp(-j 2 pi k l / N) = p - j q; times cm - j sm: Re = p cm - q sm, Im = -(p sm + q cm)
    re = np.einsum("cmk,mk->ck", p, cm) - np.einsum("cmk,mk->ck", q, sm)
    im = np.einsum("cmk,mk->ck", p, sm) + np.einsum("cmk,mk->ck", q, cm)
    return np.sum(re * re + im * im, axis=-1) / n


def _factor(n: int) -> tuple[int, int]:
    """``(L, M)`` with ``L M >= n``, both near sqrt(n): a divisor of n near its root when there is one."""
    root = max(int(math.isqrt(n)), 1)
    for lb in range(root, max(root // 2, 1) - 1, -1):
        if n % lb == 0:
            return lb, n // lb
    return root, -(-n // root)


def _angle_table(k: np.ndarray, idx: np.ndarray, n: int) -> np.ndarray:
    """Columns ``cos(2 pi k i / n)`` for each k, then ``sin(...)``, shape (len(idx), 2K); ``k i`` reduced mod n."""
    ph = (2.0 * np.pi / n) * np.mod(np.outer(idx, k), n)
    return np.concatenate([np.cos(ph), np.sin(ph)], axis=1)


def low_frequency_test(resid: np.ndarray, u_offset: float, n_fixed: int = 1,
                       bins: int = LOWFREQ_BINS) -> tuple[float, int, bool]:
    """Chi-square test of the residual's lowest Fourier bins against the stated u(offset).

    Parameters
    ----------
    resid : ndarray, shape (N,)
        Fit residuals in time order (uniform time base).
    u_offset : float
        The fit's standard uncertainty of the offset (the record's mean).
        Under the noise model that gave it, the noise density near 0 Hz is
        ``S0 = N u^2`` (per sample, two-sided): white noise has ``u^2 =
        sigma^2 / N``, coloured noise its model's level at 0 Hz.
    n_fixed : int
        Kept for the caller's bookkeeping (terms the fit removed near 0 Hz);
        the bins used, ``k = 1..K``, are orthogonal to the offset already.
    bins : int
        Number of bins ``K`` (frequencies ``k / T``, ``k = 1..K``).

    Returns
    -------
    (chi2, dof, significant)
        ``chi2 = 2 sum_k I_k / S0`` with the periodogram ``I_k = |sum_i r_i
        exp(-2 pi i k i / N)|^2 / N``, chi-square with ``dof = 2K`` when the
        density below ``K / T`` is ``S0`` (each ``I_k / S0`` is exponential
        with mean one); significant at level ``VARIANCE_ALPHA``.

    Notes
    -----
    Noise whose density grows below 1/T (1/f noise, random-walk wander)
    fills the lowest bins; the record's mean then carries noise from below
    1/T as well, which no model fitted inside the record can give, so the
    test names it instead of pretending to cover it.  Its power is that of
    the K lowest bins: 1/f noise that crosses the white level above about
    5/T is found in most records.
    """
    from scipy.stats import chi2

    r = np.asarray(resid, dtype=float)
    n = r.size
    if n < 8 * bins or not (u_offset > 0 and math.isfinite(u_offset)):
        return math.nan, 0, False
    stat = float(2.0 * low_frequency_power(r, bins)[0] / (n * u_offset**2))
    dof = 2 * bins
    return stat, dof, bool(stat > chi2.isf(VARIANCE_ALPHA, dof))
