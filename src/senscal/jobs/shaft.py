"""Shaft jobs: gravity identification (``shaft-calibrate``) and compensation (``shaft-compensate``).

Both read a run with an encoder angle channel and a tangential accelerometer
channel (Yang et al. 2014, see ``senscal.shaft``).  The jobs load and check
the recording, call the engines and return frozen results; writing the model
file, the compensated recording and the plots stays with the caller (the
CLI), which uses :meth:`ShaftCompensateResult.output_recording` and
:meth:`senscal.shaft.GravityModel.save`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.io.plausibility import merge_time_warnings
from senscal.jobs._base import JobResult, Quantity, ReadOptions, given_or_loaded, source_name

if TYPE_CHECKING:  # the engines load when a job runs, not when the CLI starts
    from senscal.shaft import GravityModel, ShaftCompensation

__all__ = ["ShaftCalibrateOptions", "ShaftCalibrateResult", "shaft_calibrate", "ShaftCompensateOptions",
           "ShaftCompensateResult", "shaft_compensate", "angle_unit_of", "calibration_summary", "METHOD"]

#: How the registry describes the method of a shaft calibration.
METHOD = "gravity sine fit against the encoder angle (Yang et al. 2014)"


def _angle_word(unit: str, name: str) -> str | None:
    """``"deg"`` or ``"rad"`` for a file's angle unit (parsed as a unit), None when the file gives none."""
    from senscal.units import compatible, same_unit

    if not unit.strip():
        return None
    for word in ("deg", "rad"):
        if same_unit(unit, word):
            return word
    kind = "an angle senscal reads only in deg or rad" if compatible(unit, "rad") else "not an angle"
    raise InputError(f"the angle channel '{name}' is in {unit!r}, {kind}; give it in deg or rad")


def _accel_in_si(rec, name: str) -> tuple[np.ndarray, str]:
    """The accelerometer channel and its unit: an acceleration (``g``, ``mg``) in m/s^2, which
    ``--sensitivity 1`` means; a sensor output (V, mV) as it is, ``--sensitivity`` being per m/s^2."""
    from senscal.units import compatible, factor

    data, unit = np.asarray(rec[name], dtype=float), rec.unit(name)
    if unit.strip() and compatible(unit, "m/s^2"):
        return data * factor(unit, "m/s^2", what=f"the accelerometer channel '{name}'"), "m/s^2"
    return data, unit


def angle_unit_of(rec, name: str, given: str | None) -> str:
    """The unit of the encoder angle channel: as given, else from the file, else rad.

    Parameters
    ----------
    rec : Recording
    name : str
        Angle channel.
    given : {"deg", "rad"} or None
        The user's unit; None takes the file's.

    Raises
    ------
    InputError
        A unit other than deg/rad, or one that contradicts the file.
    """
    in_file = _angle_word(rec.unit(name), name)
    if given is None:
        return in_file or "rad"
    g = given.strip().lower()
    if g not in ("deg", "rad"):
        raise InputError(f"--angle-unit must be deg or rad, got {given!r}")
    if in_file and in_file != g:
        raise InputError(f"--angle-unit {g} contradicts the file, which says channel '{name}' is in {in_file}; "
                         "drop --angle-unit or fix the file")
    return g


def calibration_summary(model) -> dict[str, Any]:
    """The JSON document of a gravity calibration (the ``senscal shaft calibrate --json`` contract).

    Phases and tilt in degrees, speed in rev/s, the rest in the model's units.
    """
    return {
        "amplitude": model.amplitude, "u_amplitude": model.u_amplitude,
        "phase_deg": math.degrees(model.phase), "u_phase_deg": math.degrees(model.u_phase),
        "offset": model.offset, "u_offset": model.u_offset, "residual_rms": model.residual_rms,
        "tilt_deg": math.degrees(model.tilt), "u_tilt_deg": math.degrees(model.u_tilt),
        "revolutions": model.revolutions,
        "bias": model.bias, "u_bias": model.u_bias, "noise": model.noise,
        "sensitivity": model.sensitivity, "output_unit": model.output_unit,
        "mean_speed_rps": model.mean_speed / (2 * math.pi), "speed_variation": model.speed_variation,
        "angular_acceleration_rms": model.angular_acceleration_rms,
        "ripple_correction": model.ripple_correction, "ripple_coefficient": model.ripple_coefficient,
        "u_ripple_coefficient": model.u_ripple_coefficient, "ripple_leak": model.ripple_leak,
        "synchronous_ripple": model.synchronous_ripple, "nuisance": list(model.nuisance),
        "u_angle_deg": math.degrees(model.u_angle),
        "once_per_turn_angle_deg": math.degrees(model.once_per_turn_angle),
        "u_once_per_turn_angle_deg": math.degrees(model.u_once_per_turn_angle),
        "angle_error_deg": math.degrees(model.angle_error), "u_angle_error_deg": math.degrees(model.u_angle_error),
        "encoder_step_deg": None if model.encoder_step is None else math.degrees(model.encoder_step),
        "encoder_step_detected": model.encoder_step_detected,
        "u_encoder_step": {"amplitude": model.u_encoder_step[0], "phase_deg": math.degrees(model.u_encoder_step[1]),
                           "offset": model.u_encoder_step[2]},
        "twice_per_turn": model.twice_per_turn, "u_twice_per_turn": model.u_twice_per_turn,
        "centripetal_coefficient": model.centripetal_coefficient,
        "u_centripetal_coefficient": model.u_centripetal_coefficient, "diagnostic": list(model.diagnostic),
        "n_samples": model.n_samples, "window_s": model.window, "warnings": list(model.warnings),
    }


