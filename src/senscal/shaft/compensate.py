"""Gravity compensation of a tangential accelerometer and its validation against the encoder.

References
----------
.. [1] Yang X., Li C., Mu D., Chen C., "New application of the sinusoidal
   excitation method in sensor calibration", Transducer and Microsystem
   Technologies, 2014 (seed 000, experiment 2; ``shared/METHODS.md`` 1c).
.. [2] Savitzky A., Golay M. J. E., Analytical Chemistry 36 (1964): the
   smoothing differentiator of the encoder angle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.shaft.angle import angle_to_rad, check_radius, encoder_kinematics, savgol, smooth
from senscal.shaft.model import GravityModel, by_angle, check_accel, fit_angle, time_step

__all__ = ["ShaftCompensation", "compensate", "centripetal_leakage"]


@dataclass(frozen=True)
class ShaftCompensation(ResultMixin):
    """Gravity-compensated run: tangential and angular acceleration with the encoder's check.

    Arrays (shape (N,), not in :meth:`to_dict`) and a summary of scalars.

    Attributes
    ----------
    t : ndarray
        Time, s.
    angle : ndarray
        Unwrapped encoder angle, rad.
    tangential_acceleration : ndarray
        ``(accel - gravity(angle)) / S``, m/s^2; with ``remove_centripetal``
        also minus the leakage and divided by ``cos(misalignment)``.
    angular_acceleration : ndarray
        ``tangential_acceleration / radius``, rad/s^2 (not smoothed).
    angular_acceleration_encoder : ndarray
        Savitzky-Golay second derivative of the angle, rad/s^2.
    angular_velocity_encoder : ndarray
        Savitzky-Golay first derivative of the angle, rad/s.
    uncompensated_angular_acceleration : ndarray
        ``accel / (S radius)`` with nothing removed, rad/s^2.
    radius : float
        m.
    window : float
        Savitzky-Golay window (cubic) used for the encoder and for the
        smoothed comparison, s.
    n_samples : int
    revolutions : float
        Turns of the run (net).
    rms_difference : float
        RMS of (accelerometer alpha smoothed with the same window - encoder
        alpha), rad/s^2, over the samples away from the filter's edges.
    rms_difference_raw : float
        The same without smoothing the accelerometer, rad/s^2.
    expected_rms_difference : float
        What ``rms_difference`` should be from noise alone: calibration noise
        floor after smoothing and encoder quantisation through the
        differentiator, rad/s^2.
    correlation : float
        Correlation of the smoothed accelerometer alpha with the encoder alpha.
    uncompensated_rms_difference : float
        RMS of (uncompensated alpha smoothed - encoder alpha), rad/s^2.
    noise_floor : float
        Per-sample noise of ``angular_acceleration`` from the calibration's
        accelerometer noise, rad/s^2 (``noise / (S radius)``).
    noise_floor_smoothed : float
        ``noise_floor`` after the smoothing window, rad/s^2.
    encoder_noise : float
        Noise of the encoder alpha from the angle's quantisation, rad/s^2.
    residual_gravity_amplitude, u_residual_gravity_amplitude : float or None
        Sinusoid of the angle left in ``tangential_acceleration - radius *
        encoder alpha``, m/s^2 (None for runs under one revolution).
    centripetal_coefficient, u_centripetal_coefficient : float or None
        ``k r`` (m) of the removed leakage ``k r (w^2 - w_cal^2)`` (None when not asked).
    misalignment, u_misalignment : float or None
        ``asin(k)``: sensitive axis turned toward the centre, rad.
    bias_change, u_bias_change : float or None
        Change of the sensor bias since calibration, m/s^2 (from the leakage
        regression); its u includes the calibration's ``u_offset``.
    warnings : tuple of str
    """

    t: np.ndarray = field(repr=False)
    angle: np.ndarray = field(repr=False)
    tangential_acceleration: np.ndarray = field(repr=False)
    angular_acceleration: np.ndarray = field(repr=False)
    angular_acceleration_encoder: np.ndarray = field(repr=False)
    angular_velocity_encoder: np.ndarray = field(repr=False)
    uncompensated_angular_acceleration: np.ndarray = field(repr=False)
    radius: float
    window: float
    n_samples: int
    revolutions: float
    rms_difference: float
    rms_difference_raw: float
    expected_rms_difference: float
    correlation: float
    uncompensated_rms_difference: float
    noise_floor: float
    noise_floor_smoothed: float
    encoder_noise: float
    residual_gravity_amplitude: float | None
    u_residual_gravity_amplitude: float | None
    centripetal_coefficient: float | None
    u_centripetal_coefficient: float | None
    misalignment: float | None
    u_misalignment: float | None
    bias_change: float | None
    u_bias_change: float | None
    warnings: tuple[str, ...] = ()

    @property
    def angular_acceleration_smoothed(self) -> np.ndarray:
        """``angular_acceleration`` through the same Savitzky-Golay window as the encoder, rad/s^2."""
        dt = (self.t[-1] - self.t[0]) / (self.t.size - 1)
        return smooth(self.angular_acceleration, int(round(self.window / dt)) | 1)


def centripetal_leakage(tangential, alpha_encoder, omega_encoder, radius: float, mean_square_speed: float,
                        block: int):
    """Regress ``tangential - r alpha_encoder`` on ``w^2 - w_cal^2`` and a constant.

    A sensitive axis turned by ``d`` toward the centre adds ``sin(d) r w^2``;
    the calibration absorbed its value at the calibration speeds into the
    offset, so what is left is ``k r (w^2 - w_cal^2)``.  The regression runs
    on block means (``block`` samples, one filter window) so that the
    residuals, coloured by the encoder filter, are close to independent and
    the standard uncertainties mean what they say.

    Parameters
    ----------
    tangential : ndarray
        Compensated tangential acceleration, m/s^2.
    alpha_encoder, omega_encoder : ndarray
        Encoder angular acceleration (rad/s^2) and velocity (rad/s).
    radius : float
        m.
    mean_square_speed : float
        Mean ``w^2`` of the calibration run, rad^2/s^2.
    block : int
        Samples per block.

    Returns
    -------
    (kr, u_kr, c, u_c) : tuple of float
        Leakage coefficient ``k r`` (m) and the constant (m/s^2, a bias change
        since calibration), with standard uncertainties; NaN uncertainties
        when there are too few blocks or no speed change to regress on.
    """
    d = tangential - radius * alpha_encoder
    x = omega_encoder**2 - mean_square_speed
    nb = d.size // block
    if nb < 3:
        return 0.0, math.nan, float(np.mean(d)), math.nan
    db = d[: nb * block].reshape(nb, block).mean(axis=1)
    xb = x[: nb * block].reshape(nb, block).mean(axis=1)
    a = np.column_stack([xb, np.ones(nb)])
    coef, _, rank, _ = scipy.linalg.lstsq(a, db)
    if rank < 2:
        return 0.0, math.nan, float(np.mean(d)), math.nan
    res = db - a @ coef
    cov = np.linalg.inv(a.T @ a) * float(res @ res) / (nb - 2)
    return float(coef[0]), float(math.sqrt(cov[0, 0])), float(coef[1]), float(math.sqrt(cov[1, 1]))


def compensate(model: GravityModel, accel, angle, t=None, *, fs: float | None = None, radius: float,
               angle_unit: str = "rad", window: float | None = None, remove_centripetal: bool = False,
               accel_unit: str | None = None) -> ShaftCompensation:
    """Remove the identified gravity term and return tangential and angular acceleration.

    Parameters
    ----------
    model : GravityModel
        From :func:`calibrate_gravity` (or :func:`load_model`).
    accel : array_like, shape (N,)
        Accelerometer output, in the unit of the calibration.
    angle : array_like, shape (N,)
        Encoder angle in ``angle_unit`` (wrapped angles are unwrapped; the
        shaft may reverse).
    t : array_like, shape (N,), optional
        Time stamps, s (uniform).  Give ``t`` or ``fs``.
    fs : float, optional
        Sample rate, Hz.
    radius : float
        Distance of the sensor from the axis, m (> 0).
    angle_unit : {"rad", "deg"}
    window : float, optional
        Savitzky-Golay window (s) of the encoder derivatives and of the
        smoothed comparison; default: the calibration's.
    remove_centripetal : bool
        Estimate and remove the centripetal leakage ``k r (w^2 - w_cal^2)``
        of a misaligned sensitive axis by regression on the encoder's ``w^2``
        (beyond the paper; needs a run whose speed changes).
    accel_unit : str, optional
        Unit of ``accel``, checked against the model.

    Returns
    -------
    ShaftCompensation

    Raises
    ------
    InputError
        Radius <= 0, unit mismatch, bad arguments.
    DataError
        NaN/inf, irregular time stamps.

    References
    ----------
    .. [1] Yang X., Li C., Mu D., Chen C., Transducer and Microsystem
       Technologies, 2014 (seed 000, experiment 2: compensation by the
       identified gravity term; METHODS.md 1c).
    .. [2] Savitzky A., Golay M. J. E., Analytical Chemistry 36 (1964).
    """
    r = check_radius(radius)
    model.check_applicable(accel_unit=accel_unit)
    theta = angle_to_rad(angle, angle_unit)
    n = theta.size
    a = check_accel(accel, n)
    dt = time_step(n, t, fs)
    tt = np.asarray(t, dtype=float) if t is not None else np.arange(n) * dt
    kin = encoder_kinematics(theta, dt, window=model.window if window is None else window)
    s = model.sensitivity
    # Gravity at the smoothed angle: the raw count's quantisation would add amplitude * step/sqrt(12) of noise.
    at = (a - model.gravity(kin.angle)) / s
    warnings: list[str] = []
    kr = u_kr = c = u_c = mis = u_mis = None
    if remove_centripetal:
        # Quintic derivatives over three windows: flat to 0.1 % up to 1/(12 window) (the cubic ones leave a
        # few tenths of a percent of the speed modulation's alpha in the difference), with 15 times less
        # quantisation noise than the compensation's own window; either would count as noise in the regression.
        # Blocks stay one window long: the accelerometer's white noise then dominates the block means, and
        # more blocks keep k=2 near 95 % (with 15 blocks, Student's t would make it 93 %).
        m5 = min(3 * kin.window_samples, n - 1 + n % 2)
        p5 = 5 if m5 >= 7 else 3
        # The filters extrapolate over their first and last half window: those samples stay out.
        mid = slice(m5 // 2, n - m5 // 2) if n > 2 * m5 else slice(0, n)
        kr, u_kr, c, u_c = centripetal_leakage(at[mid], savgol(theta, m5, 2, dt, polyorder=p5)[mid],
                                               savgol(theta, m5, 1, dt, polyorder=p5)[mid], r,
                                               model.mean_square_speed, kin.window_samples)
        if math.isnan(u_kr):
            warnings.append(named("centripetal-not-estimable", (
                "the speed hardly changes in this run (or it is too short): the centripetal leakage cannot be "
                "estimated and was not removed; compensate a run whose speed varies")))
            kr = u_kr = c = u_c = None
        else:
            # The bias change is measured against the calibration's offset: its uncertainty is in it too.
            u_c = math.hypot(u_c, model.u_offset / s)
            k = kr / r
            mis = math.asin(max(-1.0, min(1.0, k)))
            u_mis = u_kr / r / math.sqrt(max(1.0 - k * k, 1e-12))
            # The same turned axis sees only cos(d) of the tangential acceleration.
            at = (at - kr * (kin.angular_velocity**2 - model.mean_square_speed)) / math.cos(mis)
    alpha = at / r
    alpha_unc = a / (s * r)
    m = kin.window_samples
    e = kin.edge
    inner = slice(e, n - e) if n > 2 * e + 2 else slice(0, n)
    al_enc = kin.angular_acceleration
    al_s = smooth(alpha, m)
    diff = (al_s - al_enc)[inner]
    rms = float(np.sqrt(np.mean(diff**2)))
    rms_raw = float(np.sqrt(np.mean((alpha - al_enc)[inner] ** 2)))
    unc = float(np.sqrt(np.mean((smooth(alpha_unc, m) - al_enc)[inner] ** 2)))
    sa, se = al_s[inner], al_enc[inner]
    corr = float(np.corrcoef(sa, se)[0, 1]) if np.std(sa) > 0 and np.std(se) > 0 else math.nan
    floor = model.noise / (s * r)
    floor_s = floor * kin.smoothing_gain
    expected = math.hypot(floor_s, kin.u_angular_acceleration)

    revs = abs(float(theta[-1] - theta[0])) / (2.0 * math.pi)
    res_amp = u_res_amp = None
    if float(np.ptp(theta)) >= 2.0 * math.pi:
        x, w, (y,) = by_angle(kin.angle[inner], (at - r * al_enc)[inner])
        fit = fit_angle(y, x, w)
        res_amp, u_res_amp = float(fit.amplitude), float(fit.u_amplitude)
        limit = max(5.0 * u_res_amp, 0.02 * model.amplitude / s)
        if res_amp > limit:
            warnings.append(named("gravity-left", (
                f"a gravity-like sinusoid of {res_amp:.3g} m/s^2 ({100 * res_amp * s / model.amplitude:.3g}% of the "
                "calibrated one) is left after compensation: the sensor was remounted, the angle zero or channel "
                "differs, or the model belongs to another sensor; recalibrate")))
    if math.isfinite(corr) and rms > 3.0 * expected and rms > 0.1 * float(np.std(se)):
        warnings.append(named("encoder-mismatch", (
            f"accelerometer and encoder angular accelerations differ by {rms:.3g} rad/s^2 RMS (noise alone would "
            f"give {expected:.3g}); check the radius and the model"
            + ("" if remove_centripetal else ", or remove the centripetal leakage of a misaligned axis (--centripetal)"))))
    return ShaftCompensation(
        t=tt, angle=theta, tangential_acceleration=at, angular_acceleration=alpha, angular_acceleration_encoder=al_enc,
        angular_velocity_encoder=kin.angular_velocity, uncompensated_angular_acceleration=alpha_unc, radius=r,
        window=kin.window, n_samples=int(n), revolutions=revs, rms_difference=rms, rms_difference_raw=rms_raw,
        expected_rms_difference=expected, correlation=corr, uncompensated_rms_difference=unc, noise_floor=floor,
        noise_floor_smoothed=floor_s, encoder_noise=kin.u_angular_acceleration, residual_gravity_amplitude=res_amp,
        u_residual_gravity_amplitude=u_res_amp, centripetal_coefficient=kr, u_centripetal_coefficient=u_kr,
        misalignment=mis, u_misalignment=u_mis, bias_change=c, u_bias_change=u_c, warnings=tuple(warnings),
    )
