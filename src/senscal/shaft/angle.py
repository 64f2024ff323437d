"""Encoder angle handling and encoder-based kinematics of a rotating shaft.

The encoder angle is the abscissa of the gravity fit and the independent
reference of the angular acceleration, so it is checked, converted to
radians and unwrapped here, once, for every shaft routine.

References
----------
.. [1] Yang X., Li C., Mu D., Chen C., "New application of the sinusoidal
   excitation method in sensor calibration", Transducer and Microsystem
   Technologies, 2014 (seed 000, experiment 2; ``shared/METHODS.md`` 1c).
.. [2] Savitzky A., Golay M. J. E., "Smoothing and differentiation of data by
   simplified least squares procedures", Analytical Chemistry 36 (1964).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import oaconvolve, savgol_coeffs, savgol_filter

from senscal._result import ResultMixin
from senscal.errors import DataError, InputError, TooFewSamplesError

__all__ = ["white_noise_std", "angle_to_rad", "check_radius", "check_uniform", "EncoderKinematics", "encoder_kinematics",
           "savgol", "savgol_window", "smooth"]

TWO_PI = 2.0 * math.pi
POLYORDER = 3


def angle_to_rad(angle, unit: str = "rad", *, monotonic: bool = False, name: str = "angle") -> np.ndarray:
    """Encoder angle in radians, unwrapped, optionally checked to be monotonic.

    Parameters
    ----------
    angle : array_like, shape (N,)
        Encoder angle in ``unit``; may be wrapped (0..360 deg, 0..2 pi rad or
        -180..180 deg): any step larger than half a turn between two samples
        is taken as a wrap, so the shaft must turn less than half a
        revolution per sample.
    unit : {"rad", "deg"}
        Unit of ``angle``.
    monotonic : bool
        Require the unwrapped angle never to reverse (a constant-speed
        calibration run); equal consecutive readings (a slow encoder) pass.
    name : str
        Channel name for messages.

    Returns
    -------
    ndarray, shape (N,)
        Unwrapped angle in rad.

    Raises
    ------
    InputError
        Unknown unit, wrong shape.
    DataError
        NaN/inf, or a reversal when ``monotonic`` is asked for.
    """
    unit = str(unit).lower()
    if unit not in ("rad", "deg"):
        raise InputError(f"angle unit must be 'deg' or 'rad', got {unit!r}")
    a = np.asarray(angle, dtype=np.float64)
    if a.ndim != 1:
        raise InputError(f"angle '{name}' must be 1-D, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DataError(f"angle '{name}' has NaN or inf in data row {int(np.flatnonzero(~np.isfinite(a))[0]) + 1}; "
                        "fix the encoder channel")
    rad = np.radians(a) if unit == "deg" else a.copy()
    rad = np.unwrap(rad, period=TWO_PI)
    if monotonic and rad.size > 1:
        d = np.diff(rad)
        sign = 1.0 if rad[-1] >= rad[0] else -1.0
        back = np.flatnonzero(sign * d < 0)
        if back.size:
            i = int(back[0]) + 1
            raise DataError(
                f"angle '{name}' is not monotonic: it reverses at data row {i + 1} "
                f"({math.degrees(rad[i - 1]):.6g} -> {math.degrees(rad[i]):.6g} deg after unwrapping); "
                "calibrate on a run that turns one way, or check --angle-unit and the encoder channel"
            )
    return rad


def check_radius(radius) -> float:
    """Return ``radius`` (m) as a float, or raise :class:`InputError` unless it is > 0."""
    try:
        r = float(radius)
    except (TypeError, ValueError):
        raise InputError(f"radius must be a number of metres, got {radius!r}") from None
    if not math.isfinite(r) or r <= 0:
        raise InputError(f"radius must be a positive distance in m from the shaft axis to the sensor, got {radius!r}")
    if r < 1e-6:
        # Dividing by a sub-micrometre radius (1e-320 overflowed to inf) is a unit slip, not a sensor position.
        raise InputError(f"radius {r:g} m is below a micrometre; give the sensor's distance from the axis in metres")
    return r


def check_uniform(t: np.ndarray) -> float:
    """Sample interval (s) of a uniform time base; :class:`DataError` otherwise."""
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        raise TooFewSamplesError("at least two samples are needed")
    d = np.diff(t)
    dt = (t[-1] - t[0]) / (t.size - 1)
    if not np.all(d > 0):
        raise DataError("time stamps must strictly increase")
    if np.ptp(d) > 1e-3 * dt + 4e-16 * np.max(np.abs(t)):
        raise DataError("the encoder derivative needs equally spaced samples but the time stamps are irregular; "
                        "resample the recording to a uniform rate first")
    return float(dt)


def savgol_window(window: float, dt: float, n: int) -> int:
    """Odd Savitzky-Golay window length in samples for ``window`` seconds."""
    if not (math.isfinite(window) and window > 0):
        raise InputError(f"smoothing window must be a positive number of seconds, got {window!r}")
    if not window / dt <= n:
        # Checked before the conversion to samples: 1e308 s over a short step is infinity, not an integer.
        raise InputError(f"the smoothing window ({window:g} s) is longer than the record ({n} samples of {dt:g} s); "
                         "use a shorter --window or a longer record")
    m = int(round(window / dt)) | 1
    m = max(m, POLYORDER + 2)  # the smallest odd window a cubic can be fitted in
    if m > n:
        raise TooFewSamplesError(
            f"the smoothing window ({m} samples = {m * dt:g} s) is longer than the record ({n} samples); "
            "use a shorter --window or a longer record"
        )
    return m


def savgol(x: np.ndarray, m: int, deriv: int = 0, dt: float = 1.0, polyorder: int = POLYORDER) -> np.ndarray:
    """``scipy.signal.savgol_filter(x, m, polyorder, deriv, delta=dt, mode="interp")``, FFT-convolved inside.

    Long windows on long records make the direct convolution O(N m); the
    interior is convolved by overlap-add instead and the first and last
    half windows come from ``savgol_filter`` itself (polynomial fit), so the
    result equals scipy's to rounding.
    """
    n = x.size
    if n >= 2 and polyorder >= 1:
        # Filter the departure from the straight line through the ends, and add the line's own result
        # back exactly: an unwrapped angle reaches thousands of rad, and the convolution's rounding,
        # proportional to that size, biased the mean of the second derivative (1e-3 rad/s^2 at 1000 turns).
        slope = (x[-1] - x[0]) / (n - 1)
        line = x[0] + slope * np.arange(n)
        out = _savgol(x - line, m, deriv, dt, polyorder)
        if deriv == 0:
            return out + line
        return out + (slope / dt if deriv == 1 else 0.0)
    return _savgol(x, m, deriv, dt, polyorder)


def _savgol(x: np.ndarray, m: int, deriv: int, dt: float, polyorder: int) -> np.ndarray:
    n = x.size
    if n < 4 * m or m < 64:
        return savgol_filter(x, m, polyorder, deriv=deriv, delta=dt, mode="interp")
    h = savgol_coeffs(m, polyorder, deriv=deriv, delta=dt)
    out = oaconvolve(x, h, mode="same")
    e = m // 2
    edge = _edge_matrix(m, polyorder, deriv, float(dt))
    out[:e] = edge[:e] @ x[:m]
    out[n - e:] = edge[m - e:] @ x[n - m:]
    return out


@functools.lru_cache(maxsize=64)
def _edge_matrix(m: int, polyorder: int, deriv: int, dt: float) -> np.ndarray:
    """``savgol_filter(.., mode="interp")`` on one window as a matrix: polynomial fit, then its derivative.

    Row ``i`` gives the ``deriv``-th derivative (per ``dt``) at sample ``i`` of the least-squares
    polynomial through the window's ``m`` samples (scipy fits the same polynomial at each edge).
    """
    k = np.arange(m, dtype=float) - (m - 1) / 2.0
    scale = (m - 1) / 2.0 or 1.0
    u = k / scale
    vander = np.vander(u, polyorder + 1, increasing=True)
    fit = np.linalg.pinv(vander)  # coefficients of u^j
    dv = np.zeros_like(vander)
    for j in range(deriv, polyorder + 1):
        dv[:, j] = math.perm(j, deriv) * u ** (j - deriv)
    out = dv @ fit / (scale * dt) ** deriv
    out.setflags(write=False)
    return out


def smooth(x: np.ndarray, m: int) -> np.ndarray:
    """Savitzky-Golay smoothing (cubic, ``m`` samples): the same low-pass the encoder derivative has."""
    return savgol(x, m)


def white_noise_std(x: np.ndarray, m: int) -> float:
    """Standard deviation of the white noise on ``x``, from ``x`` minus its Savitzky-Golay smoothing.

    Signal the cubic window follows cancels; white noise of variance ``s^2``
    leaves ``(1 - 2 h0[c] + |h0|^2) s^2``, which is divided out.  Samples
    within half a window of the ends are not used.
    """
    h0 = savgol_coeffs(m, POLYORDER)
    e = m // 2
    resid = (x - smooth(x, m))[e:x.size - e]
    if resid.size == 0:
        return 0.0
    keep = 1.0 - 2.0 * h0[e] + float(h0 @ h0)
    return float(np.sqrt(np.mean(resid**2) / keep))


@dataclass(frozen=True)
class EncoderKinematics(ResultMixin):
    """Angular velocity and acceleration from the encoder angle.

    Attributes
    ----------
    angle : ndarray
        Savitzky-Golay smoothed angle, rad: the encoder's quantisation
        (step / sqrt(12)) reduced by ``smoothing_gain``, the motion kept.
    angular_velocity : ndarray
        Savitzky-Golay first derivative of the angle, rad/s.
    angular_acceleration : ndarray
        Savitzky-Golay second derivative, rad/s^2.
    window_samples : int
        Filter length (odd); cubic polynomial.
    window : float
        Filter length in s.
    angle_noise : float
        Estimated noise of the angle (rad), from the angle minus its
        smoothed value (encoder quantisation ~ step / sqrt(12)).
    u_angular_acceleration : float
        Standard deviation of ``angular_acceleration`` caused by ``angle_noise``
        if that noise were white, rad/s^2.  Quantisation of a smooth motion
        is not white (its error pattern repeats with the count rate), so
        take this as an estimate within about a factor of two.
    smoothing_gain : float
        ``sqrt(sum h0^2)`` of the smoothing filter: white noise of standard
        deviation s becomes ``s * smoothing_gain`` after :func:`smooth`.
    """

    angle: np.ndarray = field(repr=False)
    angular_velocity: np.ndarray = field(repr=False)
    angular_acceleration: np.ndarray = field(repr=False)
    window_samples: int
    window: float
    angle_noise: float
    u_angular_acceleration: float
    smoothing_gain: float

    @property
    def edge(self) -> int:
        """Samples at each end where the filter extrapolates (excluded from statistics)."""
        return self.window_samples // 2


def encoder_kinematics(theta: np.ndarray, dt: float, *, window: float = 0.1) -> EncoderKinematics:
    """Angular velocity and acceleration of the shaft from its encoder angle.

    Parameters
    ----------
    theta : ndarray, shape (N,)
        Unwrapped angle in rad (see :func:`angle_to_rad`).
    dt : float
        Sample interval in s (uniform).
    window : float
        Savitzky-Golay window in s (cubic fit).  Longer windows lower the
        quantisation noise of the second derivative (about ``window^-2.5``)
        but flatten angular accelerations faster than about ``1 / window`` Hz.

    Returns
    -------
    EncoderKinematics
    """
    n = theta.size
    m = savgol_window(window, dt, n)
    w = savgol(theta, m, 1, dt)
    al = savgol(theta, m, 2, dt)
    h0 = savgol_coeffs(m, POLYORDER)
    h2 = savgol_coeffs(m, POLYORDER, deriv=2, delta=dt)
    s_theta = white_noise_std(theta, m)
    return EncoderKinematics(angle=smooth(theta, m), angular_velocity=w, angular_acceleration=al, window_samples=int(m), window=m * dt,
                             angle_noise=s_theta, u_angular_acceleration=s_theta * float(np.linalg.norm(h2)),
                             smoothing_gain=float(np.linalg.norm(h0)))
