"""IMU job: accelerometer and gyroscope from one multi-pose session (``senscal imu calibrate``, issue 27)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError, SenscalError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, source_name

__all__ = ["ImuOptions", "ImuCalibrateResult", "imu_calibrate", "ImuApplyOptions", "ImuApplyResult", "imu_apply"]

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
    temperature_channel : str or None
        The IMU's temperature: bias and scale are fitted against it (:func:`senscal.imu.calibrate_imu`).
    g_sensitivity : bool
        Fit the gyro's sensitivity to specific force.
    rate_table : str, Path, senscal.io.ratetable.RateTable or None
        Segments of known rate after the multi-pose session (the file format: :mod:`senscal.io.ratetable`).
    """

    accel_channels: str | tuple[str, str, str] = ("ax", "ay", "az")
    gyro_channels: str | tuple[str, str, str] = ("gx", "gy", "gz")
    gravity: float = 9.80665
    static_window: float = 1.0
    min_pose: float = 1.0
    init_static: float | None = None
    temperature_channel: str | None = None
    g_sensitivity: bool = False
    rate_table: Any = None


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
    calibration : senscal.imu.model.ImuCalibration
        What ``--out`` saves and ``senscal imu apply`` uses.
    noise : senscal.imu.noise.ImuNoise or None
        Allan noise levels of the still start (None when it is too short).
    g_before, g_after : ndarray, shape (K,)
        ``|f| - g`` per pose, nominal and calibrated accelerometer, m/s^2.
    pose_temperature : ndarray (K,) or None
    temperature_channel, temp_unit : str or None
    warnings : tuple of str
    rate_table : senscal.io.ratetable.RateTable or None
        The stated rate table (``result.rate_table`` holds its fit).
    """

    job: ClassVar[str] = "imu-calibrate"

    result: Any = field(repr=False)
    source: str
    accel_channels: tuple[str, str, str]
    gyro_channels: tuple[str, str, str]
    accel_unit: str
    gyro_unit: str
    calibration: Any = field(default=None, repr=False)
    noise: Any = field(default=None, repr=False)
    g_before: Any = field(default=None, repr=False)
    g_after: Any = field(default=None, repr=False)
    pose_temperature: Any = field(default=None, repr=False)
    temperature_channel: str | None = None
    temp_unit: str = ""
    warnings: tuple[str, ...] = ()
    rate_table: Any = field(default=None, repr=False)

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
            "g_sensitivity": None if g.g_sensitivity is None else {
                "value": g.g_sensitivity, "u": g.u_g_sensitivity, "unit": f"{gunit} per m/s^2",
                "rows": "gyro axis x, y, z", "columns": "specific force along the accelerometer frame's x, y, z"},
        }
        te = r.temperature
        temperature = None
        if te is not None:
            tu = self.temp_unit or "unit"
            temperature = {
                "channel": self.temperature_channel, "reference": te.reference, "unit": self.temp_unit,
                "range": [te.low, te.high], "swing": te.swing,
                "note": "biases and scales above hold at the reference temperature; coefficient j multiplies "
                        "(T - reference)^j",
                "accelerometer": {"degree": te.degree_accel, "heldout_chi2": list(te.scores_accel),
                                  "bias": te.accel_bias, "u_bias": te.u_accel_bias, "bias_unit": f"{aunit} per {tu}^j",
                                  "scale": te.accel_scale, "u_scale": te.u_accel_scale,
                                  "scale_unit": f"relative per {tu}^j"},
                "gyroscope": {"degree": te.degree_gyro, "heldout_chi2": list(te.scores_gyro),
                              "bias": te.gyro_bias, "u_bias": te.u_gyro_bias, "bias_unit": f"{gunit} per {tu}^j",
                              "scale_degree": te.degree_gyro_scale,
                              "scale_heldout_chi2": list(te.scores_gyro_scale), "scale": te.gyro_scale,
                              "u_scale": te.u_gyro_scale, "scale_unit": f"relative per {tu}^j"}}
        nz = self.noise
        noise = None if nz is None else {
            "still_start_s": nz.duration_s, "accel_noise_density": nz.accel_density,
            "accel_random_walk": nz.accel_random_walk, "accel_random_walk_is_bound": nz.accel_rw_bound,
            "gyro_noise_density": nz.gyro_density, "gyro_random_walk": nz.gyro_random_walk,
            "gyro_random_walk_is_bound": nz.gyro_rw_bound,
            "units": {"accel_noise_density": "m/s^2/sqrt(Hz)", "accel_random_walk": "m/s^3/sqrt(Hz)",
                      "gyro_noise_density": "rad/s/sqrt(Hz)", "gyro_random_walk": "rad/s^2/sqrt(Hz)"},
            "ros": nz.ros_covariance(), "kalibr_yaml": nz.kalibr_yaml()}
        before, after = r.residual_before_deg, r.residual_after_deg
        return to_jsonable({
            "file": self.source, "gravity": r.gravity,
            "static": {"n_poses": st.n_poses, "threshold_multiple": r.poses.multiple,
                       "reference_variance": r.poses.reference_variance, "tried": list(r.poses.tried),
                       "starts": st.starts, "stops": st.stops,
                       "gyro_check": None if r.poses.gyro is None else {
                           "split": r.poses.gyro.n_split, "trimmed": r.poses.gyro.trimmed,
                           "dropped": [{"start_s": a, "stop_s": b, "deviations": z} for a, b, z in r.poses.gyro.unsplit],
                           "dropped_short": [{"start_s": a, "stop_s": b, "deviations": z}
                                             for a, b, z in r.poses.gyro.short],
                           "moving_mean_scatter": r.poses.gyro.scale,
                           "note": "still runs of the accelerometer cut where the gyro's 0.1 s moving mean leaves its "
                                   "run level by more than 5 still deviations (a turn about the vertical)"}},
            "accelerometer": accel, "gyroscope": gyro,
            "gravity_direction_residual_deg": {
                "before": before, "after": after,
                "rms_before": float(np.sqrt(np.mean(before ** 2))), "rms_after": float(np.sqrt(np.mean(after ** 2))),
                "nominal_gyro_scale": r.nominal_scale},
            "temperature": temperature, "noise": noise, "rate_table": self._rate_table_doc(),
            "budget": self.budget(),
            "warnings": list(self.warnings)})

    def _rate_table_doc(self) -> dict[str, Any] | None:
        """The ``rate_table`` section: segments, their residuals, the consistency check, pose-only/table-only."""
        from senscal.imu.ratetable import derived_components

        fit, tab = self.result.rate_table, self.rate_table
        if fit is None or tab is None:
            return None
        gunit = self.gyro_unit or "reading"

        def summary(m, c):
            if m is None:
                return None
            d, (cd,) = derived_components(m, [c])
            u = np.sqrt(np.clip(np.diag(cd), 0, None))
            return {"scale": d[:3], "u_scale": u[:3], "misalignment_deg": np.degrees(d[3:]),
                    "u_misalignment_deg": np.degrees(u[3:])}

        segs = [{"start_s": tab.start[k], "stop_s": tab.stop[k], "axis": tab.axis[k], "rate_rad_s": tab.rate[k],
                 "rate_deg_s": math.degrees(tab.rate[k]), "u_rate_rad_s": tab.u_rate[k], "u_axis_rad": tab.u_axis[k],
                 "residual": fit.residual[k], "u_predicted": fit.u_residual[k],
                 "residual_from_poses": fit.predicted_from_poses[k]} for k in range(tab.n_segments)]
        return {"file": tab.source, "n_segments": tab.n_segments, "segments": segs, "residual_unit": gunit,
                "consistency": {"chi2": fit.chi2, "dof": fit.dof, "inflation": fit.inflation,
                                "note": "segments against the multi-pose estimate, chi-square with 3 dof per "
                                        "segment; beyond its 99.9 % point rate-table-inconsistent is named"},
                "multi_pose_only": summary(fit.pose_matrix, fit.pose_covariance),
                "table_only": summary(fit.table_matrix, fit.table_covariance),
                "combined": summary(fit.matrix, fit.covariance)}

    def budget(self) -> dict[str, Any]:
        """Uncertainty budget (standard uncertainties, k=1) of the gyro scales and angles and the accelerometer.

        With a rate table the combined gyro covariance splits exactly into the multi-pose fit, the segment means,
        the static-pose bias, the table's stated rate and axis (:data:`senscal.imu.ratetable.SOURCES`); without
        one the multi-pose fit is the only component.
        """
        from senscal.imu import ACCEL_NAMES
        from senscal.imu.ratetable import derived_components

        r, g = self.result, self.result.gyroscope
        fit = r.rate_table
        comps = list(fit.components) if fit is not None else [("multi-pose rotations (type A)", "A", g.covariance)]
        _, cd = derived_components(g.matrix, [c for _, _, c in comps])
        gyro = [{"source": src, "type": kind, "u_scale": np.sqrt(np.clip(np.diag(c)[:3], 0, None)),
                 "u_misalignment_deg": np.degrees(np.sqrt(np.clip(np.diag(c)[3:], 0, None)))}
                for (src, kind, _), c in zip(comps, cd)]
        ua = np.sqrt(np.clip(np.diag(r.accel_covariance), 0, None))
        accel = [{"source": "static pose means about |f| = g (type A)", "type": "A",
                  "u": dict(zip(ACCEL_NAMES, ua))}]
        return {"gyroscope": gyro, "accelerometer": accel,
                "note": "k = 2; local g taken as exact (--gravity): its u is not in the accelerometer's budget"}

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
        gs = g["g_sensitivity"]
        if gs is not None:
            for i, ax in enumerate("xyz"):
                for j, fx in enumerate("xyz"):
                    out.append(Quantity(f"gyro_g_sensitivity_{ax}{fx}", gs["value"][i][j], gs["u"][i][j], gs["unit"]))
        te = d["temperature"]
        if te is not None:
            for sec, key, unit in (("accelerometer", "bias", te["accelerometer"]["bias_unit"]),
                                   ("accelerometer", "scale", te["accelerometer"]["scale_unit"]),
                                   ("gyroscope", "bias", te["gyroscope"]["bias_unit"])):
                blk = te[sec]
                for j in range(blk["degree"]):
                    for i, ax in enumerate("xyz"):
                        out.append(Quantity(f"{sec[:5] if sec == 'accelerometer' else 'gyro'}_{key}_tc{j + 1}_{ax}",
                                            blk[key][j][i], blk[f"u_{key}"][j][i], unit.replace("^j", f"^{j + 1}")))
            gb = te["gyroscope"]
            for j in range(gb.get("scale_degree") or 0):
                for i, ax in enumerate("xyz"):
                    out.append(Quantity(f"gyro_scale_tc{j + 1}_{ax}", gb["scale"][j][i], gb["u_scale"][j][i],
                                        gb["scale_unit"].replace("^j", f"^{j + 1}")))
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
    for opt, v in (("--static-window", o.static_window), ("--min-pose", o.min_pose), ("--init-static", o.init_static)):
        # NaN passes every '<' check and reached int(), as 1e308 s times the rate did: an internal error
        from senscal.jobs._units import LONGEST_SESSION_S

        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and 0 <= v <= LONGEST_SESSION_S
                                  and (v > 0 or opt == "--min-pose")):
            raise InputError(f"{opt} must be a finite number of seconds, {'0' if opt == '--min-pose' else 'above 0'} "
                             f"to {LONGEST_SESSION_S:g} (no IMU session is longer), got {v!r}")
    tch = o.temperature_channel or None
    if tch is not None and tch in set(ac) | set(gc):
        raise InputError(f"--temperature-channel {tch} is one of the accelerometer or gyroscope channels; give the "
                         "IMU's temperature channel")
    rec = o.read(source, channels=list(ac) + list(gc) + ([tch] if tch else []), job="imu")
    from senscal.jobs._units import check_magnitude, check_session_time

    check_session_time(rec, source_name(source), "IMU calibration")
    check_magnitude(rec, list(ac) + list(gc) + ([tch] if tch else []), source_name(source))
    units_a = {rec.units.get(c, "") for c in ac}
    units_g = {rec.units.get(c, "") for c in gc}
    if len(units_a) > 1 or len(units_g) > 1:
        raise InputError(f"{source_name(source)}: the three axes of a triad must share one unit, got "
                         f"{sorted(units_a)} and {sorted(units_g)}; convert them first")
    aunit, gunit = units_a.pop(), units_g.pop()
    from senscal.jobs._units import celsius_if_other_degree, check_triad_unit, rate_factor

    check_triad_unit(aunit, accel=True, channels=ac, source=source_name(source))
    check_triad_unit(gunit, accel=False, channels=gc, source=source_name(source))
    gyro = rec.data(list(gc))
    k_rate = rate_factor(gunit)  # every angular rate (deg/s, deg/h, mrad/s, rpm) in rad/s: one scale for all files
    if k_rate is not None:
        gyro = gyro * k_rate
        gunit = "rad/s"
    temp = rec.data([tch])[0] if tch else None
    tunit = rec.units.get(tch, "") if tch else ""
    if temp is not None:
        temp, tunit = celsius_if_other_degree(temp, tunit)  # the swing check and the coefficients count kelvins
    accel = rec.data(list(ac))
    table = None
    if o.rate_table is not None:
        from senscal.io.ratetable import RateTable, read_rate_table

        table = o.rate_table if isinstance(o.rate_table, RateTable) else read_rate_table(o.rate_table)
    res = calibrate_imu(rec.time, accel, gyro, gravity=o.gravity, window_s=o.static_window,
                        min_pose_s=o.min_pose, init_s=o.init_static, accel_unit=aunit, gyro_unit=gunit,
                        accel_channels=ac, source=source_name(source), temperature=temp, temp_unit=tunit,
                        g_sensitivity=o.g_sensitivity, rate_table=table)
    warnings = list(merge_time_warnings(res.warnings, rec.warnings))
    cal = calibration_of(res, accel_unit=aunit, gyro_unit=gunit, accel_channels=ac, gyro_channels=gc,
                         temp_channel=tch, temp_unit=tunit)
    st = res.poses.static
    temp_pose = None if temp is None else np.array([temp[a:b].mean() for a, b in zip(st.starts, st.stops)])
    f_pose = cal.apply_accel(st.means, temp_pose)
    g_after = np.linalg.norm(f_pose, axis=0) - res.gravity
    from senscal.triaxial.calibrate import nominal_raw

    raw, _ = nominal_raw(st.means, res.gravity)
    g_before = np.linalg.norm(raw, axis=0) - res.gravity
    noise = None
    a0, b0 = int(st.starts[0]), int(st.stops[0])
    try:
        from senscal.imu.noise import noise_parameters

        f0, w0 = cal.apply(accel[:, a0:b0], gyro[:, a0:b0], None if temp is None else temp[a0:b0])
        noise = noise_parameters(f0, w0, rec.sample_rate)
    except SenscalError:
        from senscal.diagnostics import named

        warnings.append(named("imu-noise-unavailable", f"the still start holds {b0 - a0} samples, too few for an "
                              "Allan deviation: no noise densities (kalibr YAML, ROS covariance); record a longer "
                              "still start (IMU-TK: 30-50 s)"))
    return ImuCalibrateResult(result=res, source=source_name(source), accel_channels=ac, gyro_channels=gc,
                              accel_unit=aunit, gyro_unit=gunit, calibration=cal, noise=noise, g_before=g_before,
                              g_after=g_after, pose_temperature=temp_pose, temperature_channel=tch, temp_unit=tunit,
                              warnings=tuple(warnings), rate_table=table)


def calibration_of(res, *, accel_unit: str = "", gyro_unit: str = "", accel_channels=("ax", "ay", "az"),
                   gyro_channels=("gx", "gy", "gz"), temp_channel: str | None = None, temp_unit: str = ""):
    """The saved calibration (:class:`senscal.imu.model.ImuCalibration`) of an engine result."""
    from senscal.imu.model import ImuCalibration
    from senscal.triaxial.estimators import unpack

    ma, ba, _ = unpack("full", res.accel_values, res.gravity)
    g, te = res.gyroscope, res.temperature
    z = np.zeros((0, 3))
    return ImuCalibration(
        accel_matrix=ma, accel_bias=ba, gyro_matrix=g.matrix, gyro_bias=g.bias, gravity=res.gravity,
        accel_unit=accel_unit, gyro_unit=gyro_unit, accel_channels=tuple(accel_channels),
        gyro_channels=tuple(gyro_channels), g_sensitivity=g.g_sensitivity,
        temp_reference=None if te is None else te.reference, temp_unit=temp_unit,
        temp_channel=temp_channel if te is not None else None,
        accel_bias_tc=z if te is None else te.accel_bias, accel_scale_tc=z if te is None else te.accel_scale,
        gyro_bias_tc=z if te is None else te.gyro_bias, gyro_scale_tc=z if te is None else te.gyro_scale)


# ---------------------------------------------------------------------------
# imu-apply
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ImuApplyOptions(ReadOptions):
    """Options of :func:`imu_apply` (the ``senscal imu apply`` options).

    Attributes
    ----------
    params : str, Path or senscal.imu.model.ImuCalibration
        The file of ``senscal imu calibrate --out`` (or a calibration in memory).
    accel_channels, gyro_channels : str, tuple of 3 str or None
        Channels to correct (default: the names the calibration was made from).
    temperature_channel : str or None
        The IMU's temperature (default: the calibration's, when it has temperature terms).
    """

    params: Any = None
    accel_channels: str | tuple[str, str, str] | None = None
    gyro_channels: str | tuple[str, str, str] | None = None
    temperature_channel: str | None = None


@dataclass(frozen=True)
class ImuApplyResult(JobResult):
    """A recording with both triads corrected (m/s^2, rad/s); the other channels are copied.

    Attributes
    ----------
    calibration : senscal.imu.model.ImuCalibration
    recording : senscal.io.Recording
    source, params_source : str
    accel_channels, gyro_channels : tuple of 3 str
    warnings : tuple of str
    """

    job: ClassVar[str] = "imu-apply"

    calibration: Any = field(repr=False)
    recording: Any = field(repr=False)
    source: str
    params_source: str
    accel_channels: tuple[str, str, str]
    gyro_channels: tuple[str, str, str]
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal imu apply --json`` document (``out`` is set by the writer)."""
        rec = self.recording
        f = rec.data(list(self.accel_channels))
        norm = np.linalg.norm(f, axis=0)
        return to_jsonable({"file": self.source, "out": None, "params": self.params_source,
                            "n_samples": int(norm.size), "accel_channels": list(self.accel_channels),
                            "gyro_channels": list(self.gyro_channels),
                            "specific_force_norm_mean": float(norm.mean()), "unit_accel": "m/s^2",
                            "unit_gyro": "rad/s", "warnings": list(self.warnings)})