def _u_angle(deg) -> float:
    """``--u-angle-deg`` in rad, refused unless a number in [0, 180)."""
    try:
        v = float(deg)
    except (TypeError, ValueError):
        raise InputError(f"--u-angle-deg must be a number of degrees, got {deg!r}") from None
    if not (math.isfinite(v) and 0.0 <= v < 180.0):
        raise InputError(f"--u-angle-deg must be a standard uncertainty in deg, >= 0, got {deg!r}; "
                         "give the encoder's accuracy (e.g. 0.01)")
    return math.radians(v)


def _encoder_lines(lines) -> int | None:
    """``--encoder-lines`` as a whole number >= 4 of counts per revolution (None: not given)."""
    if lines is None:
        return None
    try:
        v = float(lines)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v.is_integer() and v >= 4):
        raise InputError(f"--encoder-lines must be a whole number of counts per revolution (>= 4), got {lines!r}")
    return int(v)


def _quantity(name: str, value: float, u: float, unit: str) -> Quantity:
    from senscal.registry import UnknownQuantityError

    if not (math.isfinite(value) and math.isfinite(u)):
        raise UnknownQuantityError(f"the result's {name!r} is not finite; nothing to save")
    return Quantity(name, float(value), float(u), unit)


# ---------------------------------------------------------------------------
# shaft-calibrate
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ShaftCalibrateOptions(ReadOptions):
    """Options of :func:`shaft_calibrate` (the ``senscal shaft calibrate`` options).

    Attributes
    ----------
    angle, accel : str
        Encoder angle channel and tangential accelerometer channel.
    angle_unit : {"deg", "rad"} or None
        Unit of the angle channel; None: the file's, else rad.
    sensitivity : float
        Accelerometer output per m/s^2 (1: output in m/s^2).
    u_sensitivity : float
        Standard uncertainty of ``sensitivity``, same unit.
    radius : float or None
        Sensor radius, m: subtract ``S r alpha_encoder`` before the fit.
    ripple_correction : bool
        Estimate the response to encoder angular acceleration with the fit.
    g : float
        Local gravity, m/s^2.
    window : float or None
        Savitzky-Golay window of the encoder derivatives, s (None: 0.1 s).
    max_speed_variation : float
        Warn above this speed std/mean (fraction, 0.1 = 10 %).
    u_angle_deg : float
        Standard uncertainty of the encoder angle's once-per-turn error
        (eccentric disc; RMS over a turn), deg: the prior of the angle error
        the calibration estimates from the data (0: none).
    encoder_lines : int or None
        Encoder counts per revolution: the step ``360 / N`` deg is in u when
        the readings cannot show it; None: the step is detected, and an
        unresolvable one named ``encoder-step-unknown``.
    time_column, fs, names, time_unit, skip_rows
        How the recording is read (:class:`~senscal.jobs._base.ReadOptions`).
    """

    angle: str = "angle"
    accel: str = "accel"
    angle_unit: str | None = None
    sensitivity: float = 1.0
    u_sensitivity: float = 0.0
    radius: float | None = None
    ripple_correction: bool = True
    g: float = 9.80665
    window: float | None = None
    max_speed_variation: float = 0.10
    u_angle_deg: float = 0.0
    encoder_lines: int | None = None


