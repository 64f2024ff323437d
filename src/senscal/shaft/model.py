"""Gravity identification on a rotating shaft: the calibration and its model.

A single-axis accelerometer mounted tangentially at radius ``r`` on a shaft
whose axis is tilted by ``tilt`` from the horizontal reads, in its output
unit (sensitivity ``S``)::

    a(theta) = S * (r * alpha + g cos(tilt) sin(theta + phi_0)) + bias + noise

At (nearly) constant speed ``alpha ~ 0`` and the reading is a sinusoid of
the encoder angle: fitting ``amplitude * sin(theta + phase) + offset``
against the angle (not time) identifies the gravity term whatever the speed
ripple does to the time axis [1]_.

References
----------
.. [1] Yang X., Li C., Mu D., Chen C., "New application of the sinusoidal
   excitation method in sensor calibration", Transducer and Microsystem
   Technologies, 2014 (seed 000, experiment 2, eq. 11 and fig. 4;
   ``shared/METHODS.md`` section 1c).
.. [2] Frisch R., Waugh F. V., "Partial time regressions as compared with
   individual trends", Econometrica 1 (1933): the nuisance regressor is
   projected out with the sine fit itself.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import DataError, FileFormatError, InputError, TooFewSamplesError
from senscal.shaft.angle import angle_to_rad, check_radius, check_uniform, encoder_kinematics, savgol, white_noise_std
from senscal.sinefit import fit_sine, wrap_phase

__all__ = ["G", "GravityModel", "calibrate_gravity", "load_model"]

G = 9.80665
ANGLE_FREQ = 1.0 / (2.0 * math.pi)  # fit_sine against an angle in rad: one cycle per revolution
KIND = "senscal.shaft.GravityModel"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class GravityModel(ResultMixin):
    """The identified gravity term of a tangential accelerometer on a shaft.

    ``gravity(theta) = amplitude * sin(theta + phase) + offset`` in the
    accelerometer's output unit, ``theta`` the encoder angle in rad.  The
    model saves and loads itself as JSON (:meth:`save`, :func:`load_model`)
    with its ``kind`` and ``format_version``, and checks the data it is
    applied to (:meth:`check_applicable`).

    Attributes
    ----------
    amplitude, u_amplitude : float
        Peak gravity amplitude, output unit (``S g cos(tilt)``).
    phase, u_phase : float
        Phase at encoder zero, rad, in (-pi, pi].
    offset, u_offset : float
        Constant term, output unit: sensor bias plus the centripetal leakage
        of a misaligned axis at the calibration speed.
    covariance : ndarray, shape (3, 3)
        Covariance of (amplitude, phase, offset).
    residual_rms : float
        RMS of the per-sample residuals, output unit.
    noise : float
        White noise of the accelerometer, output unit, from the output minus
        its Savitzky-Golay smoothing (``residual_rms`` also holds the encoder
        differentiator's noise the ripple correction brings in).
    sensitivity, u_sensitivity : float
        Output unit per m/s^2 (1 when the output is in m/s^2).
    output_unit : str
        Unit of the accelerometer channel at calibration ('' if unknown).
    g : float
        Local gravity, m/s^2.
    tilt, u_tilt : float
        Shaft tilt from horizontal, rad: ``acos(amplitude / (S g))``.
    bias, u_bias : float
        ``offset / S`` in m/s^2.
    revolutions : float
        Turns covered by the calibration run.
    n_samples : int
        Samples used.
    mean_speed : float
        Mean angular velocity, rad/s (sign = direction).
    mean_square_speed : float
        Mean of ``w^2`` over the run, rad^2/s^2 (reference of the centripetal leakage).
    speed_variation : float
        Standard deviation of the speed over its mean (ratio).
    angular_acceleration_rms : float
        RMS angular acceleration from the encoder, rad/s^2.
    ripple_correction : str
        How encoder-measured angular acceleration was kept out of the fit:
        ``"regression"`` (coefficient estimated with the fit), ``"radius"``
        (``S r alpha`` subtracted for a given radius) or ``"none"``.
    ripple_coefficient, u_ripple_coefficient : float
        Output per unit encoder angular acceleration (``S r`` ideally),
        output unit / (rad/s^2).
    ripple_leak : float
        Change of the amplitude caused by the correction (what a plain fit
        would have got wrong), output unit.
    radius : float or None
        Radius given for the ``"radius"`` correction, m.
    window : float
        Savitzky-Golay window of the encoder derivatives, s.
    warnings : tuple of str
        What the data say about the run: speed far from constant, ripple
        leaking into the fit uncorrected or locked to the rotation, amplitude
        above ``S g``, an output unit that is not m/s^2 without a sensitivity.
    source : str or None
        File the calibration came from.
    created : str
        UTC time of the calibration (ISO 8601).
    kind, format_version
        Type tag and file format version of the saved model.
    """

    amplitude: float
    phase: float
    offset: float
    u_amplitude: float
    u_phase: float
    u_offset: float
    covariance: np.ndarray
    residual_rms: float
    noise: float
    sensitivity: float
    u_sensitivity: float
    output_unit: str
    g: float
    tilt: float
    u_tilt: float
    bias: float
    u_bias: float
    revolutions: float
    n_samples: int
    mean_speed: float
    mean_square_speed: float
    speed_variation: float
    angular_acceleration_rms: float
    ripple_correction: str
    ripple_coefficient: float
    u_ripple_coefficient: float
    ripple_leak: float
    radius: float | None
    window: float
    warnings: tuple[str, ...] = ()
    source: str | None = None
    created: str = ""
    kind: str = KIND
    format_version: int = FORMAT_VERSION

    # -- the model -------------------------------------------------------------
    def gravity(self, theta) -> np.ndarray:
        """Gravity term (output unit) at encoder angles ``theta`` (rad, unwrapped or not)."""
        return self.amplitude * np.sin(np.asarray(theta, dtype=float) + self.phase) + self.offset

    def u_gravity(self, theta) -> np.ndarray:
        """Standard uncertainty of :meth:`gravity` from the fit covariance, output unit."""
        x = np.asarray(theta, dtype=float) + self.phase
        jac = np.stack([np.sin(x), self.amplitude * np.cos(x), np.ones_like(x)], axis=-1)
        return np.sqrt(np.einsum("...i,ij,...j->...", jac, np.asarray(self.covariance), jac))

    def check_applicable(self, *, accel_unit: str | None = None) -> None:
        """Check that an accelerometer channel may be compensated with this model.

        Parameters
        ----------
        accel_unit : str, optional
            Unit of the accelerometer channel ('' or None when unknown); must
            match the calibration's when both are known.

        Raises
        ------
        InputError
            The units differ (another sensor or a rescaled channel).

        Notes
        -----
        :func:`senscal.shaft.compensate` also checks the data themselves:
        a gravity term left after compensation (sensor remounted, another
        sensor, wrong angle zero) is reported as a warning.
        """
        if accel_unit and self.output_unit and accel_unit.strip() != self.output_unit.strip():
            raise InputError(
                f"the accelerometer channel is in '{accel_unit}' but the model was calibrated in "
                f"'{self.output_unit}'; convert the channel or recalibrate with this sensor"
            )

    # -- persistence -----------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (phases also in degrees)."""
        d = super().to_dict()
        d["phase_deg"] = math.degrees(self.phase)
        d["u_phase_deg"] = math.degrees(self.u_phase)
        d["tilt_deg"] = math.degrees(self.tilt)
        d["u_tilt_deg"] = math.degrees(self.u_tilt)
        return d

    def save(self, path: str | Path) -> Path:
        """Write the model as JSON (folders created)."""
        from senscal.io.guard import check_output, write_text

        path = check_output(path, what="model file")
        write_text(path, json.dumps(self.to_dict(), indent=2) + "\n", what="model file")
        return path

    @classmethod
    def from_dict(cls, d: dict[str, Any], *, source: str = "model") -> "GravityModel":
        """Rebuild a model from :meth:`to_dict` output, checking its type and version."""
        if not isinstance(d, dict) or d.get("kind") != KIND:
            kind = d.get("kind") if isinstance(d, dict) else type(d).__name__
            raise FileFormatError(f"{source} is not a senscal shaft gravity model (kind={kind!r}); "
                                  "give the MODEL.json written by 'senscal shaft calibrate --out'")
        ver = d.get("format_version")
        if not isinstance(ver, int) or ver > FORMAT_VERSION or ver < 1:
            raise FileFormatError(f"{source} has model format version {ver!r} but this senscal reads up to "
                                  f"{FORMAT_VERSION}; upgrade senscal or recalibrate")
        names = {f.name for f in dataclasses.fields(cls)}
        kw = {k: v for k, v in d.items() if k in names}
        missing = [f.name for f in dataclasses.fields(cls)
                   if f.name not in kw and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
        if missing:
            raise FileFormatError(f"{source} lacks the field(s) {', '.join(missing)}; recalibrate to rewrite it")
        for k in ("amplitude", "phase", "offset", "u_amplitude", "u_phase", "u_offset", "sensitivity", "g"):
            if not isinstance(kw[k], (int, float)) or not math.isfinite(kw[k]):
                raise FileFormatError(f"{source} has a non-numeric '{k}' ({kw[k]!r}); recalibrate to rewrite it")
        from senscal.io.sidefiles import array_field

        kw["covariance"] = array_field(kw["covariance"], (3, 3), f"'covariance' in {source}")
        kw["warnings"] = tuple(kw.get("warnings") or ())
        return cls(**kw)


def load_model(path: str | Path) -> GravityModel:
    """Read a :class:`GravityModel` written by :meth:`GravityModel.save`."""
    from senscal.io.guard import note_input

    path = Path(path)
    note_input(path)
    if not path.exists():
        raise FileFormatError(f"model file {path} does not exist; run 'senscal shaft calibrate ... --out {path}'")
    from senscal.io.sidefiles import read_json

    d = read_json(path, "model file", expect=None)  # from_dict names a wrong top-level type
    return GravityModel.from_dict(d, source=f"model file {path}")


# ---------------------------------------------------------------------------
# Calibration
# ---------------------------------------------------------------------------

def time_step(n: int, t, fs) -> float:
    if (t is None) == (fs is None):
        raise InputError("give the time stamps t (s) or the sample rate fs (Hz), exactly one of them")
    if t is None:
        fs = float(fs)
        if not (math.isfinite(fs) and fs > 0):
            raise InputError(f"sample rate fs must be a positive number of Hz, got {fs!r}")
        return 1.0 / fs
    t = np.asarray(t, dtype=float)
    if t.shape != (n,):
        raise InputError(f"t must hold one time stamp per sample ({n}), got shape {t.shape}")
    return check_uniform(t)


def check_accel(accel, n: int | None = None) -> np.ndarray:
    a = np.asarray(accel, dtype=np.float64)
    if a.ndim != 1 or (n is not None and a.size != n):
        raise InputError(f"the accelerometer channel must be 1-D with one sample per angle sample ({n}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DataError(f"the accelerometer channel has NaN or inf at sample {int(np.flatnonzero(~np.isfinite(a))[0])}; "
                        "remove or interpolate bad samples first")
    return a


def by_angle(theta: np.ndarray, *ys: np.ndarray):
    """Samples sorted by angle, repeated encoder readings merged (weights = counts).

    The gravity term is a function of the angle only, so the order of the
    samples does not matter; merging equal angles keeps the least-squares
    problem identical while giving the fit a strictly increasing abscissa.
    """
    order = np.argsort(theta, kind="stable")
    x = theta[order]
    ux, inv, cnt = np.unique(x, return_inverse=True, return_counts=True)
    if ux.size == x.size:
        return ux, None, [y[order] for y in ys]
    return ux, cnt.astype(float), [np.bincount(inv, y[order]) / cnt for y in ys]


def fit_angle(y, x, w=None):
    return fit_sine(y, x, freq=ANGLE_FREQ, weights=w)


def calibrate_gravity(accel, angle, t=None, *, fs: float | None = None, angle_unit: str = "rad",
                      sensitivity: float = 1.0, u_sensitivity: float = 0.0, output_unit: str = "",
                      radius: float | None = None, ripple_correction: bool = True, g: float = G,
                      window: float = 0.1, max_speed_variation: float = 0.10,
                      source: str | None = None) -> GravityModel:
    """Identify the gravity term seen by a tangential accelerometer on a shaft.

    Fits ``amplitude * sin(theta + phase) + offset`` to the accelerometer
    against the unwrapped encoder angle (the three-parameter sine fit with
    the angle as abscissa), so speed ripple does not distort the sinusoid.

    Parameters
    ----------
    accel : array_like, shape (N,)
        Accelerometer output (output unit: m/s^2 or V, ...).
    angle : array_like, shape (N,)
        Encoder angle in ``angle_unit``; wrapped angles are unwrapped.  Must
        not reverse during the run.
    t : array_like, shape (N,), optional
        Time stamps, s (uniform).  Give ``t`` or ``fs``.
    fs : float, optional
        Sample rate, Hz.
    angle_unit : {"rad", "deg"}
        Unit of ``angle``.
    sensitivity : float
        Output per m/s^2 (1 for an output in m/s^2), used for the tilt and
        the bias in m/s^2.
    u_sensitivity : float
        Standard uncertainty of ``sensitivity``.
    output_unit : str
        Unit of ``accel``, stored so compensation can check it.
    radius : float, optional
        Radius of the sensor, m.  When given, ``sensitivity * radius *
        alpha_encoder`` is subtracted before the fit (works for ripple locked
        to the rotation too).
    ripple_correction : bool
        Without ``radius``: estimate the response to the encoder's angular
        acceleration together with the gravity term (a fourth regressor,
        projected out with the sine fit itself [2]_), so non-synchronous
        speed ripple does not leak into the fit; its uncertainty enters the
        reported covariance.  False gives the plain three-parameter fit of
        the paper [1]_.
    g : float
        Local gravity, m/s^2.
    window : float
        Savitzky-Golay window for the encoder derivatives, s.
    max_speed_variation : float
        Speed standard deviation over mean speed above which a warning says
        the run was not at constant speed.
    source : str, optional
        Where the data came from (stored in the model).

    Returns
    -------
    GravityModel

    Raises
    ------
    TooFewSamplesError
        Less than one full revolution.
    DataError
        NaN/inf, a reversing angle, irregular time stamps.
    InputError
        Bad arguments (sensitivity <= 0, radius <= 0, ...).

    References
    ----------
    .. [1] Yang X., Li C., Mu D., Chen C., Transducer and Microsystem
       Technologies, 2014 (seed 000, experiment 2; METHODS.md 1c).
    .. [2] Frisch R., Waugh F. V., Econometrica 1 (1933).
    """
    theta = angle_to_rad(angle, angle_unit, monotonic=True)
    n = theta.size
    a = check_accel(accel, n)
    if not (math.isfinite(sensitivity) and sensitivity > 0):
        raise InputError(f"sensitivity must be a positive number (output per m/s^2), got {sensitivity!r}")
    if not (math.isfinite(u_sensitivity) and u_sensitivity >= 0):
        raise InputError(f"u_sensitivity must be >= 0, got {u_sensitivity!r}")
    if not (math.isfinite(g) and g > 0):
        raise InputError(f"g must be a positive acceleration in m/s^2, got {g!r}")
    if radius is not None:
        radius = check_radius(radius)
    revs = abs(float(theta[-1] - theta[0])) / (2.0 * math.pi)
    if revs < 1.0:
        raise TooFewSamplesError(
            f"the calibration run covers only {revs:.3g} revolutions ({math.degrees(abs(theta[-1] - theta[0])):.4g} deg); "
            "record at least one full revolution (several are better), or check --angle-unit"
        )
    dt = time_step(n, t, fs)
    kin = encoder_kinematics(theta, dt, window=window)
    e = kin.edge
    w_in = kin.angular_velocity[e:n - e] if n > 2 * e + 2 else kin.angular_velocity
    al_in = kin.angular_acceleration[e:n - e] if n > 2 * e + 2 else kin.angular_acceleration
    mean_speed = float(np.mean(w_in))
    speed_var = float(np.std(w_in) / abs(mean_speed)) if mean_speed != 0 else math.inf
    alpha = kin.angular_acceleration
    # Instrument for the response to alpha: the same derivative over a window three times longer.
    # Its quantisation noise is far smaller and nearly independent of alpha's, so the coefficient is
    # not pulled toward zero by the noise in alpha (errors in variables), as least squares would be.
    ninst = min(n - 1 + n % 2, 3 * kin.window_samples)
    inst = savgol(theta, ninst, 2, dt)
    ei = ninst // 2

    # The filters extrapolate over their first and last half window: keep those samples out of the
    # fit when the encoder's angular acceleration is used, unless that would leave < 1 revolution.
    use_alpha = bool(ripple_correction or radius)
    keep = slice(ei, n - ei) if use_alpha and n > 2 * ei + 2 and abs(theta[n - ei - 1] - theta[ei]) >= 2.0 * math.pi \
        else slice(0, n)
    # The abscissa is the smoothed angle: the encoder's quantisation would otherwise be an error in
    # the variable (amplitude * step / sqrt(12) of extra residual and a small sinc bias of the amplitude).
    th_fit = kin.angle
    x, wts, (ya, yal, yz) = by_angle(th_fit[keep], a[keep], alpha[keep], inst[keep])
    # Frisch-Waugh-Lovell: the coefficient of alpha from the sine-fit residuals, here by instrumental
    # variables.  (Channel by channel: the engine's batched path is slower on a non-uniform abscissa.)
    plain, fal, finst = (fit_angle(y, x, wts) for y in (ya, yal, yz))
    ra, ral, rz = ya - plain.evaluate(x), yal - fal.evaluate(x), yz - finst.evaluate(x)
    ww = np.ones_like(x) if wts is None else wts
    szz = float(np.sum(ww * rz * rz))
    sza = float(np.sum(ww * rz * ral))
    identifiable = szz > 0 and abs(sza) > 0
    b = float(np.sum(ww * rz * ra) / sza) if identifiable else 0.0
    if radius is not None:
        # Subtracting S r alpha needs alpha's true size: a quintic window keeps the once-per-turn
        # ripple unflattened (the cubic one is 0.1-0.5 % low at 1 Hz for 0.1 s, a bias of several u).
        mode, coef = "radius", sensitivity * radius
        alpha = savgol(theta, kin.window_samples, 2, dt, polyorder=5)
        yal = by_angle(th_fit[keep], alpha[keep])[2][0]
    elif ripple_correction and identifiable:
        mode, coef = "regression", b
    else:
        mode, coef = "none", 0.0
    fit = fit_angle(ya - coef * yal, x, wts) if coef != 0.0 else plain
    cov = np.asarray(fit.covariance, dtype=float).copy()
    dof = fit.dof
    u_b = math.nan
    if identifiable:
        # The sine fit is linear in the data: the residual of ya - b*yal is ra - b*ral.
        sigma2 = float(np.sum(ww * (ra - b * ral) ** 2)) / max(dof - 1, 1)
        u_b = math.sqrt(sigma2 * szz) / abs(sza)
    if mode == "regression":
        # Covariance = fixed-coefficient covariance + u_b^2 * g g^T, where g is how (amplitude, phase,
        # offset) move with the coefficient; the cross terms vanish because the instrument's residual
        # is orthogonal to the sine-fit columns.
        cov *= dof / max(dof - 1, 1)
        amp_al, ph_al, off_al = fal.amplitude, fal.phase, fal.offset
        gvec = np.array([-amp_al * math.cos(fit.phase - ph_al),
                         -amp_al * math.sin(ph_al - fit.phase) / fit.amplitude,
                         -off_al])
        cov += u_b**2 * np.outer(gvec, gvec)
    u = np.sqrt(np.diag(cov))
    amp, ph, off = float(fit.amplitude), float(fit.phase), float(fit.offset)
    resid = (a - coef * alpha - (amp * np.sin(th_fit + ph) + off))[keep]
    rms = float(np.sqrt(np.mean(resid**2)))
    noise = white_noise_std(a, kin.window_samples)

    # Tilt from horizontal: cos(tilt) = amplitude / (S g).
    ratio = amp / (sensitivity * g)
    u_ratio = math.hypot(u[0] / (sensitivity * g), ratio * u_sensitivity / sensitivity)
    tilt = math.acos(min(max(ratio, -1.0), 1.0))
    # Near a horizontal shaft acos is not linear: tilt ~ sqrt(2 (1 - ratio)) has spread ~ sqrt(2 u).
    u_tilt = u_ratio / math.sqrt(max(1.0 - min(ratio, 1.0) ** 2, 2.0 * u_ratio))
    bias = off / sensitivity
    u_bias = math.hypot(u[2] / sensitivity, bias * u_sensitivity / sensitivity)

    warnings = []
    if speed_var > max_speed_variation:
        warnings.append(f"speed was far from constant: it varied by {100 * speed_var:.3g}% (std/mean, limit "
                        f"{100 * max_speed_variation:.3g}%); angular acceleration leaks into the gravity fit, "
                        "calibrate at a steadier speed")
    leak = float(plain.amplitude) - amp if mode != "none" else -b * float(fal.amplitude) * math.cos(ph - fal.phase)
    # A leak that was removed is reported in ripple_leak; only one left in the fit is a warning.
    if mode == "none" and abs(leak) > 2.0 * u[0] and math.isfinite(leak):
        warnings.append(f"angular acceleration during the run moved the gravity amplitude by about {leak:.3g} "
                        f"({abs(leak) / u[0]:.3g} standard uncertainties) and was NOT removed: enable the ripple "
                        "correction or give the radius")
    if mode == "regression" and u[0] > 3.0 * math.sqrt(fit.covariance[0][0]):
        warnings.append(f"the speed ripple is mostly locked to the rotation, so the fit can hardly tell it from "
                        f"gravity: the amplitude uncertainty grew {u[0] / math.sqrt(fit.covariance[0][0]):.3g} times; "
                        "give the sensor radius (--radius) to remove it, or calibrate at a steadier speed")
    unit = str(output_unit or "").strip()
    if unit and sensitivity == 1.0 and unit.replace(" ", "").replace("²", "^2") not in ("m/s^2", "m/s2", "ms^-2", "m*s^-2"):
        warnings.append(f"the accelerometer output is in '{unit}' but no sensitivity was given: tilt and bias "
                        "assume m/s^2; give the sensitivity (output per m/s^2)")
    if ratio - 1.0 > 3.0 * u_ratio:
        warnings.append(f"gravity amplitude {amp:.6g} exceeds sensitivity * g = {sensitivity * g:.6g}; "
                        "check --sensitivity (the output may not be in m/s^2)")
    return GravityModel(
        amplitude=amp, phase=float(wrap_phase(ph)), offset=off, u_amplitude=float(u[0]), u_phase=float(u[1]),
        u_offset=float(u[2]), covariance=cov, residual_rms=rms, noise=noise, sensitivity=float(sensitivity),
        u_sensitivity=float(u_sensitivity), output_unit=str(output_unit or ""), g=float(g), tilt=tilt,
        u_tilt=u_tilt, bias=bias, u_bias=u_bias, revolutions=revs, n_samples=int(resid.size), mean_speed=mean_speed,
        mean_square_speed=float(np.mean(w_in**2)), speed_variation=speed_var,
        angular_acceleration_rms=float(np.sqrt(np.mean(al_in**2))), ripple_correction=mode,
        ripple_coefficient=float(coef if mode != "none" else b), u_ripple_coefficient=float(u_b if mode != "radius" else 0.0),
        ripple_leak=float(leak), radius=radius, window=kin.window, warnings=tuple(warnings), source=source,
        created=_dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
    )