def imu_apply(source, options: ImuApplyOptions = ImuApplyOptions()) -> ImuApplyResult:
    """Correct an IMU recording's accelerometer and gyroscope with a saved calibration.

    Parameters
    ----------
    source : str, Path or Recording
        The recording to correct (never modified).
    options : ImuApplyOptions
        ``params`` is required.

    Returns
    -------
    ImuApplyResult

    Raises
    ------
    SenscalError
        Missing or unreadable calibration, unknown channel, a unit of another dimension (one line, with the fix).
    """
    from senscal.diagnostics import named
    from senscal.imu.model import ImuCalibration, load_calibration
    from senscal.io import Recording
    from senscal.jobs._base import given_or_loaded
    from senscal.persist.units import unit_factor

    o = options
    if o.params is None:
        raise InputError("imu apply needs the calibration: give --params CAL.json from "
                         "'senscal imu calibrate --out CAL.json'")
    cal, params_source = given_or_loaded(o.params, ImuCalibration, load_calibration, label="<calibration>",
                                         what="the calibration", path="calibration file")
    ac = _three(o.accel_channels or cal.accel_channels, "--accel-channels")
    gc = _three(o.gyro_channels or cal.gyro_channels, "--gyro-channels")
    tch = o.temperature_channel or (cal.temp_channel if cal.has_temperature else None)
    warnings: list[str] = []
    rec = o.read(source)
    names = list(ac) + list(gc)
    if tch is not None and tch not in rec.channels and not o.temperature_channel:
        warnings.append(named("imu-temperature-missing", f"the calibration has temperature terms about "
                              f"{cal.temp_reference:.4g} {cal.temp_unit} but {source_name(source)} has no channel "
                              f"'{tch}': corrected as at the reference temperature; give --temperature-channel"))
        tch = None
    rec.data(names + ([tch] if tch else []))  # unknown channel -> one-line error listing the channels
    src = source_name(source)
    fa = [unit_factor(rec.units.get(c, ""), cal.accel_unit, what=f"channel '{c}' of {src}",
                      fix="convert the data or calibrate again") for c in ac]
    from senscal.jobs._units import rate_factor, temperature_in

    fg = []
    for c in gc:
        u = rec.units.get(c, "")
        k = rate_factor(u)
        fg.append(k if k is not None and cal.gyro_unit == "rad/s" else
                  unit_factor(u, cal.gyro_unit, what=f"channel '{c}' of {src}", fix="convert the data or calibrate again"))
    # A unit on one side only is read as the other side's: named, since deg/s read as rad/s is a factor of 57.
    from senscal.jobs._units import one_side_unit

    assumed = [a for a in (one_side_unit(cs, rec.units, cu) for cs, cu in (
        (ac, cal.accel_unit), (gc, cal.gyro_unit), ((tch,) if tch else (), cal.temp_unit))) if a]
    if assumed:
        warnings.append(named("imu-units-assumed", f"{src}: {'; '.join(assumed)}; write the units in the header "
                              "('ax [m/s^2]', 'gx [deg/s]', 'temp [degC]'), or calibrate from a file that states them"))
    a = rec.data(list(ac)) * np.asarray(fa)[:, None]
    g = rec.data(list(gc)) * np.asarray(fg)[:, None]
    temp = rec.data([tch])[0] if tch else None
    if temp is not None:  # degF or K data against a degC calibration: converted, offsets included
        temp = temperature_in(temp, rec.units.get(tch, ""), cal.temp_unit, channel=tch, source=src)
    f, w = cal.apply(a, g, temp)
    new, units = dict(rec.channels), dict(rec.units)
    for i, c in enumerate(ac):
        new[c], units[c] = f[i], "m/s^2"
    for i, c in enumerate(gc):
        new[c], units[c] = w[i], "rad/s"
    out = Recording(channels=new, t=rec.t, fs=rec.fs, t0=rec.t0, units=units,
                    metadata={**rec.metadata, "imu_calibration": f"from {params_source}"})
    return ImuApplyResult(calibration=cal, recording=out, source=src, params_source=params_source,
                          accel_channels=ac, gyro_channels=gc, warnings=tuple(warnings))
