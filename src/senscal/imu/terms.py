"""Bias terms of an IMU calibration: time drift, temperature polynomials, gyro g-sensitivity.

The gyroscope's bias over the static poses is a weighted linear model of the
pose means (weights: samples per pose over the per-sample variance):

    b_i(pose k) = c_i + sum_j p_ij dT_k^j + sum_l G_il f_lk      (with a temperature channel)
    b_i(pose k) = c_i + s_i (t_k - t_ref) + sum_l G_il f_lk      (without)

``dT = T - T_ref`` (``T_ref`` the sample-weighted mean temperature of the poses), ``f`` the calibrated
specific force (m/s^2, for the optional g-sensitivity ``G``).  The polynomial degree is chosen on held-out
data: the leave-one-pose-out prediction error (PRESS), which needs no refit for a linear model.

The accelerometer's temperature terms act on the pose means before the magnitude fit,

    a_corr = (a - sum_j c_j dT^j) / (1 + sum_j s_j dT^j)       (per axis: bias and relative scale)

and their degree is chosen by five-fold cross-validation over the poses (folds interleaved in time, so
each spans the temperature range).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

__all__ = ["BiasDesign", "fit_bias", "press_degree", "accel_temperature_correct", "accel_temperature_degree",
           "MAX_DEGREE", "MIN_SWING_K"]

#: Highest temperature polynomial degree tried.
MAX_DEGREE = 3
#: Below this temperature swing over the poses (K) the temperature terms extrapolate poorly: a named warning.
#: Chosen as the band over which MEMS bias tempco curvature (typically < 1e-3 of the linear term per K) stays
#: below the linear term's own u for a 30-pose session; it is a practical limit, not a test statistic.
MIN_SWING_K = 5.0


@dataclass(frozen=True)
class BiasDesign:
    """Which columns the gyro bias model holds.

    Attributes
    ----------
    t_ref : float
        Reference time, s (sample-weighted mean of the poses).
    temp_ref : float or None
        Reference temperature (sample-weighted mean over the poses), the channel's unit; None without one.
    degree : int
        Temperature polynomial degree (0: none; with no temperature channel the time slope is column 1).
    g_sensitivity : bool
        Three columns for the specific force.
    time_slope : bool
        With a temperature channel: a time slope too, after the temperature columns (a bias that drifts in time
        besides following the temperature; chosen on held-out poses like the degree).
    """

    t_ref: float
    temp_ref: float | None
    degree: int
    g_sensitivity: bool
    time_slope: bool = False

    @property
    def has_slope(self) -> bool:
        return self.temp_ref is None or self.time_slope

    @property
    def slope_col(self) -> int | None:
        """Index of the time-slope column (None without one)."""
        if self.temp_ref is None:
            return 1
        return 1 + self.degree if self.time_slope else None

    @property
    def n_cols(self) -> int:
        return (1 + (self.degree if self.temp_ref is not None else 1) + (1 if self.temp_ref is not None and
                self.time_slope else 0) + (3 if self.g_sensitivity else 0))

    def matrix(self, t: np.ndarray, temp: np.ndarray | None, f: np.ndarray | None) -> np.ndarray:
        """Design matrix, shape (n, n_cols), at times ``t`` (s), temperatures ``temp`` and forces ``f`` (3, n)."""
        t = np.asarray(t, float)
        cols = [np.ones_like(t)]
        if self.temp_ref is None:
            cols.append(t - self.t_ref)
        else:
            dt = np.asarray(temp, float) - self.temp_ref
            cols.extend(dt ** j for j in range(1, self.degree + 1))
            if self.time_slope:
                cols.append(t - self.t_ref)
        if self.g_sensitivity:
            cols.extend(np.asarray(f, float))
        return np.column_stack(cols)


def fit_bias(x: np.ndarray, means: np.ndarray, counts: np.ndarray, noise: np.ndarray):
    """Weighted least squares of the pose means on the design, per axis, with covariance.

    Parameters
    ----------
    x : ndarray, shape (K, p)
        Design at the poses.
    means : ndarray, shape (K, 3)
        Gyro pose means (reading).
    counts : ndarray, shape (K,)
        Samples per pose.
    noise : ndarray, shape (3,)
        Per-sample noise std per axis (reading).

    Returns
    -------
    coef : ndarray, shape (p, 3)
    cov : ndarray, shape (3, p, p)
        Per axis; when the means scatter beyond their noise (chi-square above its 99.9 % point: coloured
        noise, an unmodelled drift) scaled by ``chi2 / dof``.
    chi2 : ndarray, shape (3,)
    dof : int
    """
    k_n, p = x.shape
    w = counts.astype(float)
    xtwx = x.T @ (w[:, None] * x)
    inv = np.linalg.pinv(xtwx)
    coef = inv @ (x.T @ (w[:, None] * means))
    resid = means - x @ coef
    dof = k_n - p
    chi2 = (w[:, None] * resid ** 2).sum(axis=0) / np.maximum(noise, 1e-300) ** 2
    scale = (np.where(chi2 > stats.chi2.ppf(0.999, dof), chi2 / dof, 1.0) if dof > 0 else np.ones(3))
    cov = np.array([inv * noise[i] ** 2 * scale[i] for i in range(3)])
    return coef, cov, chi2, dof


def press_degree(design_of, means: np.ndarray, counts: np.ndarray, noise: np.ndarray, max_degree: int = MAX_DEGREE
                 ) -> tuple[int, list[float]]:
    """Temperature degree with the smallest leave-one-pose-out prediction error.

    Parameters
    ----------
    design_of : callable
        ``design_of(d) -> X`` (K, p) for degree ``d``.
    means, counts, noise :
        As :func:`fit_bias`.

    Returns
    -------
    (degree, scores)
        ``scores[d]``: the sum over axes of the held-out chi-square (NaN where too few poses).
    """
    w = counts.astype(float)
    scores = []
    for d in range(max_degree + 1):
        x = design_of(d)
        if x.shape[0] - x.shape[1] < 2:
            scores.append(math.nan)
            continue
        inv = np.linalg.pinv(x.T @ (w[:, None] * x))
        h = w * np.einsum("kp,pq,kq->k", x, inv, x)
        resid = means - x @ (inv @ (x.T @ (w[:, None] * means)))
        loo = resid / np.maximum(1.0 - h, 1e-9)[:, None]
        scores.append(float(((w[:, None] * loo ** 2) / np.maximum(noise, 1e-300) ** 2).sum()))
    finite = [s if math.isfinite(s) else math.inf for s in scores]
    return int(np.argmin(finite)), scores


def _tc_split(tc: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    tc = np.asarray(tc, float).reshape(2, degree, 3) if degree else np.zeros((2, 0, 3))
    return tc[0], tc[1]


def accel_temperature_correct(means: np.ndarray, dtemp: np.ndarray, tc: np.ndarray, degree: int) -> np.ndarray:
    """Pose means with the temperature terms removed.

    Parameters
    ----------
    means : ndarray, shape (3, K)
        Accelerometer pose means (reading).
    dtemp : ndarray, shape (K,)
        Pose temperature minus the reference.
    tc : ndarray, shape (6 * degree,)
        Bias coefficients (degree, 3) (reading per unit^j) then relative-scale coefficients (degree, 3)
        (per unit^j), flattened.
    degree : int
    """
    cb, cs = _tc_split(tc, degree)
    pw = np.stack([dtemp ** j for j in range(1, degree + 1)]) if degree else np.zeros((0, dtemp.size))
    return (means - cb.T @ pw) / (1.0 + cs.T @ pw)


def accel_temperature_degree(means: np.ndarray, sd: np.ndarray, dtemp: np.ndarray, theta0: np.ndarray,
                             gravity: float, max_degree: int = 2, folds: int = 5) -> tuple[int, list[float]]:
    """Accelerometer temperature degree by ``folds``-fold cross-validation over the poses.

    Each fold leaves out every ``folds``-th pose (interleaved in time), fits the magnitude model with the
    temperature terms on the rest and scores the left-out poses' magnitude residuals over their noise.

    Cross-validation with ~30 poses and 6 parameters per degree can prefer a model that does not fit (a short
    or lopsided warm-up: the held-out poses' extrapolation costs more than the misfit).  So a degree whose
    full-data chi-square exceeds its 99.9 % point is stepped up while the next degree lowers the chi-square
    significantly (likelihood ratio, chi-square with 6 dof at 99.9 %): a model the noise rejects is not kept
    when a larger one removes the misfit.

    Returns
    -------
    (degree, scores)
        ``scores[d]``: held-out chi-square (NaN where the model has too many parameters for the poses).
    """
    from senscal.triaxial.estimators import residuals

    k_n = means.shape[1]
    scores = []
    for d in range(max_degree + 1):
        n_par = 9 + 6 * d
        if k_n - k_n // folds - n_par < 3:
            scores.append(math.nan)
            continue
        tot = 0.0
        for f in range(folds):
            test = np.arange(k_n) % folds == f
            train = ~test

            def fun(ph, sel=train):
                m = accel_temperature_correct(means[:, sel], dtemp[sel], ph[9:], d)
                return residuals("full", ph[:9], m, gravity) / sd[sel]

            sol = optimize.least_squares(fun, np.concatenate([theta0, np.zeros(6 * d)]), method="lm",
                                         x_scale="jac")
            m = accel_temperature_correct(means[:, test], dtemp[test], sol.x[9:], d)
            r = residuals("full", sol.x[:9], m, gravity) / sd[test]
            tot += float(r @ r)
        scores.append(tot)
    finite = [s if math.isfinite(s) else math.inf for s in scores]
    best = int(np.argmin(finite))

    def chi2_full(d):
        def fun(ph):
            m = accel_temperature_correct(means, dtemp, ph[9:], d)
            return residuals("full", ph[:9], m, gravity) / sd

        sol = optimize.least_squares(fun, np.concatenate([theta0, np.zeros(6 * d)]), method="lm", x_scale="jac")
        return float(sol.fun @ sol.fun)

    c_best = None
    while best < max_degree and k_n - 9 - 6 * (best + 1) >= 3:
        c_best = chi2_full(best) if c_best is None else c_best
        if c_best <= stats.chi2.ppf(0.999, k_n - 9 - 6 * best):
            break
        c_next = chi2_full(best + 1)
        if c_best - c_next <= stats.chi2.ppf(0.999, 6):
            break
        best, c_best = best + 1, c_next
    return best, scores
