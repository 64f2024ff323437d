"""Whiteness test and coloured-noise covariance for the sine fit.

The least-squares covariance ``sigma^2 (A^T A)^-1`` assumes white noise.  When
the noise is coloured, what sets the uncertainty of a sine's amplitude and
phase is the noise *at the fitted frequency*, and for the offset the noise
near 0 Hz, not the total variance.  This module

1. tests the residual for whiteness with its lag-one autocorrelation
   (the Durbin-Watson statistic in another form: ``r1 sqrt(N)`` is standard
   normal for white noise), cheap enough to run inside the fit's single pass;
2. when the test fires, models the residual as an autoregressive (AR)
   process (Yule-Walker, order by BIC) and propagates its spectrum through
   the design matrix exactly: ``cov = G^-1 (A^T Sigma A) G^-1`` with
   ``A^T Sigma A = sum_m S(nu_m) F_m F_m^H / M`` on a zero-padded DFT grid;
3. gives the effective degrees of freedom of the resulting uncertainty
   from the asymptotic variance of the AR spectrum estimate (delta method),
   so a user can choose a Student-t coverage factor.

References
----------
.. [1] D. W. K. Andrews and J. C. Monahan, "An improved heteroskedasticity and
   autocorrelation consistent covariance matrix estimator", Econometrica 60
   (1992) 953-966 (AR pre-whitening of the sandwich covariance).
.. [2] P. J. Brockwell and R. A. Davis, *Time Series: Theory and Methods*,
   2nd ed., Springer 1991, 8.1-8.2 (Yule-Walker, asymptotic covariance) and
   9.3 (order selection; BIC is the consistent criterion, so a false alarm
   on white noise gets order 0 or 1, not a spurious high order).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["WHITE_Z", "ColouredNoise", "lag1_significant", "coloured_covariance"]

# Two-sided 1 % quantile of the standard normal: the whiteness test's false
# alarm rate on white noise is 1 %.  Colour too weak to trip it changes u by
# about r1 (at most 2.6 / sqrt(N), 6 % at N = 2000): inside the coverage rule.
WHITE_Z = 2.576
# Colour that changes u by less than about 1 % is not worth a switch: AR(1)
# noise with lag-one correlation r1 scales u by sqrt((1 + r1) / (1 - r1)),
# about 1 + r1.  This bound binds only beyond N = (2.576 / 0.01)^2 = 66,000
# samples, where it removes the false alarms (and their cost) of long records.
WHITE_R1_MIN = 0.01


def lag1_significant(r1, n: int):
    """True where the lag-one autocorrelation ``r1`` of ``n`` residuals is not white.

    Not white means: significant at the 1 % level (``|r1| sqrt(N) > 2.576``)
    and large enough to change u by 1 % or more (``|r1| > 0.01``).

    Parameters
    ----------
    r1 : float or ndarray
        Lag-one autocorrelation (dimensionless).
    n : int
        Number of samples.
    """
    a = np.abs(np.asarray(r1, dtype=float))
    return (a * math.sqrt(n) > WHITE_Z) & (a > WHITE_R1_MIN)


@dataclass(frozen=True)
class ColouredNoise:
    """The coloured-noise covariance of one channel.

    Attributes
    ----------
    cov_lin : ndarray, shape (p, p)
        Covariance of the linear(ised) parameters (unit of the parameters squared).
    dof_effective : float
        Effective degrees of freedom of the standard uncertainties (smallest
        over the design's columns).
    order : int
        Order of the autoregressive noise model (0 = white).
    """

    cov_lin: np.ndarray
    dof_effective: float
    order: int


def _autocov(r: np.ndarray, maxlag: int) -> np.ndarray:
    """Biased autocovariance ``sum r_i r_{i+l} / N`` for l = 0..maxlag."""
    n = r.size
    m = 1 << int(math.ceil(math.log2(2 * n)))
    x = np.fft.rfft(r, m)
    return np.fft.irfft(x.real**2 + x.imag**2, m)[: maxlag + 1] / n


def _levinson_bic(acov: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """Yule-Walker AR coefficients of the order with the smallest BIC (``N log s2 + k log N``).

    Returns (phi, innovation variance); phi has the order's length.
    """
    pmax = acov.size - 1
    best = (n * math.log(acov[0]), np.zeros(0), acov[0])
    phi = np.zeros(0)
    err = acov[0]
    for k in range(1, pmax + 1):
        refl = (acov[k] - phi @ acov[k - 1:0:-1]) / err if k > 1 else acov[1] / err
        phi = np.concatenate([phi - refl * phi[::-1], [refl]])
        err = err * (1.0 - refl * refl)
        if not err > 0:
            break
        bic = n * math.log(err) + k * math.log(n)
        if bic < best[0]:
            best = (bic, phi.copy(), err)
    return best[1], best[2]


def coloured_covariance(resid: np.ndarray, design: np.ndarray, ginv: np.ndarray, n_params: int,
                        column_omega: np.ndarray) -> ColouredNoise:
    """Covariance of least-squares parameters under stationary coloured noise.

    Parameters
    ----------
    resid : ndarray, shape (N,)
        Residuals of the fit on a uniform time base (unit of y).
    design : ndarray, shape (N, p)
        The design matrix the parameters were fitted with (its columns need
        not be sinusoids).
    ginv : ndarray, shape (p, p)
        ``(A^T A)^-1``.
    n_params : int
        Parameters fitted (the residual variance is rescaled by
        ``N / (N - n_params)`` as for white noise).
    column_omega : ndarray, shape (p,)
        Frequency (rad/sample) each column carries (0 for offset and drift,
        ``k w dt`` for harmonic k): where the effective degrees of freedom
        are evaluated.

    Returns
    -------
    ColouredNoise
    """
    n = resid.size
    pmax = int(min(32, max(1, n // 50)))
    acov = _autocov(resid, pmax)
    if not acov[0] > 0:
        return ColouredNoise(np.zeros_like(ginv), float(n - n_params), 0)
    phi, s2e = _levinson_bic(acov, n)
    s2e *= n / max(n - n_params, 1)
    order = phi.size
    m = 1 << int(math.ceil(math.log2(2 * n)))
    ar = np.fft.rfft(np.concatenate([[1.0], -phi]), m)
    spec = s2e / (ar.real**2 + ar.imag**2)   # two-sided density per sample, white = sigma^2
    fa = np.fft.rfft(design, m, axis=0)
    wgt = np.full(spec.size, 2.0)
    wgt[0] = 1.0
    if m % 2 == 0:
        wgt[-1] = 1.0
    omega_mat = ((fa * (wgt * spec)[:, None]).T @ fa.conj()).real / m
    cov = ginv @ omega_mat @ ginv
    cov = 0.5 * (cov + cov.T)
    # Delta method: var(log S(w)) = g' Cov(phi) g + var(log s2e), with
    # Cov(phi) = s2e Gamma^-1 / N and var(log s2e) = 2 / N; u^2 ~ chi2_nu / nu
    # has var(log) = 2 / nu.
    if order:
        gamma = scipy.linalg.toeplitz(acov[:order])
        cphi = (acov[0] * _innov_ratio(acov, phi)) * np.linalg.inv(gamma) / n
        k = np.arange(1, order + 1)
        nus = []
        for w in np.unique(np.asarray(column_omega, dtype=float)):
            a_w = 1.0 - np.sum(phi * np.exp(-1j * w * k))
            g = 2.0 * np.real(np.exp(-1j * w * k) / a_w)
            var = float(g @ cphi @ g) + 2.0 / n
            nus.append(2.0 / var)
        nu = float(min(min(nus), n - n_params))
    else:
        nu = float(n - n_params)
    return ColouredNoise(cov, nu, order)


def _innov_ratio(acov: np.ndarray, phi: np.ndarray) -> float:
    """Innovation variance over the process variance, ``1 - phi . rho``."""
    return float(1.0 - phi @ (acov[1:phi.size + 1] / acov[0]))
