"""Drift between calibrations and the date a sensor is due.

Pure numerics: arrays and frozen dataclasses in and out. Times are in years
(Julian years of 365.25 days) since a reference epoch chosen by the caller.

References
----------
.. [1] Seed 002: patent CN102564486A, Shanghai Dianji University (2012): a
   sensor's bias drifts slowly between calibrations and nobody knows whether
   it is still right; the registry quantifies that drift from the history.
.. [2] JCGM 100:2008 (GUM), clause 4.2 and annex H.3 (calibration of a
   thermometer: a weighted straight line and the uncertainty of a
   prediction from it).
.. [3] OIML D 10 / ILAC-G24:2022, "Guidelines for the determination of
   recalibration intervals of measuring equipment" (the "staircase" /
   control-chart reasoning behind a due date).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from senscal._result import ResultMixin
from senscal.errors import DataError, InputError, TooFewSamplesError

if TYPE_CHECKING:
    import numpy as np

# numpy loads in the functions that compute, not with this module: the registry's
# record/show/list/due commands import the result classes and never fit.

__all__ = ["DriftFit", "DueDate", "fit_drift", "due_time", "DAYS_PER_YEAR"]

DAYS_PER_YEAR = 365.25


@dataclass(frozen=True)
class DriftFit(ResultMixin):
    """Weighted straight line ``value(t) = value_at_epoch + drift_per_year * t``.

    Attributes
    ----------
    value_at_epoch, u_value_at_epoch : float
        Fitted value at ``t = 0`` and its standard uncertainty, unit of the quantity.
    drift_per_year, u_drift_per_year : float
        Slope and its standard uncertainty, unit of the quantity per year.
    covariance : ndarray, shape (2, 2)
        Covariance of ``(value_at_epoch, drift_per_year)``.
    chi2 : float
        Weighted sum of squared residuals (dimensionless).
    dof : int
        Degrees of freedom, ``n - 2``.
    birge_ratio : float
        ``sqrt(chi2 / dof)`` (NaN with two records). When the records
        scatter more than their stated uncertainties allow (chi-square test
        at 5 %), the covariance is scaled by ``birge_ratio**2`` so the
        drift's uncertainty is not understated.
    scaled : bool
        Whether the covariance was scaled by ``birge_ratio**2``.
    z : float
        ``drift_per_year / u_drift_per_year``.
    p_value : float
        Two-sided probability of a slope at least this large if the sensor
        did not drift (normal with stated uncertainties; Student t with
        ``dof`` degrees of freedom when the covariance was scaled).
    significant : bool
        ``p_value < alpha``.
    alpha : float
        Significance level used.
    n_records : int
    """

    value_at_epoch: float
    u_value_at_epoch: float
    drift_per_year: float
    u_drift_per_year: float
    covariance: np.ndarray
    chi2: float
    dof: int
    birge_ratio: float
    scaled: bool
    z: float
    p_value: float
    significant: bool
    alpha: float
    n_records: int

    def predict(self, t_years):
        """Fitted value at ``t_years`` and its standard uncertainty (line only)."""
        import numpy as np

        t = np.asarray(t_years, dtype=float)
        value = self.value_at_epoch + self.drift_per_year * t
        c = self.covariance
        var = c[0, 0] + 2.0 * t * c[0, 1] + t * t * c[1, 1]
        return value, np.sqrt(np.maximum(var, 0.0))


@dataclass(frozen=True)
class DueDate(ResultMixin):
    """When the predicted deviation plus its expanded uncertainty reaches the tolerance.

    Attributes
    ----------
    t_due : float or None
        Time of the crossing in years since the epoch; None when it does not
        happen within ``horizon_years`` after the last record.
    overdue : bool
        The bound is already at or beyond the tolerance at the last record;
        ``t_due`` is then the time of the last record.
    reference : float
        Value deviations are measured from (nominal or first record).
    tolerance : float
        Allowed absolute deviation, unit of the quantity.
    k : float
        Coverage factor applied to the prediction's uncertainty.
    deviation_at_due, u_deviation_at_due : float or None
        Predicted deviation and its standard uncertainty at ``t_due``.
    """

    t_due: float | None
    overdue: bool
    reference: float
    tolerance: float
    k: float
    deviation_at_due: float | None
    u_deviation_at_due: float | None


def fit_drift(t_years, values, uncertainties, *, alpha: float = 0.05) -> DriftFit:
    """Weighted least-squares straight line through a calibration history.

    Parameters
    ----------
    t_years : array_like, shape (n,)
        Calibration times, years since an epoch of the caller's choice.
    values : array_like, shape (n,)
        Calibrated values (unit of the quantity, e.g. V/(m/s^2)).
    uncertainties : array_like, shape (n,)
        Standard uncertainties (k=1) of ``values``, same unit; weights are
        ``1 / u**2`` (GUM H.3).
    alpha : float
        Significance level of the drift test (two-sided).

    Returns
    -------
    DriftFit

    Raises
    ------
    TooFewSamplesError
        Fewer than two records: a drift cannot be estimated from one.
    DataError
        Non-finite values, non-positive uncertainties, or all records at the same time.
    """
    import numpy as np
    # scipy.special's distribution functions: the same numbers as scipy.stats at a fraction of the call cost.
    from scipy import special

    t = np.asarray(t_years, dtype=float).ravel()
    y = np.asarray(values, dtype=float).ravel()
    u = np.asarray(uncertainties, dtype=float).ravel()
    if not (t.shape == y.shape == u.shape):
        raise InputError(f"times, values and uncertainties must have the same length, got {t.size}, {y.size}, {u.size}")
    if t.size < 2:
        raise TooFewSamplesError(f"a drift needs at least two calibration records, found {t.size}; "
                                 "record another calibration (senscal registry record) first")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y)) and np.all(np.isfinite(u))):
        raise DataError("calibration history contains non-finite times, values or uncertainties")
    if np.any(u <= 0):
        raise DataError("every calibration record needs a positive standard uncertainty to weight the drift fit")
    if np.ptp(t) == 0:
        raise DataError("all calibration records have the same date; a drift needs records at different dates")
    # Whitened design: rows divided by u, so ordinary least squares is the weighted fit.
    a = np.column_stack([np.ones_like(t), t]) / u[:, None]
    b = y / u
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    cov = np.linalg.inv(a.T @ a)
    resid = b - a @ coef
    chi2 = float(resid @ resid)
    dof = t.size - 2
    birge = math.sqrt(chi2 / dof) if dof > 0 else math.nan
    # Scale only when the scatter is inconsistent with the stated uncertainties
    # (chi-square test at 5 %): scaling every time chi2 > dof would make the
    # drift test conservative (false-alarm rate well under alpha) for sensors
    # whose certificates are honest.
    scaled = dof > 0 and birge > 1.0 and special.chdtrc(dof, chi2) < 0.05
    if scaled:
        cov = cov * birge**2
    u_slope = math.sqrt(cov[1, 1])
    z = float(coef[1] / u_slope)
    p = float(2.0 * (special.stdtr(dof, -abs(z)) if scaled else special.ndtr(-abs(z))))
    return DriftFit(
        value_at_epoch=float(coef[0]), u_value_at_epoch=math.sqrt(cov[0, 0]),
        drift_per_year=float(coef[1]), u_drift_per_year=u_slope, covariance=cov,
        chi2=chi2, dof=dof, birge_ratio=birge, scaled=bool(scaled), z=z, p_value=p, significant=bool(p < alpha),
        alpha=alpha, n_records=int(t.size),
    )


def due_time(fit: DriftFit, *, t_last: float, reference: float, tolerance: float, k: float = 2.0,
             horizon_years: float = 100.0) -> DueDate:
    """First time after the last record at which ``|deviation| + k u`` reaches the tolerance.

    The deviation is the fitted line minus ``reference``; ``u`` is the
    standard uncertainty of the fitted line at that time (it grows as the
    prediction moves away from the records). The bound is convex in time, so
    after the last record it crosses the tolerance at most once; the
    crossing is found by bracketing and Brent's method.

    Parameters
    ----------
    fit : DriftFit
    t_last : float
        Time of the last record, years since the fit's epoch.
    reference : float
        Nominal value, or the first recorded value (unit of the quantity).
    tolerance : float
        Allowed absolute deviation from ``reference`` (unit of the quantity, > 0).
    k : float
        Coverage factor of the uncertainty added to the deviation (2: about 95 %).
    horizon_years : float
        How far after the last record to look.

    Returns
    -------
    DueDate
    """
    from scipy import optimize

    if not (tolerance > 0 and math.isfinite(tolerance)):
        raise InputError(f"tolerance must be a positive finite number, got {tolerance}")
    if not (math.isfinite(k) and k > 0):  # NaN passed "k <= 0" and stalled the root search
        raise InputError(f"coverage factor --k must be a positive, finite number, got {k}")

    def bound(t: float) -> float:
        value, u = fit.predict(t)
        return float(abs(value - reference) + k * u - tolerance)

    def result(t_due, overdue):
        if t_due is None:
            return DueDate(None, overdue, reference, tolerance, k, None, None)
        value, u = fit.predict(t_due)
        return DueDate(float(t_due), overdue, reference, tolerance, k, float(value - reference), float(u))

    if bound(t_last) >= 0:
        return result(t_last, True)
    step = 1.0 / 12.0
    lo, hi = t_last, t_last + step
    while bound(hi) < 0:
        if hi - t_last >= horizon_years:
            return result(None, False)
        lo, hi = hi, min(t_last + 2.0 * (hi - t_last), t_last + horizon_years)
    return result(optimize.brentq(bound, lo, hi, xtol=1e-6), False)
