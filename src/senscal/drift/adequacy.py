"""Model adequacy of a drift fit: innovation tests and moment-based noise levels.

Pure functions on arrays.  Under a correct state-space model with the right
noise levels the normalised innovations of the Kalman filter are independent
standard normal; :func:`innovation_checks` tests their scale (normalised
innovation squared) and their whiteness (Ljung-Box).  :func:`moment_levels`
gives noise levels from the autocovariances of the first differences, which
do not depend on the likelihood's optimiser and so serve both as starting
values and as a check that a maximum-likelihood solution has not collapsed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
# scipy.special, not scipy.stats: the same chi-square tails at a fraction of the import time.
from scipy.special import chdtr, chdtrc

from senscal._result import ResultMixin

__all__ = ["InnovationCheck", "innovation_checks", "MomentLevels", "moment_levels", "ljung_box"]

#: p-value below which an innovation test rejects the model.  One in a
#: thousand: a user running many records should not see false alarms often,
#: and the tests are strong enough on a few hundred samples to catch misfits
#: that matter (a wrong signal time constant, a missed ramp).
P_REJECT = 1e-3


@dataclass(frozen=True)
class InnovationCheck(ResultMixin):
    """Tests of the normalised innovations of the final model.

    Attributes
    ----------
    n : int
        Innovations tested (components x samples, after the prior's transient).
    nis : float
        Mean normalised innovation squared per component (1 under the model).
    nis_p : float
        Two-sided p-value of ``sum e^2 ~ chi2(n)``.
    lags : int
        Ljung-Box lags.
    whiteness_q : tuple of float
        Ljung-Box statistic of each measured component.
    whiteness_p : float
        Smallest Ljung-Box p-value over components, times their number
        (Bonferroni).
    adequate : bool
        Both p-values above :data:`P_REJECT`.
    """

    n: int
    nis: float
    nis_p: float
    lags: int
    whiteness_q: tuple[float, ...]
    whiteness_p: float
    adequate: bool


def ljung_box(e: np.ndarray, lags: int) -> tuple[float, float]:
    """Ljung-Box statistic and p-value of one series (NaN entries dropped).

    Parameters
    ----------
    e : ndarray, (T,)
        Series, nominally white with zero mean [1].
    lags : int
        Number of autocorrelations summed.

    Returns
    -------
    (Q, p) : tuple of float

    References
    ----------
    G. M. Ljung, G. E. P. Box, "On a measure of lack of fit in time series
    models", Biometrika 65 (1978) 297-303.
    """
    x = np.asarray(e, dtype=float)
    x = x[np.isfinite(x)]
    n = x.size
    if n <= lags + 2:
        return float("nan"), 1.0
    x = x - x.mean()
    c0 = float(x @ x)
    if c0 <= 0:
        return float("nan"), 1.0
    r = np.array([float(x[k:] @ x[:-k]) / c0 for k in range(1, lags + 1)])
    q = n * (n + 2) * float(np.sum(r**2 / (n - np.arange(1, lags + 1))))
    return q, float(chdtrc(lags, q))


def innovation_checks(normalized_innovation: np.ndarray, *, skip: int = 0) -> InnovationCheck:
    """Scale and whiteness of normalised innovations.

    Parameters
    ----------
    normalized_innovation : ndarray, (m, T)
        Whitened innovations (standard normal under the model), NaN = missing.
    skip : int
        Leading samples left out (the prior's transient, whose innovations
        depend on a prior that is only a convention).

    Returns
    -------
    InnovationCheck
    """
    e = np.atleast_2d(np.asarray(normalized_innovation, dtype=float))[:, skip:]
    good = np.isfinite(e)
    n = int(good.sum())
    s = float(np.sum(e[good] ** 2))
    nis = s / n if n else float("nan")
    if n:
        p_nis = float(2 * min(chdtrc(n, s), chdtr(n, s)))
    else:
        p_nis = 1.0
    T = e.shape[1]
    # Enough lags to see a slow misfit, few enough to keep the test's power:
    # about ln(T) (Tsay's rule), at least 5, at most 30.
    lags = int(min(30, max(5, round(np.log(max(T, 2))))))
    qs, ps = [], []
    for row in e:
        q, p = ljung_box(row, lags)
        qs.append(q)
        ps.append(p)
    p_white = float(min(1.0, min(ps) * len(ps))) if ps else 1.0
    return InnovationCheck(n=n, nis=nis, nis_p=min(1.0, p_nis), lags=lags, whiteness_q=tuple(float(q) for q in qs),
                           whiteness_p=p_white, adequate=bool(p_nis >= P_REJECT and p_white >= P_REJECT))


@dataclass(frozen=True)
class MomentLevels(ResultMixin):
    """Noise levels from the autocovariances of first differences.

    Attributes
    ----------
    noise_var : ndarray, (m,)
        White-noise variance of each channel, ``-gamma_1`` of its first
        difference [unit^2] (NaN when the estimate is not positive).
    noise_var_se : ndarray, (m,)
        Standard error of that estimate (Bartlett: ``gamma_0 / sqrt(N)``
        bounds it for a lag-one autocovariance) [unit^2].
    common_var : float
        Per-sample variance of the increments every channel shares (the
        quantity's random walk), the median cross-covariance of the
        differences at lag 0 [unit^2]; NaN with one channel.
    own_var : ndarray, (m,)
        Per-sample variance of each channel's increments beyond the white
        noise: ``gamma_0 + 2 gamma_1`` (quantity plus own bias) [unit^2].
    """

    noise_var: np.ndarray
    noise_var_se: np.ndarray
    common_var: float
    own_var: np.ndarray


def moment_levels(y: np.ndarray) -> MomentLevels:
    """Moment estimates for ``y_i = s + b_i + v_i`` with random-walk s, b_i.

    The first difference ``d_i = w_s + w_bi + v_i,t - v_i,t-1`` has
    ``gamma_0 = q_s + q_bi + 2 r_i`` and ``gamma_1 = -r_i``; two channels'
    differences share only ``q_s`` at lag 0.  A smooth departure (a
    Gauss-Markov quantity, a ramp) adds a small positive lag-one term, so the
    noise estimate errs low by at most that.

    Parameters
    ----------
    y : ndarray, (m, T)
        Measurements, NaN = missing (pairs with a missing end are dropped).

    Returns
    -------
    MomentLevels

    References
    ----------
    R. H. Shumway, D. S. Stoffer, *Time Series Analysis and Its
    Applications*, 4th ed. (2017), sec. 3.8 (differenced random walk plus
    noise is MA(1)); M. S. Bartlett (1946) for the standard error.
    """
    y = np.atleast_2d(np.asarray(y, dtype=float))
    m = y.shape[0]
    d = np.diff(y, axis=1)
    d = d - np.nanmean(d, axis=1, keepdims=True)
    g0 = np.nanmean(d**2, axis=1)
    g1 = np.nanmean(d[:, 1:] * d[:, :-1], axis=1)
    N = np.sum(np.isfinite(d[:, 1:] * d[:, :-1]), axis=1).astype(float)
    r = -g1
    se = g0 / np.sqrt(np.maximum(N, 1.0))
    common = float("nan")
    if m > 1:
        cross = [np.nanmean(d[i] * d[j]) for i in range(m) for j in range(i + 1, m)]
        common = float(np.nanmedian(cross))
    return MomentLevels(noise_var=np.where(r > 0, r, np.nan), noise_var_se=se, common_var=common,
                        own_var=g0 + 2 * g1)
