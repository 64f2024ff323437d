"""The three classic ways to turn array kinematics into angular velocity.

All functions work on every axis and every sample at once (time on the last
axis) and take the time stamps, so non-uniform sampling is handled.

References
----------
.. [1] Wang W., Dai Y., Chen H., Wang P., "Application of Kalman filter to
   calculate angular velocity of complicated vibration by full acceleration
   sensor", China Measurement & Test, 2017(5), section 2.1, eq. (6)-(9)
   (seed 001); METHODS.md 2c.
"""

from __future__ import annotations

import warnings

import numpy as np

from senscal.errors import DataError, InputError, TooFewSamplesError

__all__ = ["integration_rate", "sqrt_rate", "differential_rate", "estimate_noise_std", "rate_increments"]


def _check(x: np.ndarray, t: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=float)
    t = np.asarray(t, dtype=float)
    if x.ndim != 2 or x.shape[0] != 3 or t.shape != (x.shape[1],):
        raise InputError(f"{what} must have shape (3, T) with t of shape (T,), got {x.shape} and {t.shape}")
    if t.size < 2:
        raise TooFewSamplesError(f"{what} needs at least 2 samples")
    return x, t


def rate_increments(alpha: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Trapezoid increments ``w(t_k) - w(t_{k-1})`` from angular acceleration.

    Parameters
    ----------
    alpha : ndarray, shape (3, T)
        Angular acceleration, rad/s^2.
    t : ndarray, shape (T,)
        Time, s.

    Returns
    -------
    ndarray, shape (3, T)
        Increment into sample k (rad/s); column 0 is zero.
    """
    inc = np.zeros_like(alpha)
    inc[:, 1:] = 0.5 * np.diff(t) * (alpha[:, 1:] + alpha[:, :-1])
    return inc


def integration_rate(alpha: np.ndarray, t: np.ndarray, initial=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Integration method: ``w(t) = w(t-T) + T (dw/dt(t-T) + dw/dt(t)) / 2``.

    Low noise and no sign ambiguity, but any non-zero-mean error of the
    angular acceleration (sensor bias) makes ``w`` drift without bound.

    Parameters
    ----------
    alpha : ndarray, shape (3, T)
        Angular acceleration, rad/s^2.
    t : ndarray, shape (T,)
        Time, s.
    initial : sequence of 3 floats
        Angular velocity at ``t[0]``, rad/s.

    Returns
    -------
    ndarray, shape (3, T)
        Angular velocity, rad/s.

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), eq. (6), with the trapezoid rule
       METHODS.md 2c recommends.
    """
    alpha, t = _check(alpha, t, "angular acceleration")
    w0 = np.asarray(initial, float).reshape(3, 1)
    return w0 + np.cumsum(rate_increments(alpha, t), axis=1)


def sqrt_rate(squares: np.ndarray, sign_reference: np.ndarray) -> np.ndarray:
    """Square-root method: ``|w_i| = sqrt(w_i^2)``, sign from a reference.

    Negative squares (noise near ``w = 0``) give zero.

    Parameters
    ----------
    squares : ndarray, shape (3, T)
        ``wx^2, wy^2, wz^2`` from the array, (rad/s)^2.
    sign_reference : ndarray, shape (3, T)
        Angular velocity whose sign is used (the paper: the integration
        method's), rad/s.  Zero counts as positive.

    Returns
    -------
    ndarray, shape (3, T)
        Angular velocity, rad/s.

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), eq. (7).
    """
    squares = np.asarray(squares, float)
    sign = np.where(np.asarray(sign_reference, float) < 0, -1.0, 1.0)
    return sign * np.sqrt(np.maximum(squares, 0.0))


def differential_rate(squares: np.ndarray, alpha: np.ndarray, t: np.ndarray, *, lag: int = 1,
                      squares_std=None, max_uncertainty: float | None = None,
                      reject_factor: float = 3.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Differential method: ``w(t) = (w^2(t) - w^2(t-tau)) / (2 D) + D / 2``.

    ``D = w(t) - w(t-tau)`` is the integrated angular acceleration over the
    last ``lag`` samples (trapezoid).  The identity is exact for the true
    increment, so no sign test is needed and constant errors of the squares
    cancel in the difference; but where ``D`` is small the quotient is
    ill-conditioned and the estimate is a gross error.  Such samples are
    detected from the estimate's own standard uncertainty and rejected.

    Parameters
    ----------
    squares : ndarray, shape (3, T)
        ``wx^2, wy^2, wz^2``, (rad/s)^2.
    alpha : ndarray, shape (3, T)
        Angular acceleration, rad/s^2.
    t : ndarray, shape (T,)
        Time, s.
    lag : int
        Difference span in samples (1 = one sample period, the paper's).
    squares_std : sequence of 3 floats, optional
        Standard deviation of one sample of each square from white channel
        noise, (rad/s)^2; without it the uncertainty is in units of it and
        only the relative rejection rule applies.
    max_uncertainty : float, optional
        Reject samples whose standard uncertainty exceeds this, rad/s.
    reject_factor : float
        Also reject samples whose uncertainty exceeds ``reject_factor``
        times the median uncertainty of that axis (``inf`` disables).

    Returns
    -------
    omega : ndarray, shape (3, T)
        Angular velocity, rad/s; NaN where rejected (and the first ``lag``
        samples).
    uncertainty : ndarray, shape (3, T)
        Standard uncertainty from white noise of the squares, rad/s.
    rejected : ndarray of bool, shape (3, T)

    References
    ----------
    .. [1] Wang et al. 2017 (seed 001), eq. (8)-(9) and section 2.2.
    """
    squares = np.asarray(squares, float)
    alpha, t = _check(alpha, t, "angular acceleration")
    lag = int(lag)
    if lag < 1:
        raise InputError(f"lag must be at least 1 sample, got {lag}")
    if squares.shape != alpha.shape:
        raise InputError("squares and alpha must have the same shape (3, T)")
    if t.size <= lag:
        raise TooFewSamplesError(f"the differential method with lag {lag} needs more than {lag} samples")
    cum = np.cumsum(rate_increments(alpha, t), axis=1)
    d = np.full_like(alpha, np.nan)
    d[:, lag:] = cum[:, lag:] - cum[:, :-lag]
    ds = np.full_like(squares, np.nan)
    ds[:, lag:] = squares[:, lag:] - squares[:, :-lag]
    with np.errstate(divide="ignore", invalid="ignore"):
        omega = ds / (2.0 * d) + 0.5 * d
        s = np.ones(3) if squares_std is None else np.asarray(squares_std, float)
        # Two independent samples of the square in the difference.
        u = np.sqrt(2.0) * s[:, None] / (2.0 * np.abs(d))
    u[~np.isfinite(u)] = np.inf
    bad = ~np.isfinite(omega)
    if np.isfinite(reject_factor):
        with warnings.catch_warnings():  # an axis with no finite uncertainty is all rejected anyway
            warnings.simplefilter("ignore", RuntimeWarning)
            med = np.nanmedian(np.where(np.isfinite(u), u, np.nan), axis=1, keepdims=True)
        bad |= u > reject_factor * med
    if max_uncertainty is not None:
        if squares_std is None:
            raise InputError("max_uncertainty needs squares_std (the noise of the squares)")
        bad |= u > max_uncertainty
    omega = np.where(bad, np.nan, omega)
    return omega, u, bad


def estimate_noise_std(readings: np.ndarray) -> np.ndarray:
    """White-noise standard deviation of each channel from its second differences.

    For an oversampled smooth signal plus white noise of variance s^2, the
    second difference is dominated by noise of variance 6 s^2; the median
    absolute deviation makes it robust to shocks.

    Parameters
    ----------
    readings : ndarray, shape (M, T)
        Channels, any unit.

    Returns
    -------
    ndarray, shape (M,)
        Noise standard deviation, unit of the readings.
    """
    y = np.asarray(readings, float)
    if y.shape[-1] < 8:
        raise TooFewSamplesError("noise estimation needs at least 8 samples per channel")
    d2 = np.diff(y, n=2, axis=-1)
    # The second differences of an oversampled signal are centred on zero
    # (their mean telescopes to ~0), so the MAD needs no second median.
    mad = np.median(np.abs(d2), axis=-1)
    s = mad / (0.6744897501960817 * np.sqrt(6.0))
    if np.any(~np.isfinite(s)):
        raise DataError("channel noise could not be estimated (non-finite readings)")
    return s
