"""IMU job: accelerometer and gyroscope from one multi-pose session (``senscal imu calibrate``, issue 27)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, source_name

__all__ = ["ImuOptions", "ImuCalibrateResult", "imu_calibrate"]

_ANG_RATE = {"rad/s": 1.0, "deg/s": math.pi / 180.0, "dps": math.pi / 180.0, "°/s": math.pi / 180.0}


def _three(names: Any, what: str) -> tuple[str, str, str]:
    listed = [s.strip() for s in names.split(",") if s.strip()] if isinstance(names, str) else list(names or ())
    if len(listed) != 3:
        raise InputError(f"{what} needs exactly three channel names X,Y,Z, got {names!r}")
    return tuple(str(n) for n in listed)  # type: ignore[return-value]


@dataclass(frozen=True)
class ImuOptions(ReadOptions):
    """Options of :func:`imu_calibrate` (the ``senscal imu calibrate`` options).

    Attributes
    ----------
    accel_channels, gyro_channels : str or tuple of 3 str
        Accelerometer and gyroscope X, Y, Z channels.
    gravity : float
        Local g, m/s^2.
    static_window : float
        Moving-variance window of the static detection, s.
    min_pose : float
        Shortest static pose kept, s.
    init_static : float or None
        Length of the still start, s (its variance is the sweep's reference); None: estimated.
    """

    accel_channels: str | tuple[str, str, str] = ("ax", "ay", "az")
    gyro_channels: str | tuple[str, str, str] = ("gx", "gy", "gz")
    gravity: float = 9.80665
    static_window: float = 1.0
    min_pose: float = 1.0
    init_static: float | None = None


def _pq(v: float, u: float, unit: str) -> dict[str, Any]:
    return {"value": float(v), "u": float(u), "U_k2": 2.0 * float(u), "unit": unit}


@dataclass(frozen=True)
class ImuCalibrateResult(JobResult):
    """An IMU calibration: the engine's result with where it came from.

    Attributes
    ----------
    result : senscal.imu.ImuResult
    source : str
    accel_channels, gyro_channels : tuple of 3 str
    accel_unit, gyro_unit : str
        Units of the readings (the gyro's after conversion to rad/s when it named an angular-rate unit).
    warnings : tuple of str
    """

    job: ClassVar[str] = "imu-calibrate"

    result: Any = field(repr=False)
    source: str
    accel_channels: tuple[str, str, str]
    gyro_channels: tuple[str, str, str]
    accel_unit: str
    gyro_unit: str
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal imu calibrate --json`` document."""
        from senscal.imu import ACCEL_NAMES, GYRO_ANGLES

        r, g = self.result, self.result.gyroscope
        ua = np.sqrt(np.clip(np.diag(r.accel_covariance), 0, None))
        av = dict(zip(ACCEL_NAMES, r.accel_values))
        au = dict(zip(ACCEL_NAMES, ua))
        aunit = self.accel_unit or "reading"
        gunit = self.gyro_unit or "reading"
        st = r.poses.static
        na = r.accelerometer.norm_error_after
        accel = {
            "channels": list(self.accel_channels),
            "scale": [av[n] for n in ("Kx", "Ky", "Kz")], "u_scale": [au[n] for n in ("Kx", "Ky", "Kz")],
            "scale_unit": f"{aunit} per m/s^2",
            "bias": [av[n] for n in ("Bx", "By", "Bz")], "u_bias": [au[n] for n in ("Bx", "By", "Bz")],
            "bias_unit": aunit,
            "misalignment_deg": {n: _pq(math.degrees(av[n]), math.degrees(au[n]), "deg")
                                 for n in ("alpha", "beta", "gamma")},
            "g_spread": {"std": na.get("std"), "unit": "m/s^2", "before_std": r.accelerometer.norm_error_before.get("std")},
            "chi2": r.accel_chi2, "dof": r.accel_dof,
        }
        gyro = {
            "channels": list(self.gyro_channels),
            "matrix": g.matrix, "matrix_unit": f"{gunit} per rad/s",
            "scale": g.scale, "u_scale": g.u_scale, "scale_unit": f"{gunit} per rad/s",
            "bias": g.bias, "u_bias": g.u_bias, "bias_unit": gunit, "bias_time_s": g.t_ref,
            "bias_rate": g.bias_rate, "u_bias_rate": g.u_bias_rate,
            "misalignment_deg": {n: _pq(math.degrees(v), math.degrees(u), "deg")
                                 for n, v, u in zip(GYRO_ANGLES, g.angles, g.u_angles)},
            "noise_per_sample": r.gyro_noise, "excitation_deg": np.degrees(r.excitation_rad),
            "chi2": r.chi2, "dof": r.dof,
        }
        before, after = r.residual_before_deg, r.residual_after_deg
        return to_jsonable({
            "file": self.source, "gravity": r.gravity,
            "static": {"n_poses": st.n_poses, "threshold_multiple": r.poses.multiple,
                       "reference_variance": r.poses.reference_variance, "tried": list(r.poses.tried),
                       "starts": st.starts, "stops": st.stops},
            "accelerometer": accel, "gyroscope": gyro,
            "gravity_direction_residual_deg": {
                "before": before, "after": after,
                "rms_before": float(np.sqrt(np.mean(before ** 2))), "rms_after": float(np.sqrt(np.mean(after ** 2))),
                "nominal_gyro_scale": r.nominal_scale},
            "warnings": list(self.warnings)})

    def quantities(self) -> tuple[Quantity, ...]:
        """Scales, biases and misalignment angles of both triads (angles in deg)."""
        from senscal.imu import GYRO_ANGLES

        d = self.to_dict()
        a, g = d["accelerometer"], d["gyroscope"]
        out = []
        for i, ax in enumerate("xyz"):
            out.append(Quantity(f"accel_scale_{ax}", a["scale"][i], a["u_scale"][i], a["scale_unit"]))
            out.append(Quantity(f"accel_bias_{ax}", a["bias"][i], a["u_bias"][i], a["bias_unit"]))
            out.append(Quantity(f"gyro_scale_{ax}", g["scale"][i], g["u_scale"][i], g["scale_unit"]))
            out.append(Quantity(f"gyro_bias_{ax}", g["bias"][i], g["u_bias"][i], g["bias_unit"]))
        for n, p in a["misalignment_deg"].items():
            out.append(Quantity(f"accel_{n}", p["value"], p["u"], "deg"))
        for n in GYRO_ANGLES:
            p = g["misalignment_deg"][n]
            out.append(Quantity(f"gyro_misalignment_{n}", p["value"], p["u"], "deg"))
        return tuple(out)


def imu_calibrate(source, options: ImuOptions = ImuOptions()) -> ImuCalibrateResult:
    """Calibrate an IMU's accelerometer and gyroscope from a multi-pose session.

    Parameters
    ----------
    source : str, Path or Recording
        One recording holding the six channels sample for sample.
    options : ImuOptions

    Returns
    -------
    ImuCalibrateResult

    Raises
    ------
    SenscalError
        Missing channels, no static poses, too few rotations (one line, with the fix).
    """
    from senscal.imu import calibrate_imu
    from senscal.io.plausibility import merge_time_warnings

    o = options
    ac = _three(o.accel_channels, "--accel-channels")
    gc = _three(o.gyro_channels, "--gyro-channels")
    if set(ac) & set(gc):
        raise InputError("--accel-channels and --gyro-channels must name six different channels")
    rec = o.read(source, channels=list(ac) + list(gc), job="imu")
    units_a = {rec.units.get(c, "") for c in ac}
    units_g = {rec.units.get(c, "") for c in gc}
    if len(units_a) > 1 or len(units_g) > 1:
        raise InputError(f"{source_name(source)}: the three axes of a triad must share one unit, got "
                         f"{sorted(units_a)} and {sorted(units_g)}; convert them first")
    aunit, gunit = units_a.pop(), units_g.pop()
    gyro = rec.data(list(gc))
    key = gunit.strip().lower()
    if key in _ANG_RATE:
        gyro = gyro * _ANG_RATE[key]
        gunit = "rad/s"
    res = calibrate_imu(rec.time, rec.data(list(ac)), gyro, gravity=o.gravity, window_s=o.static_window,
                        min_pose_s=o.min_pose, init_s=o.init_static, accel_unit=aunit, gyro_unit=gunit,
                        accel_channels=ac, source=source_name(source))
    warnings = merge_time_warnings(res.warnings, rec.warnings)
    return ImuCalibrateResult(result=res, source=source_name(source), accel_channels=ac, gyro_channels=gc,
                              accel_unit=aunit, gyro_unit=gunit, warnings=tuple(warnings))
