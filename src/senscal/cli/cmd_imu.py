"""``senscal imu calibrate`` and ``senscal simulate imu`` (issue 27)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli._quantities import ListOf, units
from senscal.cli.app import app, simulate_app
from senscal.cli.cert_opts import (CalDateOpt, CertIdOpt, CustomerOpt, DccOpt, EnvOpt, ItemOpt, LabOpt, LocationOpt,
                                   ManufacturerOpt, ModelOpt, ReportOpt, RunFileOpt, SensorIdOpt, SignCertOpt,
                                   SignKeyOpt, cert_fields, certify)
from senscal.cli.common import JsonOpt, StrictOpt, console, emit_warnings, print_json, progress_bar, table
from senscal.cli.option_groups import READ, REGISTRY, command_params, save_registered, with_options
from senscal.cli.registry_opts import StandardOpt, note_standards, use_standards
from senscal.errors import InputError
from senscal.jobs._base import with_read_options

imu_app = typer.Typer(help="IMU calibration: accelerometer and gyroscope together from one multi-pose session.",
                      no_args_is_help=True)
app.add_typer(imu_app, name="imu")


@with_read_options
def _imu_options(*, accel_channels: str = "ax,ay,az", gyro_channels: str = "gx,gy,gz", gravity: float = 9.80665,
                 static_window: float = 1.0, min_pose: float = 1.0, init_static: float | None = None,
                 temperature_channel: str | None = None, g_sensitivity: bool = False, rate_table: Path | None = None,
                 **_):
    """``ImuOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.imu import ImuOptions

    return ImuOptions(accel_channels=accel_channels, gyro_channels=gyro_channels, gravity=gravity,
                      static_window=static_window, min_pose=min_pose, init_static=init_static,
                      temperature_channel=temperature_channel, g_sensitivity=g_sensitivity, rate_table=rate_table)


