"""``senscal shaft calibrate|compensate`` and ``senscal simulate shaft``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import app, simulate_app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings,
                                print_json, progress_bar, table)
from senscal.cli.common import StartOpt, StopOpt, TimeUnitOpt
from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt,
                                       StandardOpt, note_standards, save_if_requested, use_standards)
from senscal.errors import InputError
from senscal.jobs._base import with_read_options

shaft_app = typer.Typer(help="Rotating shaft: gravity identification and compensation (angular acceleration "
                             "from one tangential accelerometer).", no_args_is_help=True)
app.add_typer(shaft_app, name="shaft")

AngleOpt = Annotated[str, typer.Option("--angle", help="Encoder angle channel.")]
AccelOpt = Annotated[str, typer.Option("--accel", help="Accelerometer channel (tangential).")]
AngleUnitOpt = Annotated[Optional[str], typer.Option(
    "--angle-unit", help="deg or rad; default: the channel's unit in the file, else rad.")]
WindowOpt = Annotated[Optional[str], typer.Option(
    "--window", help="Savitzky-Golay window of the encoder derivatives, s.")]
PlotOpt = Annotated[Optional[Path], typer.Option("--plot", help="Before/after compensation against angle (PNG).")]



@with_read_options
def _calibrate_options(*, angle: str = "angle", accel: str = "accel", angle_unit: str | None = None,
                       sensitivity: float = 1.0, u_sensitivity: float = 0.0, radius: float | None = None,
                       ripple_correction: bool = True, g: float = 9.80665, window: float | None = None,
                       max_speed_variation: str = "10%", u_angle_deg: float = 0.0,
                       encoder_lines: int | None = None, **_):
    """``ShaftCalibrateOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.cli.common import parse_relative
    from senscal.jobs.shaft import ShaftCalibrateOptions

    return ShaftCalibrateOptions(
        angle=angle, accel=accel, angle_unit=angle_unit, sensitivity=sensitivity, u_sensitivity=u_sensitivity,
        radius=radius, ripple_correction=ripple_correction, g=g, window=window,
        max_speed_variation=parse_relative(max_speed_variation, "--max-speed-variation"), u_angle_deg=u_angle_deg,
        encoder_lines=encoder_lines)