@dataclass(frozen=True)
class ShaftCalibrateResult(JobResult):
    """Gravity model of a constant-speed run, with the data it was fitted to.

    Attributes
    ----------
    model : senscal.shaft.GravityModel
        Amplitude, phase, offset (output unit), tilt (rad), bias (m/s^2) with
        standard uncertainties (k=1).
    source : str
        The recording (path, or the Recording's ``source``).
    angle : ndarray, shape (N,)
        Encoder angle, rad (as recorded, converted from its unit).
    accel : ndarray, shape (N,)
        Accelerometer output, output unit.
    accel_unit : str
        Unit of the accelerometer channel in the file ('' if unknown).
    warnings : tuple of str
        Named warnings (the model's).
    """

    job: ClassVar[str] = "shaft-calibrate"
    method: ClassVar[str] = METHOD

    model: GravityModel
    source: str
    angle: np.ndarray = field(repr=False)
    accel: np.ndarray = field(repr=False)
    accel_unit: str = ""
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal shaft calibrate --json`` document (without the output paths the CLI adds)."""
        return to_jsonable(calibration_summary(self.model))

    def quantities(self) -> tuple[Quantity, ...]:
        """``gravity_amplitude`` and ``bias`` (the fitted offset), in the output unit, as ``--save`` stores them."""
        m = self.model
        return (_quantity("gravity_amplitude", m.amplitude, m.u_amplitude, m.output_unit),
                _quantity("bias", m.offset, m.u_offset, m.output_unit))

    def to_dataframe(self):
        """One row per fitted quantity: value, standard u (k=1), unit, k, U = 2u."""
        import pandas as pd

        m = self.model
        rows = [("amplitude", m.amplitude, m.u_amplitude, m.output_unit),
                ("phase", math.degrees(m.phase), math.degrees(m.u_phase), "deg"),
                ("offset", m.offset, m.u_offset, m.output_unit),
                ("tilt", math.degrees(m.tilt), math.degrees(m.u_tilt), "deg"),
                ("bias", m.bias, m.u_bias, "m/s^2")]
        return pd.DataFrame([{"quantity": n, "value": float(v), "u": float(u), "unit": unit, "k": 2.0,
                              "U": 2.0 * float(u)} for n, v, u, unit in rows],
                            columns=["quantity", "value", "u", "unit", "k", "U"])

    def compensated(self) -> np.ndarray:
        """The calibration run itself with gravity removed, m/s^2 (for the before/after plot)."""
        return (self.accel - self.model.gravity(self.angle)) / self.model.sensitivity


def shaft_calibrate(source, options: ShaftCalibrateOptions = ShaftCalibrateOptions()) -> ShaftCalibrateResult:
    """Identify the gravity sinusoid of a constant-speed run against the encoder angle.

    Parameters
    ----------
    source : str, Path or Recording
        The calibration run: encoder angle and accelerometer channels.
    options : ShaftCalibrateOptions

    Returns
    -------
    ShaftCalibrateResult

    Raises
    ------
    SenscalError
        Unreadable recording, unknown channel, contradicting angle unit,
        too short a run ... (one line, with the fix).

    References
    ----------
    Yang et al. (2014), gravity compensation of a tangential accelerometer
    on a rotating shaft (``../shared/METHODS.md``).
    """
    from senscal.shaft import calibrate_gravity
    from senscal.shaft.angle import angle_to_rad

    o = options
    if not 0 <= o.max_speed_variation < 1e6:
        raise InputError(f"--max-speed-variation must be a fraction >= 0, got {o.max_speed_variation!r}")
    rec = o.read(source, channels=[o.angle, o.accel], job="shaft")
    unit = angle_unit_of(rec, o.angle, o.angle_unit)
    name = source_name(source)
    accel, accel_unit = _accel_in_si(rec, o.accel)
    model = calibrate_gravity(
        accel, rec[o.angle], rec.time, angle_unit=unit, sensitivity=o.sensitivity,
        u_sensitivity=o.u_sensitivity, output_unit=accel_unit, radius=o.radius,
        ripple_correction=o.ripple_correction, g=o.g, window=0.1 if o.window is None else o.window,
        max_speed_variation=o.max_speed_variation, u_angle=_u_angle(o.u_angle_deg),
        encoder_lines=_encoder_lines(o.encoder_lines), source=name)
    return ShaftCalibrateResult(model=model, source=name, angle=angle_to_rad(rec[o.angle], unit),
                                accel=accel, accel_unit=accel_unit,
                                warnings=merge_time_warnings(model.warnings, rec.warnings))


# ---------------------------------------------------------------------------
# shaft-compensate
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ShaftCompensateOptions(ReadOptions):
    """Options of :func:`shaft_compensate` (the ``senscal shaft compensate`` options).

    Attributes
    ----------
    model : str, Path or senscal.shaft.GravityModel
        The gravity model: MODEL.json from ``shaft calibrate --out`` or a
        model in memory (``ShaftCalibrateResult.model``).
    radius : float
        Sensor distance from the axis, m (required).
    angle, accel : str
        Encoder angle and accelerometer channels.
    angle_unit : {"deg", "rad"} or None
        Unit of the angle channel; None: the file's, else rad.
    window : float or None
        Savitzky-Golay window, s (None: the calibration's).
    centripetal : bool
        Estimate and remove the centripetal leakage ``k r (w^2 - w_cal^2)``.
    time_column, fs, names, time_unit, skip_rows
        How the recording is read (:class:`~senscal.jobs._base.ReadOptions`).
    """

    model: str | Path | GravityModel | None = None
    radius: float | None = None
    angle: str = "angle"
    accel: str = "accel"
    angle_unit: str | None = None
    window: float | None = None
    centripetal: bool = False


_OUTPUT_UNITS = {"tangential_acceleration": "m/s^2", "angular_acceleration": "rad/s^2",
                 "angular_acceleration_encoder": "rad/s^2"}


@dataclass(frozen=True)
class ShaftCompensateResult(JobResult):
    """A run with gravity removed: tangential and angular acceleration, checked against the encoder.

    Attributes
    ----------
    compensation : senscal.shaft.ShaftCompensation
        Arrays (time, angle rad, tangential m/s^2, angular rad/s^2) and the
        encoder check (rad/s^2).
    model : senscal.shaft.GravityModel
        The model that was applied.
    source : str
        The recording.
    model_source : str
        Where the model came from (its file, or ``"<model>"``).
    accel : ndarray, shape (N,)
        The uncompensated accelerometer output, output unit.
    accel_unit : str
    warnings : tuple of str
    """

    job: ClassVar[str] = "shaft-compensate"

    compensation: ShaftCompensation
    model: GravityModel
    source: str
    model_source: str
    accel: np.ndarray = field(repr=False)
    accel_unit: str = ""
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal shaft compensate --json`` document (without the output paths the CLI adds)."""
        return to_jsonable({"file": self.source, "model": self.model_source, **self.compensation.to_dict()})

    def output_recording(self):
        """What ``--out`` writes: t, tangential_acceleration (m/s^2), angular_acceleration and the encoder's (rad/s^2)."""
        from senscal.io import Recording

        c = self.compensation
        return Recording(channels={"tangential_acceleration": c.tangential_acceleration,
                                   "angular_acceleration": c.angular_acceleration,
                                   "angular_acceleration_encoder": c.angular_acceleration_encoder},
                         t=c.t, units=dict(_OUTPUT_UNITS))

    def to_dataframe(self):
        """One row per sample: t (s) and the compensated series of :meth:`output_recording`."""
        import pandas as pd

        c = self.compensation
        return pd.DataFrame({"t": c.t, "tangential_acceleration": c.tangential_acceleration,
                             "angular_acceleration": c.angular_acceleration,
                             "angular_acceleration_encoder": c.angular_acceleration_encoder})


def _model_of(model) -> tuple[Any, str]:
    from senscal.shaft import GravityModel, load_model

    if model is None:
        raise InputError("shaft compensation needs the gravity model: give --model MODEL.json from "
                         "'senscal shaft calibrate --out MODEL.json'")
    return given_or_loaded(model, GravityModel, load_model, label="<model>", what="the shaft model",
                           path="MODEL.json path")


def shaft_compensate(source, options: ShaftCompensateOptions = ShaftCompensateOptions()) -> ShaftCompensateResult:
    """Remove gravity at the measured angle: tangential and angular acceleration of any run.

    Parameters
    ----------
    source : str, Path or Recording
        The run: encoder angle and accelerometer channels.
    options : ShaftCompensateOptions
        ``model`` and ``radius`` are required.

    Returns
    -------
    ShaftCompensateResult

    Raises
    ------
    SenscalError
        Missing or unreadable model, no radius, unknown channel, units that
        differ from the calibration's ... (one line, with the fix).
    """
    from senscal.shaft import compensate

    o = options
    if o.radius is None:
        raise InputError("shaft compensation needs the sensor radius: give --radius R (m, distance from the axis)")
    model, model_source = _model_of(o.model)
    rec = o.read(source, channels=[o.angle, o.accel], job="shaft")
    unit = angle_unit_of(rec, o.angle, o.angle_unit)
    from senscal.persist.units import unit_factor

    # Data in another unit of the model's dimension (mV for a V model, g for m/s^2) are converted; another
    # dimension is refused.
    accel_unit = rec.unit(o.accel)
    scale = unit_factor(accel_unit, model.output_unit, what=f"the accelerometer channel '{o.accel}'",
                        fix="convert the channel or recalibrate with this sensor")
    accel = np.asarray(rec[o.accel], dtype=float) * scale
    if scale != 1.0:
        accel_unit = model.output_unit
    res = compensate(model, accel, rec[o.angle], rec.time, radius=o.radius, angle_unit=unit, window=o.window,
                     remove_centripetal=o.centripetal, accel_unit=accel_unit)
    return ShaftCompensateResult(compensation=res, model=model, source=source_name(source),
                                 model_source=model_source, accel=accel,
                                 accel_unit=accel_unit, warnings=merge_time_warnings(res.warnings, rec.warnings))