@with_read_options
def _apply_options(*, params: Path | str | None = None, accel_channels: str | None = None,
                   gyro_channels: str | None = None, temperature_channel: str | None = None, **_):
    """``ImuApplyOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.imu import ImuApplyOptions

    return ImuApplyOptions(params=params, accel_channels=accel_channels, gyro_channels=gyro_channels,
                           temperature_channel=temperature_channel)


# What `senscal batch` turns the job's option words into (see senscal.jobs).
JOB_OPTIONS = {"imu-calibrate": _imu_options, "imu-apply": _apply_options}

TempChannelOpt = Annotated[Optional[str], typer.Option(
    "--temperature-channel", help="The IMU's temperature channel: bias and scale against temperature (degree chosen "
                                  "on held-out poses), quoted at the poses' mean temperature.")]


def _triad_rows(sec: dict, label: str) -> list[list]:
    """Table rows of one triad: scale and bias per axis, then the misalignment angles (U = 2u)."""
    rows = [[f"{label} {what} {ax}", sec[what][i], 2 * sec[f"u_{what}"][i], sec[f"{what}_unit"]]
            for what in ("scale", "bias") for i, ax in enumerate("xyz")]
    name = "" if label == "accel" else "misalignment "
    rows += [[f"{label} {name}{n}", p["value"], p["U_k2"], "deg"] for n, p in sec["misalignment_deg"].items()]
    return rows


@imu_app.command("calibrate")
@with_options(READ, REGISTRY)
@units(gravity="m/s^2", static_window="s", min_pose="s", init_static="s")
def imu_calibrate_cmd(
    file: Annotated[Path, typer.Argument(help="Recording with three accelerometer and three gyroscope channels (a still start, then static poses joined by rotations).")],
    accel_channels: Annotated[str, typer.Option("--accel-channels", help="Accelerometer X,Y,Z channel names.")] = "ax,ay,az",
    gyro_channels: Annotated[str, typer.Option("--gyro-channels", help="Gyroscope X,Y,Z channel names (rad/s, deg/s or counts).")] = "gx,gy,gz",
    gravity: Annotated[str, typer.Option("--gravity", help="Local g, m/s^2.")] = "9.80665",
    static_window: Annotated[str, typer.Option("--static-window", help="Moving-variance window of the static detection, s.")] = "1.0",
    min_pose: Annotated[str, typer.Option("--min-pose", help="Shortest static pose kept, s.")] = "1.0",
    init_static: Annotated[Optional[str], typer.Option("--init-static", help="Length of the still start, s (reference variance of the threshold sweep; default: estimated).")] = None,
    temperature_channel: TempChannelOpt = None,
    g_sensitivity: Annotated[bool, typer.Option("--g-sensitivity", help="Fit the gyro's sensitivity to specific force (3x3, from the bias against orientation).")] = False,
    rate_table: Annotated[Optional[Path], typer.Option("--rate-table", metavar="FILE", help="Rate-table segments of known rate after the poses (CSV or YAML: start, stop, axis, rate, u_rate[, u_axis], every number with its unit; docs/imu.md): combined with the multi-pose gyro estimate.")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Write the calibration for 'senscal imu apply' (JSON, or HDF5 for .h5; - for stdout).")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="|f| - g per pose and gravity-direction error per rotation, before/after (PNG, SVG, PDF).")] = None,
    noise_yaml: Annotated[Optional[Path], typer.Option("--noise-yaml", help="Write the still start's Allan noise as a kalibr imu.yaml block (ROS covariances in --json).")] = None,
    strict: StrictOpt = False,
    json_out: JsonOpt = False,
    standard: StandardOpt = None,
    report: ReportOpt = None, dcc: DccOpt = None, sensor_id: SensorIdOpt = None, model: ModelOpt = None,
    lab: LabOpt = None, run_file: RunFileOpt = None, customer: CustomerOpt = None, item: ItemOpt = None,
    manufacturer: ManufacturerOpt = None, location: LocationOpt = None, certificate_id: CertIdOpt = None,
    calibration_date: CalDateOpt = None, env: EnvOpt = None, sign_key: SignKeyOpt = None, sign_cert: SignCertOpt = None,
    **opts,
) -> None:
    """Accelerometer and gyroscope scale, misalignment and bias from one multi-pose session."""
    from senscal.jobs.imu import imu_calibrate

    # before the job: a typo costs nothing
    used_standards = use_standards(standard, db=opts["db"], date=opts["date"], calibration_date=calibration_date)
    params = command_params(locals(), opts)
    with progress_bar("calibrating", None):
        res = imu_calibrate(file, _imu_options(**params))
    doc = res.to_dict()
    warnings = [*res.warnings, *note_standards(doc, used_standards)]
    if out is not None:
        res.calibration.save(out, extra=doc)  # type + format_version; JSON, or HDF5 for .h5 (senscal.persist)
    if noise_yaml is not None:
        if res.noise is None:
            raise InputError("--noise-yaml: the still start is too short for an Allan deviation; record a longer "
                             "still start (30-50 s) or drop --noise-yaml")
        from senscal.io.guard import write_text

        write_text(noise_yaml, res.noise.kalibr_yaml(), what="noise YAML")
    conditions = None
    if doc["temperature"] is not None:
        te = doc["temperature"]
        conditions = {"reference_temperature": te["reference"], "temperature_unit": te["unit"]}
    method = "multi-pose (IMU-TK protocol), joint ML" + (", with rate-table segments" if rate_table else "")
    cond = {"static poses": doc["static"]["n_poses"], "local gravity": f"{doc['gravity']:g} m/s^2",
            "accelerometer channels": ",".join(res.accel_channels), "gyroscope channels": ",".join(res.gyro_channels)}
    if rate_table is not None:
        cond["rate table"] = f"{rate_table} ({doc['rate_table']['n_segments']} segments)"
    if conditions:
        cond["reference temperature"] = f"{conditions['reference_temperature']:.4g} {conditions['temperature_unit']}"
    cert_warns = certify("imu", res, report=report, dcc=dcc, unit="", method=method, conditions=cond,
                         files=[str(file)], warnings=warnings, **cert_fields(params))
    warnings = [*warnings, *cert_warns]
    doc["warnings"] = [*doc.get("warnings", []), *cert_warns]
    if report is not None:
        doc["report"] = str(report)
    save_registered(res, opts, job="imu", method=method, input_files=[file], conditions=conditions,
                    standards=used_standards, certificate=report)
    if plot is not None:
        from senscal.imu.plots import plot_imu

        r = res.result
        plot_imu(res.g_before, res.g_after, r.residual_before_deg, r.residual_after_deg, plot,
                 temperature=res.pose_temperature, temp_unit=res.temp_unit,
                 title=f"{file.name}: IMU calibration ({r.poses.static.n_poses} poses)")
    if json_out:
        print_json(doc)
        emit_warnings(warnings, strict)
        return
    a, g = doc["accelerometer"], doc["gyroscope"]
    rows = _triad_rows(a, "accel") + _triad_rows(g, "gyro")
    if g["g_sensitivity"] is not None:
        gs = g["g_sensitivity"]
        rows += [[f"gyro g-sensitivity {ax}{fx}", gs["value"][i][j], 2 * gs["u"][i][j], gs["unit"]]
                 for i, ax in enumerate("xyz") for j, fx in enumerate("xyz")]
    console.print(table(f"IMU calibration of {file} (U = expanded uncertainty, k=2)", ["parameter", "value", "U",
                                                                                        "unit"], rows))
    st, gd = doc["static"], doc["gravity_direction_residual_deg"]
    console.print(f"{st['n_poses']} static poses (threshold x{st['threshold_multiple']:g} the still variance); "
                  f"|g| spread after {a['g_spread']['std']:.3g} m/s^2")
    console.print(f"gravity-direction residual per rotation: rms {gd['rms_before']:.3g} deg before, "
                  f"{gd['rms_after']:.3g} deg after the gyroscope calibration")
    rt = doc["rate_table"]
    if rt is not None:
        c, mp = rt["consistency"], rt["multi_pose_only"]
        console.print(f"rate table: {rt['n_segments']} segments, consistency chi2 {c['chi2']:.3g} for {c['dof']} dof; "
                      f"gyro scale u {', '.join(f'{u:.2g}' for u in g['u_scale'])} with it, "
                      f"{', '.join(f'{u:.2g}' for u in mp['u_scale'])} from the poses alone")
    if report is not None:
        console.print(f"certificate written to {report}")
    te = doc["temperature"]
    if te is not None:
        console.print(f"temperature: reference {te['reference']:.4g} {te['unit']} (poses {te['range'][0]:.4g} .. "
                      f"{te['range'][1]:.4g}); degree {te['accelerometer']['degree']} (accelerometer), "
                      f"{te['gyroscope']['degree']} (gyro bias), chosen on held-out poses")
    emit_warnings(warnings, strict)


@imu_app.command("apply")
@with_options(READ)
def imu_apply_cmd(
    file: Annotated[Path, typer.Argument(help="Recording to correct (never modified).")],
    params: Annotated[Path, typer.Option("--params", help="Calibration file written by 'imu calibrate --out'.")],
    out: Annotated[Path, typer.Option("--out", help="Corrected recording (CSV, Parquet, HDF5, NPZ): m/s^2 and rad/s.")],
    accel_channels: Annotated[Optional[str], typer.Option("--accel-channels", help="Accelerometer X,Y,Z channels (default: the calibration's).")] = None,
    gyro_channels: Annotated[Optional[str], typer.Option("--gyro-channels", help="Gyroscope X,Y,Z channels (default: the calibration's).")] = None,
    temperature_channel: Annotated[Optional[str], typer.Option("--temperature-channel", help="The IMU's temperature (default: the calibration's, when it has temperature terms).")] = None,
    strict: StrictOpt = False,
    json_out: JsonOpt = False,
    **opts,
) -> None:
    """Correct accelerometer and gyroscope channels with a saved IMU calibration; other channels are copied."""
    from senscal.io import write_recording
    from senscal.jobs.imu import imu_apply

    result = imu_apply(file, _apply_options(**command_params(locals(), opts)))
    if Path(out).resolve() == Path(file).resolve():
        raise InputError("--out must differ from the input file; input files are never modified")
    # 'gx [rad/s]': the corrected units travel with the data (a deg/s input's header would otherwise be read back
    # as deg/s, or as nothing)
    p = write_recording(result.recording, out, units_in_header=True)
    summary = result.to_dict()
    summary["out"] = str(p)
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {p}: {summary['n_samples']} samples, accelerometer in m/s^2 (|f| mean "
                      f"{summary['specific_force_norm_mean']:.6g}) and gyroscope in rad/s")
    emit_warnings(result.warnings, strict)


@simulate_app.command("imu")
@units(fs='Hz', init_s='s', pose_s='s', rotation_s='s', accel_noise='m/s^2', gyro_noise='rad/s',
       bias_drift=ListOf('rad/s^2'), temperature=ListOf('degC'), accel_bias_tc=ListOf('m/s^2/K'),
       accel_scale_tc=ListOf('1/K'), gyro_bias_tc=ListOf('rad/s/K'), gyro_scale_tc=ListOf('1/K'),
       g_sensitivity=ListOf('rad*s/m'),
       table_rate='rad/s', table_hold='s', table_tilt='deg', table_u_axis='deg', yaw_deg='deg', yaw_hold='s',
       table_temperature_end='degC')
def simulate_imu_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    poses: Annotated[int, typer.Option("--poses", help="Static poses after the still start.")] = 30,
    fs: Annotated[str, typer.Option("--fs", help="Sample rate, Hz.")] = "100.0",
    init_s: Annotated[str, typer.Option("--init", help="Still start, s.")] = "20.0",
    pose_s: Annotated[str, typer.Option("--pose", help="Each static pose, s.")] = "3.0",
    rotation_s: Annotated[str, typer.Option("--rotation", help="Each rotation, s (small: fast motion).")] = "1.5",
    accel_noise: Annotated[str, typer.Option("--accel-noise", help="Accelerometer noise per sample, m/s^2.")] = "0.02",
    gyro_noise: Annotated[str, typer.Option("--gyro-noise", help="Gyro noise per sample, rad/s.")] = "0.002",
    gyro_ar1: Annotated[float, typer.Option("--gyro-ar1", help="AR(1) coefficient of the gyro noise (coloured noise).")] = 0.0,
    bias_drift: Annotated[Optional[str], typer.Option("--bias-drift", help="Gyro bias change per s, x,y,z (rad/s/s).")] = None,
    exclude_axis: Annotated[Optional[int], typer.Option("--exclude-axis", help="Never rotate about this axis (0, 1, 2).")] = None,
    temperature: Annotated[Optional[str], typer.Option("--temperature", help="Warm-up from T0 to T1 over the session, degC (adds the channel temp; the parameters hold at 25 degC).")] = None,
    accel_bias_tc: Annotated[Optional[str], typer.Option("--accel-bias-tc", help="Accelerometer bias change x,y,z, m/s^2 per K (with --temperature).")] = None,
    accel_scale_tc: Annotated[Optional[str], typer.Option("--accel-scale-tc", help="Relative accelerometer scale change x,y,z per K (with --temperature).")] = None,
    gyro_bias_tc: Annotated[Optional[str], typer.Option("--gyro-bias-tc", help="Gyro bias change x,y,z, rad/s per K (with --temperature).")] = None,
    gyro_scale_tc: Annotated[Optional[str], typer.Option("--gyro-scale-tc", help="Relative gyro scale change x,y,z per K (with --temperature).")] = None,
    g_sensitivity: Annotated[Optional[str], typer.Option("--g-sensitivity", help="Gyro g-sensitivity, 9 numbers row by row, rad/s per m/s^2.")] = None,
    rate_table: Annotated[Optional[str], typer.Option("--rate-table", metavar="AXES", help="Rate-table runs after the poses about these body axes (e.g. x,y,z or z), each turned +rate and -rate; writes rate_table.csv for 'imu calibrate --rate-table'.")] = None,
    table_rate: Annotated[str, typer.Option("--table-rate", help="Table rate, rad/s (or '60 deg/s').")] = "1.0",
    table_hold: Annotated[str, typer.Option("--table-hold", help="Constant-rate part of each table run, s.")] = "20.0",
    table_u_rate: Annotated[float, typer.Option("--table-u-rate", help="Relative standard u of the rate the table file states.")] = 5e-5,
    table_u_axis: Annotated[str, typer.Option("--table-u-axis", help="Standard u of the axis direction the table file states, deg.")] = "0.0",
    table_rate_error: Annotated[float, typer.Option("--table-rate-error", help="Departure: the stated rate is (1 + this) times the true one.")] = 0.0,
    table_tilt: Annotated[str, typer.Option("--table-tilt", help="Departure: the IMU sits this far tilted on the table, deg (random direction).")] = "0.0",
    table_temperature_end: Annotated[Optional[str], typer.Option("--table-temperature-end", help="With --temperature: the warm-up spans the poses and the temperature then changes linearly over the table runs to this, degC.")] = None,
    yaw_poses: Annotated[int, typer.Option("--yaw-poses", help="Departure: this many poses hold a turn about the vertical (the accelerometer sees one pose, the gyro a rotation).")] = 0,
    yaw_deg: Annotated[str, typer.Option("--yaw-deg", help="Angle of each such turn, deg.")] = "90.0",
    yaw_hold: Annotated[Optional[str], typer.Option("--yaw-hold", help="Still time before and after each such turn, s (default --pose).")] = None,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
) -> None:
    """A multi-pose IMU session with known errors: imu.csv + truth JSON."""
    from senscal.cli.common import parse_floats
    from senscal.errors import InputError
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.imu import simulate_imu

    if poses < 1 or not fs > 0:
        raise InputError("--poses must be at least 1 and --fs positive")
    import math

    from senscal.cli import MAX_SIMULATED_SAMPLES

    # NaN passed the simulator's checks to int() (an internal error), a negative --init to an array size
    for opt, v, zero_ok in (("--init", init_s, True), ("--pose", pose_s, False), ("--rotation", rotation_s, False),
                            ("--accel-noise", accel_noise, True), ("--gyro-noise", gyro_noise, True)):
        if not (math.isfinite(v) and (v >= 0 if zero_ok else v > 0)):
            raise InputError(f"{opt} must be a finite number {'of 0 or more' if zero_ok else 'above 0'}, got {v!r}")
    if not (0 <= yaw_poses <= poses and math.isfinite(yaw_deg)) or (yaw_hold is not None and not (
            math.isfinite(yaw_hold) and yaw_hold > 0)):
        raise InputError(f"--yaw-poses must lie in 0..--poses ({poses}), --yaw-deg be finite and --yaw-hold a "
                         f"positive number of seconds, got {yaw_poses}, {yaw_deg!r}, {yaw_hold!r}")
    if table_temperature_end is not None and (not math.isfinite(table_temperature_end) or rate_table is None
                                              or temperature is None):
        raise InputError("--table-temperature-end needs --rate-table and --temperature (it continues the warm-up "
                         "over the table runs) and a finite temperature in degC")
    if not 0 <= gyro_ar1 < 1:
        raise InputError(f"--gyro-ar1 must lie in [0, 1) (1 is a random walk, not a noise), got {gyro_ar1!r}")
    n_samples = fs * (init_s + poses * (pose_s + rotation_s))
    if n_samples > MAX_SIMULATED_SAMPLES:
        raise InputError(f"--poses {poses} of {pose_s:g} + {rotation_s:g} s at --fs {fs:g} Hz is {n_samples:.3g} samples "
                         f"per channel; the simulators write at most {MAX_SIMULATED_SAMPLES:.0e}: fewer or shorter poses")
    d = tuple(parse_floats(bias_drift, "--bias-drift")) if bias_drift is not None else (0.0, 0.0, 0.0)
    if len(d) != 3:
        raise InputError("--bias-drift needs three comma-separated numbers")
    if exclude_axis is not None and exclude_axis not in (0, 1, 2):
        raise InputError("--exclude-axis must be 0, 1 or 2")

    def numbers(text, what, n):
        v = tuple(parse_floats(text, what)) if text is not None else None
        if v is not None and len(v) != n:
            raise InputError(f"{what} needs {n} comma-separated numbers, got {len(v)}")
        return v

    temp = numbers(temperature, "--temperature", 2)
    tcs = {k: numbers(v, f"--{k.replace('_', '-')}", 3) or (0.0, 0.0, 0.0) for k, v in
           (("accel_bias_tc", accel_bias_tc), ("accel_scale_tc", accel_scale_tc), ("gyro_bias_tc", gyro_bias_tc),
            ("gyro_scale_tc", gyro_scale_tc))}
    if temp is None and any(any(v) for v in tcs.values()):
        raise InputError("temperature coefficients need --temperature T0,T1 (the warm-up they act over)")
    gs = numbers(g_sensitivity, "--g-sensitivity", 9)
    spec = None
    if rate_table is not None:
        import math
        import re

        from senscal.simulate.imu_table import TableSpec

        axes = tuple(a.strip().lower() for a in rate_table.split(",") if a.strip())
        if not axes or any(re.fullmatch(r"[+-]?[xyz]", a) is None for a in axes):
            raise InputError(f"--rate-table takes body axes such as x,y,z or -z, got {rate_table!r}")
        if not (table_rate > 0 and table_hold > 1.0 and table_u_rate >= 0 and table_u_axis >= 0):
            raise InputError("--table-rate must be positive, --table-hold above 1 s, --table-u-rate and "
                             "--table-u-axis not negative")
        spec = TableSpec(axes=axes, rate=table_rate, hold_s=table_hold, u_rate_rel=table_u_rate,
                         u_axis=math.radians(table_u_axis), rate_error_rel=table_rate_error,
                         mount_tilt=math.radians(table_tilt), temperature_end=table_temperature_end)
    rec, truth = simulate_imu(n_poses=poses, fs=fs, init_s=init_s, pose_s=pose_s, rotation_s=rotation_s,
                              accel_noise=accel_noise, gyro_noise=gyro_noise, gyro_ar1=gyro_ar1, gyro_bias_drift=d,
                              exclude_axis=exclude_axis, temperature=temp, **tcs,
                              gyro_g_sensitivity=None if gs is None else np.reshape(gs, (3, 3)), rate_table=spec,
                              yaw_poses=yaw_poses, yaw_deg=yaw_deg, yaw_hold_s=yaw_hold, seed=seed)
    p = write_recording(rec, out / "imu.csv", units_in_header=True)  # ax [m/s^2]: the units travel with the data
    q = write_truth(truth, out / "imu_truth.json")
    if spec is not None:
        from senscal.io.guard import write_text
        from senscal.io.ratetable import rate_table_text
        from senscal.simulate.imu_table import rate_table_of

        q = f"{q}, " + str(write_text(out / "rate_table.csv", rate_table_text(rate_table_of(truth)), what="rate table"))
    console.print(f"wrote {p} and {q}")
