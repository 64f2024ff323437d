"""``senscal imu calibrate`` and ``senscal simulate imu`` (issue 27)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app, simulate_app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, SkipRowsOpt, StartOpt, StopOpt, StrictOpt, TimeColumnOpt,
                                TimeUnitOpt, console, emit_warnings, print_json, progress_bar, table)
from senscal.jobs._base import with_read_options

imu_app = typer.Typer(help="IMU calibration: accelerometer and gyroscope together from one multi-pose session.",
                      no_args_is_help=True)
app.add_typer(imu_app, name="imu")


@with_read_options
def _imu_options(*, accel_channels: str = "ax,ay,az", gyro_channels: str = "gx,gy,gz", gravity: float = 9.80665,
                 static_window: float = 1.0, min_pose: float = 1.0, init_static: float | None = None, **_):
    """``ImuOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.imu import ImuOptions

    return ImuOptions(accel_channels=accel_channels, gyro_channels=gyro_channels, gravity=gravity,
                      static_window=static_window, min_pose=min_pose, init_static=init_static)


# What `senscal batch` turns the job's option words into (see senscal.jobs).
JOB_OPTIONS = {"imu-calibrate": _imu_options}


@imu_app.command("calibrate")
def imu_calibrate_cmd(
    file: Annotated[Path, typer.Argument(help="Recording with three accelerometer and three gyroscope channels (a still start, then static poses joined by rotations).")],
    accel_channels: Annotated[str, typer.Option("--accel-channels", help="Accelerometer X,Y,Z channel names.")] = "ax,ay,az",
    gyro_channels: Annotated[str, typer.Option("--gyro-channels", help="Gyroscope X,Y,Z channel names (rad/s, deg/s or counts).")] = "gx,gy,gz",
    gravity: Annotated[float, typer.Option("--gravity", help="Local g, m/s^2.")] = 9.80665,
    static_window: Annotated[float, typer.Option("--static-window", help="Moving-variance window of the static detection, s.")] = 1.0,
    min_pose: Annotated[float, typer.Option("--min-pose", help="Shortest static pose kept, s.")] = 1.0,
    init_static: Annotated[Optional[float], typer.Option("--init-static", help="Length of the still start, s (reference variance of the threshold sweep; default: estimated).")] = None,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    skip_rows: SkipRowsOpt = None,
    time_unit: TimeUnitOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Accelerometer and gyroscope scale, misalignment and bias from one multi-pose session."""
    from senscal.jobs.imu import imu_calibrate

    with progress_bar("calibrating", None):
        res = imu_calibrate(file, _imu_options(**locals()))
    doc = res.to_dict()
    if json_out:
        print_json(doc)
        emit_warnings(res.warnings, strict)
        return
    a, g = doc["accelerometer"], doc["gyroscope"]
    rows = []
    for i, ax in enumerate("xyz"):
        rows.append([f"accel scale {ax}", a["scale"][i], 2 * a["u_scale"][i], a["scale_unit"]])
    for i, ax in enumerate("xyz"):
        rows.append([f"accel bias {ax}", a["bias"][i], 2 * a["u_bias"][i], a["bias_unit"]])
    for n, p in a["misalignment_deg"].items():
        rows.append([f"accel {n}", p["value"], p["U_k2"], "deg"])
    for i, ax in enumerate("xyz"):
        rows.append([f"gyro scale {ax}", g["scale"][i], 2 * g["u_scale"][i], g["scale_unit"]])
    for i, ax in enumerate("xyz"):
        rows.append([f"gyro bias {ax}", g["bias"][i], 2 * g["u_bias"][i], g["bias_unit"]])
    for n, p in g["misalignment_deg"].items():
        rows.append([f"gyro misalignment {n}", p["value"], p["U_k2"], "deg"])
    console.print(table(f"IMU calibration of {file} (U = expanded uncertainty, k=2)", ["parameter", "value", "U",
                                                                                        "unit"], rows))
    st, gd = doc["static"], doc["gravity_direction_residual_deg"]
    console.print(f"{st['n_poses']} static poses (threshold x{st['threshold_multiple']:g} the still variance); "
                  f"|g| spread after {a['g_spread']['std']:.3g} m/s^2")
    console.print(f"gravity-direction residual per rotation: rms {gd['rms_before']:.3g} deg before, "
                  f"{gd['rms_after']:.3g} deg after the gyroscope calibration")
    emit_warnings(res.warnings, strict)


@simulate_app.command("imu")
def simulate_imu_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    poses: Annotated[int, typer.Option("--poses", help="Static poses after the still start.")] = 30,
    fs: Annotated[float, typer.Option("--fs", help="Sample rate, Hz.")] = 100.0,
    init_s: Annotated[float, typer.Option("--init", help="Still start, s.")] = 20.0,
    pose_s: Annotated[float, typer.Option("--pose", help="Each static pose, s.")] = 3.0,
    rotation_s: Annotated[float, typer.Option("--rotation", help="Each rotation, s (small: fast motion).")] = 1.5,
    accel_noise: Annotated[float, typer.Option("--accel-noise", help="Accelerometer noise per sample, m/s^2.")] = 0.02,
    gyro_noise: Annotated[float, typer.Option("--gyro-noise", help="Gyro noise per sample, rad/s.")] = 0.002,
    gyro_ar1: Annotated[float, typer.Option("--gyro-ar1", help="AR(1) coefficient of the gyro noise (coloured noise).")] = 0.0,
    bias_drift: Annotated[Optional[str], typer.Option("--bias-drift", help="Gyro bias change per s, x,y,z (rad/s/s).")] = None,
    exclude_axis: Annotated[Optional[int], typer.Option("--exclude-axis", help="Never rotate about this axis (0, 1, 2).")] = None,
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
    d = tuple(parse_floats(bias_drift, "--bias-drift")) if bias_drift is not None else (0.0, 0.0, 0.0)
    if len(d) != 3:
        raise InputError("--bias-drift needs three comma-separated numbers")
    if exclude_axis is not None and exclude_axis not in (0, 1, 2):
        raise InputError("--exclude-axis must be 0, 1 or 2")
    rec, truth = simulate_imu(n_poses=poses, fs=fs, init_s=init_s, pose_s=pose_s, rotation_s=rotation_s,
                              accel_noise=accel_noise, gyro_noise=gyro_noise, gyro_ar1=gyro_ar1, gyro_bias_drift=d,
                              exclude_axis=exclude_axis, seed=seed)
    p = write_recording(rec, out / "imu.csv")
    q = write_truth(truth, out / "imu_truth.json")
    console.print(f"wrote {p} and {q}")