@with_read_options
def _compensate_options(*, model_path: Path | str | None = None, radius: float | None = None, angle: str = "angle",
                        accel: str = "accel", angle_unit: str | None = None, window: float | None = None,
                        centripetal: bool = False, **_):
    """``ShaftCompensateOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.shaft import ShaftCompensateOptions

    return ShaftCompensateOptions(model=model_path, radius=radius, angle=angle, accel=accel, angle_unit=angle_unit,
                                  window=window, centripetal=centripetal)


# What `senscal batch` turns a job's option words into (see senscal.jobs).
JOB_OPTIONS = {"shaft-calibrate": _calibrate_options, "shaft-compensate": _compensate_options}


@shaft_app.command("calibrate")
@units(radius='m', g='m/s^2', window='s')
def calibrate_cmd(
    file: Annotated[Path, typer.Argument(help="Constant-speed run: encoder angle and accelerometer.")],
    angle: AngleOpt,
    accel: AccelOpt,
    angle_unit: AngleUnitOpt = None,
    sensitivity: Annotated[float, typer.Option("--sensitivity", help="Output per m/s^2 (1: output in m/s^2).")] = 1.0,
    u_sensitivity: Annotated[float, typer.Option("--u-sensitivity", help="Standard uncertainty of --sensitivity.")] = 0.0,
    radius: Annotated[Optional[str], typer.Option(
        "--radius", help="Sensor radius (m): subtract S*r*alpha_encoder before the fit (ripple locked to the turn).")] = None,
    ripple_correction: Annotated[bool, typer.Option(
        "--ripple-correction/--no-ripple-correction",
        help="Estimate the response to encoder angular acceleration with the fit (off: the paper's plain fit).")] = True,
    g: Annotated[str, typer.Option("--g", help="Local gravity, m/s^2.")] = "9.80665",
    window: WindowOpt = None,
    max_speed_variation: Annotated[str, typer.Option(
        "--max-speed-variation", help="Warn above this speed std/mean (e.g. 10% or 0.1).")] = "10%",
    u_angle_deg: Annotated[float, typer.Option(
        "--u-angle-deg", help="Encoder accuracy: standard uncertainty of its once-per-turn angle error "
                              "(eccentric disc), deg: the prior of the angle error estimated from the data "
                              "(0: none).")] = 0.0,
    encoder_lines: Annotated[Optional[int], typer.Option(
        "--encoder-lines", help="Encoder counts per revolution: its step is in u where the readings cannot show "
                                "it (a whole number of counts per sample); without it such a step is named "
                                "encoder-step-unknown.")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Write the model (JSON) for 'shaft compensate'.")] = None,
    plot: PlotOpt = None,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    json_out: JsonOpt = False,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, standard: StandardOpt = None,
) -> None:
    """Identify the gravity sinusoid against the encoder angle: amplitude, phase, offset, tilt, bias."""
    from senscal.jobs.shaft import shaft_calibrate

    opts = _calibrate_options(**locals())
    used_standards = use_standards(standard, db=db, date=date)
    with progress_bar("gravity fit against the encoder angle", None):
        result = shaft_calibrate(file, opts)
    model = result.model
    doc = result.to_dict()
    if out is not None:
        doc["model"] = str(model.save(out))
    if plot is not None:
        from senscal.shaft.plotting import plot_compensation

        doc["plot"] = str(plot_compensation(plot, model, result.angle, result.accel, result.compensated(),
                                            unit=result.accel_unit, title=f"gravity calibration: {file.name}"))
    save_if_requested(result, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date,
                      operator=operator, job="shaft", method=result.method, input_files=[file],
                      standards=used_standards)
    std_warns = note_standards(doc, used_standards)
    if json_out:
        print_json(doc)
    else:
        rows = [["amplitude", model.amplitude, 2 * model.u_amplitude, model.output_unit],
                ["phase (deg)", doc["phase_deg"], 2 * doc["u_phase_deg"], "deg"],
                ["offset", model.offset, 2 * model.u_offset, model.output_unit],
                ["tilt from horizontal (deg)", doc["tilt_deg"], 2 * doc["u_tilt_deg"], "deg"],
                ["bias (m/s^2)", model.bias, 2 * model.u_bias, "m/s^2"],
                ["residual RMS", model.residual_rms, None, model.output_unit],
                ["revolutions", model.revolutions, None, ""],
                ["speed (rev/s)", doc["mean_speed_rps"], None, f"varies {100 * model.speed_variation:.2g}%"],
                [f"ripple leak ({model.ripple_correction})", model.ripple_leak, None,
                 "removed" if model.ripple_correction != "none" else "left in the fit"]]
        console.print(table(f"Gravity calibration of {file}  (U = expanded uncertainty, k=2)",
                            ["quantity", "value", "U (k=2)", "unit"], rows))
        for k in ("model", "plot"):
            if k in doc:
                console.print(f"wrote {doc[k]}")
    emit_warnings([*result.warnings, *std_warns], strict)


@shaft_app.command("compensate")
@units(radius='m', window='s')
def compensate_cmd(
    file: Annotated[Path, typer.Argument(help="Any run: encoder angle and accelerometer.")],
    model_path: Annotated[Path, typer.Option("--model", help="MODEL.json from 'shaft calibrate --out'.")],
    angle: AngleOpt,
    accel: AccelOpt,
    radius: Annotated[str, typer.Option("--radius", help="Sensor distance from the axis, m.")],
    angle_unit: AngleUnitOpt = None,
    window: WindowOpt = None,
    centripetal: Annotated[bool, typer.Option(
        "--centripetal/--no-centripetal",
        help="Estimate and remove the centripetal leakage k r (w^2 - w_cal^2) of a misaligned axis.")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="CSV: t, tangential_acceleration, angular_acceleration, "
                                                             "angular_acceleration_encoder.")] = None,
    plot: PlotOpt = None,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Remove gravity at the measured angle: tangential and angular acceleration, checked against the encoder."""
    from senscal.io import write_recording
    from senscal.jobs.shaft import shaft_compensate

    if out is not None and out.resolve() == Path(file).resolve():
        raise InputError(f"--out {out} would overwrite the input file; choose another name")
    with progress_bar("gravity compensation and encoder check", None):
        result = shaft_compensate(file, _compensate_options(**locals()))
    res, model = result.compensation, result.model
    doc = result.to_dict()
    if out is not None:
        doc["out"] = str(write_recording(result.output_recording(), out))
    if plot is not None:
        from senscal.shaft.plotting import plot_compensation

        doc["plot"] = str(plot_compensation(
            plot, model, res.angle, result.accel, res.tangential_acceleration, unit=result.accel_unit,
            title=f"gravity compensation: {file.name} (r = {radius:g} m)", t=res.t,
            alphas={"uncompensated (smoothed)": _smoothed(res.uncompensated_angular_acceleration, res),
                    "compensated (smoothed)": res.angular_acceleration_smoothed,
                    "encoder (Savitzky-Golay)": res.angular_acceleration_encoder}))
    if json_out:
        print_json(doc)
    else:
        rows = [["RMS difference accel vs encoder (smoothed)", res.rms_difference, "rad/s^2"],
                ["expected from noise", res.expected_rms_difference, "rad/s^2"],
                ["correlation", res.correlation, ""],
                ["RMS difference without compensation", res.uncompensated_rms_difference, "rad/s^2"],
                ["noise floor per sample (noise / S r)", res.noise_floor, "rad/s^2"],
                ["smoothing window", res.window, "s"]]
        if res.centripetal_coefficient is not None:
            rows += [["centripetal leakage k r", res.centripetal_coefficient, "m"],
                     ["U (k=2)", 2 * res.u_centripetal_coefficient, "m"],
                     ["axis misalignment", math.degrees(res.misalignment), "deg"],
                     ["U (k=2)", 2 * math.degrees(res.u_misalignment), "deg"]]
        console.print(table(f"Gravity compensation of {file}", ["quantity", "value", "unit"], rows))
        for k in ("out", "plot"):
            if k in doc:
                console.print(f"wrote {doc[k]}")
    emit_warnings(result.warnings, strict)


def _smoothed(x, res):
    from senscal.shaft.angle import smooth

    dt = (res.t[-1] - res.t[0]) / (res.t.size - 1)
    return smooth(x, int(round(res.window / dt)) | 1)


@simulate_app.command("shaft")
@units(tilt='deg', radius='m', misalignment='deg', fs='Hz', speed='rev/s', ripple_freq='Hz', cal_duration='s',
       test_speed='rev/s', modulation_freq='Hz', test_duration='s', angle_ripple_phase='deg', start_angle='deg')
def simulate_shaft_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    tilt: Annotated[str, typer.Option("--tilt", help="Shaft tilt from horizontal, deg.")] = "20.0",
    radius: Annotated[str, typer.Option("--radius", help="Sensor radius, m.")] = "0.1",
    sensitivity: Annotated[float, typer.Option("--sensitivity", help="Output per m/s^2 (1: output in m/s^2).")] = 1.0,
    bias: Annotated[float, typer.Option("--bias", help="Sensor bias, output unit.")] = 0.05,
    misalignment: Annotated[str, typer.Option("--misalignment", help="Sensitive axis toward the centre, deg.")] = "0.5",
    noise: Annotated[float, typer.Option("--noise", help="Output noise standard deviation.")] = 0.02,
    noise_rho: Annotated[float, typer.Option(
        "--noise-rho", help="Lag-one correlation of the output noise, 0 <= rho < 1 (AR(1); 0: white).")] = 0.0,
    encoder_counts: Annotated[int, typer.Option("--encoder-counts", help="Encoder counts per revolution.")] = 4096,
    fs: Annotated[str, typer.Option("--fs", help="Sample rate, Hz.")] = "1000.0",
    speed: Annotated[str, typer.Option("--speed", help="Calibration speed, rev/s.")] = "1.0",
    ripple: Annotated[float, typer.Option("--ripple", help="Relative speed ripple of the calibration run.")] = 0.03,
    ripple_freq: Annotated[str, typer.Option("--ripple-freq", help="Ripple frequency, Hz.")] = "2.7",
    sync_ripple: Annotated[float, typer.Option(
        "--sync-ripple", help="Relative speed ripple locked to the turn (once per revolution, an unbalanced rotor).")] = 0.0,
    cal_duration: Annotated[str, typer.Option("--cal-duration", help="Calibration run, s.")] = "20.0",
    test_speed: Annotated[str, typer.Option("--test-speed", help="Test run mean speed, rev/s.")] = "2.0",
    modulation: Annotated[float, typer.Option("--modulation", help="Test run relative speed modulation.")] = 0.5,
    modulation_freq: Annotated[str, typer.Option("--modulation-freq", help="Its frequency, Hz.")] = "0.5",
    test_duration: Annotated[str, typer.Option("--test-duration", help="Test run, s.")] = "10.0",
    wrap: Annotated[bool, typer.Option("--wrap/--no-wrap", help="Encoder angle wrapped to 0..360 deg.")] = True,
    angle_ripple: Annotated[float, typer.Option(
        "--angle-ripple", help="Calibration speed ripple as a function of the angle, w0 (1 + m sin(theta + p)) "
                               "(replaces --ripple/--sync-ripple).")] = 0.0,
    angle_ripple_phase: Annotated[str, typer.Option("--angle-ripple-phase", help="Its phase p, deg.")] = "0.0",
    eccentricity: Annotated[float, typer.Option(
        "--eccentricity", help="Once-per-turn encoder angle error (eccentric disc), deg.")] = 0.0,
    start_angle: Annotated[str, typer.Option(
        "--start-angle", help="True shaft angle at the start of each run, deg (0: on an encoder count).")] = "0.0",
) -> None:
    """A tilted shaft with a tangential accelerometer: shaft_cal.csv, shaft_test.csv, shaft_truth.json."""
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.shaft import simulate_shaft

    cal, test, truth = simulate_shaft(
        tilt_deg=tilt, radius=radius, sensitivity=sensitivity, bias=bias, misalignment_deg=misalignment, noise=noise,
        noise_rho=noise_rho, encoder_counts=encoder_counts, fs=fs, speed_rps=speed, ripple=ripple, ripple_freq=ripple_freq,
        sync_ripple=sync_ripple, cal_duration=cal_duration, test_speed_rps=test_speed, modulation=modulation,
        modulation_freq=modulation_freq, test_duration=test_duration, wrap=wrap, angle_ripple=angle_ripple,
        angle_ripple_phase_deg=angle_ripple_phase, eccentricity_deg=eccentricity, start_angle_deg=start_angle,
        seed=seed)
    al = truth.pop("_test_angular_acceleration")
    # Units ride in the headers ("angle [deg]"), so the angle unit need not be given for these files.
    p1 = write_recording(cal, out / "shaft_cal.csv", units_in_header=True)
    p2 = write_recording(test, out / "shaft_test.csv", units_in_header=True)
    write_recording(type(test)(channels={"angular_acceleration": al}, t=test.time, units={"angular_acceleration": "rad/s^2"}),
                    out / "shaft_test_truth.csv", units_in_header=True)
    p3 = write_truth(truth, out / "shaft_truth.json")
    console.print(f"wrote {p1}, {p2}, {p3} (angle in deg, accel in {truth['output_unit']})")
