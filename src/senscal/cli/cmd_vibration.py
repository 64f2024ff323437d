"""``senscal velocity``, ``senscal response``, ``senscal linearity`` and the
``hydraulic``, ``centrifuge``, ``shaker`` simulators."""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import ListOf, units
from senscal.cli.app import app, simulate_app
from senscal.cli.cert_opts import (CalDateOpt, CertIdOpt, ConformityOpt, CustomerOpt, DccOpt, DecisionRuleOpt, EnvOpt,
                                   ItemOpt, LabOpt, LocationOpt, ManufacturerOpt, ModelOpt, ReportOpt, RunFileOpt,
                                   SensorIdOpt, SignCertOpt, SignKeyOpt, cert_fields, certify,
                                   check_conformity)
from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt,
                                       StandardOpt, note_standards, save_if_requested, use_standards)
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, TimeUnitOpt, console, emit_warnings,
                                err_console, parse_floats, parse_relative, print_json, table, track)
from senscal.cli.common import StartOpt, StopOpt
from senscal.errors import InputError
from senscal.jobs._base import with_read_options
from senscal.jobs.vibration import LinearityOptions, ResponseOptions, VelocityOptions
from senscal.jobs.vibration import linearity as linearity_job
from senscal.jobs.vibration import response as response_job
from senscal.jobs.vibration import velocity as velocity_job
from senscal.simulate.common import write_simulation

FilesArg = Annotated[List[Path], typer.Argument(help="Recording files, one per frequency point / input level.")]
FreqOpt = Annotated[Optional[List[str]], typer.Option(
    "--freq", help="Known frequency in Hz: one for all files or one per file (repeat or comma-separate); estimated when omitted.")]
PlotOpt = Annotated[Optional[Path], typer.Option("--plot", help="Write the key plot to this PNG file.")]
ConditionOpt = Annotated[Optional[List[str]], typer.Option(
    "--condition", help="Calibration condition for the certificate, KEY=VALUE (repeatable), e.g. 'temperature=23.1 C'.")]
UnitOpt = Annotated[Optional[str], typer.Option("--output-unit", help="Unit of the sensor output when the file's header gives none (default V); mV data are converted to V.")]


def _rel(text: str | None, what: str) -> float:
    return 0.0 if text is None else parse_relative(text, what)


def _freq_values(values: list[str] | None):
    """``--freq`` words (repeated or comma-separated) as numbers; the job checks them against the files."""
    return None if not values else tuple(f for v in values for f in parse_floats(v, "--freq"))


def _save_plot(fig, path: Path | None) -> None:
    if path is not None:
        from senscal.report.plots import save_figure

        save_figure(fig, path)
        err_console.print(f"plot written to {path}")


def _conditions(items: list[str] | None) -> dict[str, str]:
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise InputError(f"--condition must look like KEY=VALUE, got {item!r}")
        out[key.strip()] = value.strip()
    return out


def _u2(u) -> str:
    """An uncertainty for a table: 2 significant digits (GUM 7.2.6)."""
    return "-" if u is None else f"{u:.2g}"


def _with_certificate(doc: dict, cert_warns: list[str], report: Path | None) -> None:
    """The certificate's warnings and file in the command's JSON document."""
    doc["warnings"] = [*doc.get("warnings", []), *cert_warns]
    if report is not None:
        doc["report"] = str(report)


def _finish(result, doc: dict, cert_warns: list[str], params: dict, *, method: str, figure, show) -> None:
    """What every vibration command does once its job has run: --save, --plot, the JSON or the table, the warnings.

    Parameters
    ----------
    result : JobResult
        The job's result (what ``--save`` stores).
    doc : dict
        The command's JSON document (printed with ``--json``).
    cert_warns : list of str
        Named warnings of the certificate.
    params : dict
        The command's parameters (``locals()``): files, report, plot, json_out, strict and the registry options.
    method : str
        How the registry describes the measurement.
    figure : callable
        Makes the ``--plot`` figure (called only when a plot is asked for).
    show : callable
        Prints the table (called only without ``--json``).
    """
    report = params["report"]
    used = params["used_standards"]
    save_if_requested(result, save=params["save"], sensor=params["sensor"], db=params["db"],
                      create_sensor=params["create_sensor"], date=params["date"], operator=params["operator"],
                      method=method, input_files=params["files"], certificate=report,
                      conditions=_conditions(params["condition"]), standards=used)
    std_warns = note_standards(doc, used)
    if params["plot"] is not None:
        _save_plot(figure(), params["plot"])
    if params["json_out"]:
        print_json(doc)
    else:
        show()
        if report is not None:
            console.print(f"certificate written to {report}")
    emit_warnings([*result.warnings, *std_warns, *cert_warns], params["strict"])


@with_read_options
def velocity_options(*, position=None, velocity=None, freq=None, u_position=None, drift=True, harmonics=1,
                     output_unit=None, conformity=None, decision_rule=None, **_) -> VelocityOptions:
    """:class:`~senscal.jobs.vibration.VelocityOptions` from the ``senscal velocity`` parameters."""
    check_conformity(conformity, decision_rule)
    return VelocityOptions(position=position, velocity=velocity, freq=_freq_values(freq),
                           u_position=_rel(u_position, "--u-position"), drift=drift, harmonics=harmonics,
                           output_unit=output_unit)


@with_read_options
def response_options(*, output=None, input_amplitude=None, reference=None, reference_sensitivity=None, angle=None,
                     static_sensitivity=None, initial_phase_deg=None, u_initial_phase_deg=0.0, phase_reference=None,
                     freq=None, u_input=None, u_reference=None, u_static=None, drift=False, harmonics=1,
                     output_unit=None, encoder_lines=None, u_angle_deg=0.0, conformity=None, decision_rule=None,
                     **_) -> ResponseOptions:
    """:class:`~senscal.jobs.vibration.ResponseOptions` from the ``senscal response`` parameters."""
    check_conformity(conformity, decision_rule)
    return ResponseOptions(
        output=output, input_amplitude=input_amplitude, reference=reference,
        reference_sensitivity=reference_sensitivity, angle=angle, static_sensitivity=static_sensitivity,
        initial_phase_deg=initial_phase_deg, u_initial_phase_deg=u_initial_phase_deg, phase_reference=phase_reference,
        freq=_freq_values(freq), u_input=_rel(u_input, "--u-input"), u_reference=_rel(u_reference, "--u-reference"),
        u_static_sensitivity=_rel(u_static, "--u-static-sensitivity"), drift=drift, harmonics=harmonics,
        output_unit=output_unit, encoder_lines=encoder_lines, u_angle_deg=u_angle_deg)


@with_read_options
def linearity_options(*, output=None, input_amplitudes=None, freq=None, angle=None, drift=False, harmonics=1,
                      u_input=None, output_unit=None, conformity=None, decision_rule=None, **_) -> LinearityOptions:
    """:class:`~senscal.jobs.vibration.LinearityOptions` from the ``senscal linearity`` parameters."""
    check_conformity(conformity, decision_rule)
    if input_amplitudes is None:
        raise InputError("give --input-amplitudes A1,A2,... (peak input of each file, m/s^2)")
    return LinearityOptions(output=output, input_amplitudes=tuple(parse_floats(input_amplitudes, "--input-amplitudes")),
                            freq=freq, angle=angle, drift=drift, harmonics=harmonics,
                            u_input=_rel(u_input, "--u-input"), output_unit=output_unit)


# What `senscal batch` uses to turn a job's option words into its options (without running the command).
JOB_OPTIONS = {"velocity": velocity_options, "response": response_options, "linearity": linearity_options}


# ---------------------------------------------------------------------------
# velocity
# ---------------------------------------------------------------------------

@app.command("velocity")
@units(freq=ListOf('Hz'))
def velocity_cmd(
    files: FilesArg,
    position: Annotated[str, typer.Option("--position", help="Position-reference channel (m).")],
    velocity: Annotated[str, typer.Option("--velocity", help="Velocity-sensor output channel.")],
    freq: FreqOpt = None,
    u_position: Annotated[Optional[str], typer.Option(
        "--u-position", help="Type B standard uncertainty of the position reference's scale, e.g. 0.1%.")] = None,
    drift: Annotated[bool, typer.Option("--drift/--no-drift", help="Fit a linear offset drift (default on).")] = True,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Harmonics of the motion fitted with the fundamental.")] = 1,
    output_unit: UnitOpt = None,
    time_column: TimeColumnOpt = "t", fs: FsOpt = None, names: NamesOpt = None, time_unit: TimeUnitOpt = None,
    start: StartOpt = None, stop: StopOpt = None,
    json_out: JsonOpt = False, report: ReportOpt = None, plot: PlotOpt = None,
    sensor_id: SensorIdOpt = None, model: ModelOpt = None, condition: ConditionOpt = None,
    dcc: DccOpt = None, lab: LabOpt = None, run_file: RunFileOpt = None, customer: CustomerOpt = None,
    item: ItemOpt = None, manufacturer: ManufacturerOpt = None, location: LocationOpt = None,
    certificate_id: CertIdOpt = None, calibration_date: CalDateOpt = None, env: EnvOpt = None,
    conformity: ConformityOpt = None, decision_rule: DecisionRuleOpt = None,
    sign_key: SignKeyOpt = None, sign_cert: SignCertOpt = None,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, standard: StandardOpt = None, strict: StrictOpt = False,
) -> None:
    """Velocity-sensor sensitivity S = A_s / (w A_p) against a position reference, per file and mean."""
    opts = velocity_options(**locals())
    used_standards = use_standards(standard, db=db, date=date, calibration_date=calibration_date)
    result = velocity_job(files, opts, progress=track)
    cal, unit = result.calibration, result.unit
    doc = result.to_dict()
    cert_warns = certify("velocity", cal, report=report, dcc=dcc, unit=unit, files=[str(f) for f in files],
                          method="Sinusoidal excitation against a position reference; least-squares sine fits of "
                                 "position and sensor output at one shared frequency; S = A_s / (w A_p) (Yang et al. 2014).",
                          conditions={"frequency points": len(cal.points),
                                      "frequencies (Hz)": ", ".join(f"{p.frequency:.4g}" for p in cal.points),
                                      "offset drift fitted": "yes" if drift else "no",
                                      "position reference u (type B)": f"{100 * opts.u_position:g} %",
                                      **_conditions(condition)},
                         warnings=result.warnings, doc=doc, **cert_fields(locals()))
    _with_certificate(doc, cert_warns, report)

    def figure():
        from senscal.report.certificate import velocity_figure

        return velocity_figure(cal)

    def show():
        rows = [[Path(p.source).stem, p.frequency, p.sensitivity, _u2(p.budget.expanded), math.degrees(p.phase),
                 _u2(2 * math.degrees(p.u_phase)), f"{p.snr_db:.1f}"] for p in cal.points]
        console.print(table(f"Velocity-sensor sensitivity ({unit}; U = expanded, k=2)",
                            ["file", "f (Hz)", "S", "U S", "phase vs v (deg)", "U phase", "SNR dB"], rows))
        console.print(f"mean S = {cal.sensitivity:.6g} {unit}, U = {cal.budget.expanded:.2g} "
                      f"(k={cal.budget.coverage_factor:.3g}), std over points = {cal.sensitivity_std:.2g}")

    _finish(result, doc, cert_warns, locals(), method="sine fit against a position reference (Yang et al. 2014)",
            figure=figure, show=show)


# ---------------------------------------------------------------------------
# response
# ---------------------------------------------------------------------------

@app.command("response")
@units(freq=ListOf('Hz'))
def response_cmd(
    files: FilesArg,
    output: Annotated[str, typer.Option("--output", help="Accelerometer output channel.")],
    input_amplitude: Annotated[Optional[str], typer.Option("--input-amplitude", help="Known peak input acceleration: m/s^2, or with a unit ('10 g').")] = None,
    reference: Annotated[Optional[str], typer.Option("--reference", help="Reference accelerometer channel (back-to-back).")] = None,
    reference_sensitivity: Annotated[Optional[str], typer.Option("--reference-sensitivity", help="Reference sensitivity: V/(m/s^2) for a voltage reference (whatever the file's scale), or with a unit ('10.2 mV/(m/s^2)').")] = None,
    angle: Annotated[Optional[str], typer.Option("--angle", help="Turntable angle channel (deg): cut to whole revolutions, input phase from it.")] = None,
    static_sensitivity: Annotated[Optional[str], typer.Option("--static-sensitivity", help="Static sensitivity S0 for S_i/S0: in the result's unit (V/(m/s^2) for a voltage output, also from mV data), or with a unit ('50 mV/(m/s^2)').")] = None,
    initial_phase_deg: Annotated[Optional[float], typer.Option("--initial-phase-deg", help="Input phase phi_0 (deg, sine convention) from a start-up test: at t=0, or at encoder angle 0 with --angle (90 when encoder zero lies along the field).")] = None,
    u_initial_phase_deg: Annotated[float, typer.Option("--u-initial-phase-deg", help="Standard uncertainty of --initial-phase-deg, deg (type B in the phase-delay budget).")] = 0.0,
    phase_reference: Annotated[Optional[Path], typer.Option("--phase-reference", help="Start-up / lowest-frequency double-centrifuge run (same channels) that gives phi_0 (needs --angle).")] = None,
    freq: FreqOpt = None,
    u_input: Annotated[Optional[str], typer.Option("--u-input", help="Type B standard uncertainty of the input amplitude, e.g. 0.2%.")] = None,
    u_reference: Annotated[Optional[str], typer.Option("--u-reference", help="Type B standard uncertainty of the reference sensitivity, e.g. 0.5%.")] = None,
    u_static: Annotated[Optional[str], typer.Option("--u-static-sensitivity", help="Type B standard uncertainty of S0, e.g. 0.05%.")] = None,
    drift: Annotated[bool, typer.Option("--drift/--no-drift", help="Fit a linear offset drift.")] = False,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Harmonics fitted with the fundamental (3 for a nonlinear sensor or a distorted excitation).")] = 1,
    encoder_lines: Annotated[Optional[int], typer.Option("--encoder-lines", help="Counts per revolution of the turntable encoder (with --angle); without it a quantised angle's step is detected. Its effect is the budget component 'encoder step'.")] = None,
    u_angle_deg: Annotated[float, typer.Option("--u-angle-deg", help="Standard uncertainty of the encoder's angle reading (accuracy specification), deg: type B in the phase delay.")] = 0.0,
    output_unit: UnitOpt = None,
    time_column: TimeColumnOpt = "t", fs: FsOpt = None, names: NamesOpt = None, time_unit: TimeUnitOpt = None,
    start: StartOpt = None, stop: StopOpt = None,
    json_out: JsonOpt = False, report: ReportOpt = None, plot: PlotOpt = None,
    sensor_id: SensorIdOpt = None, model: ModelOpt = None, condition: ConditionOpt = None,
    dcc: DccOpt = None, lab: LabOpt = None, run_file: RunFileOpt = None, customer: CustomerOpt = None,
    item: ItemOpt = None, manufacturer: ManufacturerOpt = None, location: LocationOpt = None,
    certificate_id: CertIdOpt = None, calibration_date: CalDateOpt = None, env: EnvOpt = None,
    conformity: ConformityOpt = None, decision_rule: DecisionRuleOpt = None,
    sign_key: SignKeyOpt = None, sign_cert: SignCertOpt = None,
    save_response_to: Annotated[Optional[Path], typer.Option("--save-response", help="Save the response (JSON with type and version) for later use.")] = None,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, standard: StandardOpt = None, strict: StrictOpt = False,
) -> None:
    """Accelerometer frequency response: sensitivity, S_i/S0, phase delay with GUM budgets."""
    opts = response_options(**locals())
    used_standards = use_standards(standard, db=db, date=date, calibration_date=calibration_date)
    result = response_job(files, opts, progress=track)
    resp, unit = result.response, result.unit
    doc = result.to_dict()
    cond, meth = {}, ""
    if report is not None or dcc is not None:
        cond = {"frequency points": len(resp.points), "method": resp.points[0].method}
        if result.input_amplitude is not None:
            cond["peak input acceleration (m/s^2)"] = f"{result.input_amplitude:g}"
            cond["input amplitude u (type B)"] = f"{100 * opts.u_input:g} %"
        else:
            cond["reference sensitivity"] = (f"{result.reference_sensitivity:g} {result.reference_unit} "
                                             f"(u = {100 * opts.u_reference:g} %)")
        if result.static_sensitivity is not None:
            cond["static sensitivity S0"] = (f"{result.static_sensitivity:g} {unit} "
                                             f"(u = {100 * opts.u_static_sensitivity:g} %)")
        if angle:
            cond["turntable angle synchronisation"] = "records cut to whole revolutions from a 360 deg crossing"
        cond["input phase phi_0"] = resp.phase_reference
        cond.update(_conditions(condition))
        meth = ("Double-centrifuge / known sinusoidal input; least-squares sine fit of the output "
                "(against the turntable angle when synchronised; Qin, seed 003)" if input_amplitude is not None
                else "Back-to-back comparison with a reference accelerometer (ISO 16063-21); sine fits at one shared frequency")
    cert_warns = certify("response", resp, report=report, dcc=dcc, unit=unit, method=meth, conditions=cond,
                         files=[str(f) for f in files]
                         + ([f"{phase_reference} (phase reference)"] if phase_reference is not None else []),
                         warnings=result.warnings, doc=doc, **cert_fields(locals()))
    _with_certificate(doc, cert_warns, report)
    if save_response_to is not None:
        from senscal.vibration import save_response

        doc["saved"] = str(save_response(resp, save_response_to))

    def figure():
        from senscal.report.certificate import response_figure

        return response_figure(resp)

    def show():
        rows = [[p["frequency_hz"], p["sensitivity"], _u2(p["U_sensitivity"]), p["normalized_sensitivity"],
                 _u2(p["U_normalized_sensitivity"]), p["phase_delay_deg"], _u2(p["U_phase_delay_deg"])]
                for p in doc["points"]]
        console.print(table(f"Frequency response ({unit}; U = expanded, k=2)",
                            ["f (Hz)", "S", "U S", "S/S0", "U S/S0", "phase delay (deg)", "U (deg)"], rows))
        console.print(f"phase reference: {resp.phase_reference}")
        if "repeats" in doc:
            rows = [[g["frequency_hz"], g["n_repeats"], g["sensitivity"], _u2(g["U_sensitivity"]),
                     g["normalized_sensitivity"], _u2(g["U_normalized_sensitivity"]), g["phase_delay_deg"],
                     _u2(g["U_phase_delay_deg"]), f"{g['coverage_factor']:.3g}"] for g in doc["repeats"]]
            console.print(table("Repeats combined (U = expanded with the k shown: 2, or Student's t when type A "
                                "comes from the spread of few repeats)",
                                ["f (Hz)", "n", "S", "U S", "S/S0", "U S/S0", "phase delay (deg)", "U (deg)", "k"], rows))

    _finish(result, doc, cert_warns, locals(), method=doc["method"], figure=figure, show=show)


# ---------------------------------------------------------------------------
# linearity
# ---------------------------------------------------------------------------

@app.command("linearity")
@units(input_amplitudes=ListOf('m/s^2'), freq='Hz')
def linearity_cmd(
    files: FilesArg,
    output: Annotated[str, typer.Option("--output", help="Accelerometer output channel.")],
    input_amplitudes: Annotated[str, typer.Option("--input-amplitudes", help="Peak input of each file, m/s^2, comma separated.")],
    freq: Annotated[Optional[str], typer.Option("--freq", help="Known frequency in Hz (estimated per file when omitted).")] = None,
    angle: Annotated[Optional[str], typer.Option("--angle", help="Turntable angle channel (deg): fit against the angle.")] = None,
    drift: Annotated[bool, typer.Option("--drift/--no-drift", help="Fit a linear offset drift.")] = False,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Harmonics fitted with the fundamental (3 for a nonlinear sensor or a distorted excitation).")] = 1,
    u_input: Annotated[Optional[str], typer.Option("--u-input", help="Standard uncertainty of each input level, random from level to level (e.g. main-arm speed set anew), e.g. 0.05%.")] = None,
    output_unit: UnitOpt = None,
    time_column: TimeColumnOpt = "t", fs: FsOpt = None, names: NamesOpt = None, time_unit: TimeUnitOpt = None,
    start: StartOpt = None, stop: StopOpt = None,
    json_out: JsonOpt = False, report: ReportOpt = None, plot: PlotOpt = None,
    sensor_id: SensorIdOpt = None, model: ModelOpt = None, condition: ConditionOpt = None,
    dcc: DccOpt = None, lab: LabOpt = None, run_file: RunFileOpt = None, customer: CustomerOpt = None,
    item: ItemOpt = None, manufacturer: ManufacturerOpt = None, location: LocationOpt = None,
    certificate_id: CertIdOpt = None, calibration_date: CalDateOpt = None, env: EnvOpt = None,
    conformity: ConformityOpt = None, decision_rule: DecisionRuleOpt = None,
    sign_key: SignKeyOpt = None, sign_cert: SignCertOpt = None,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, standard: StandardOpt = None, strict: StrictOpt = False,
) -> None:
    """Amplitude linearity at a fixed frequency: best straight line, deviations, linearity in % of full scale."""
    opts = linearity_options(**locals())
    used_standards = use_standards(standard, db=db, date=date, calibration_date=calibration_date)
    result = linearity_job(files, opts, progress=track)
    lin, unit, out_unit, amps = result.linearity, result.unit, result.output_unit, opts.input_amplitudes
    doc = result.to_dict()
    cert_warns = certify("linearity", lin, report=report, dcc=dcc, unit=unit, files=[str(f) for f in files],
                          method="Fixed frequency, input amplitude stepped; least-squares sine fit of each record; "
                                 "best straight line through (input, output amplitude) (Qin, seed 003)",
                          conditions={"input levels": len(files),
                                      "frequency (Hz)": f"{sum(p.frequency for p in result.points) / len(result.points):.4g}",
                                      "input range (m/s^2)": f"{min(amps):g} .. {max(amps):g}",
                                      "input level u (random per level)": f"{100 * opts.u_input:g} %",
                                      "angle synchronisation": "yes" if angle else "no", **_conditions(condition)},
                         warnings=result.warnings, doc=doc, **cert_fields(locals()))
    _with_certificate(doc, cert_warns, report)

    def figure():
        from senscal.report.certificate import linearity_figure

        return linearity_figure(lin, f"({out_unit})")

    def show():
        rows = [[Path(p.source).stem, p.input_amplitude, p.output_amplitude, _u2(2 * p.u_output_amplitude),
                 f"{p.deviation:.3g}", f"{p.deviation_percent:.3g}"] for p in lin.points]
        console.print(table("Amplitude linearity (U = expanded, k=2)",
                            ["file", "input (m/s^2)", "output", "U output", "deviation", "dev (% FS)"], rows))
        k = lin.coverage_factor
        console.print(f"slope = {lin.slope:.6g} {unit} (U = {k * lin.u_slope:.2g}, k={k:.3g}), intercept = "
                      f"{lin.intercept:.4g} (U = {k * lin.u_intercept:.2g}, k={k:.3g})")
        if lin.linearity_resolved is False:
            console.print(f"linearity below {lin.linearity_bound_percent:.2g} % of full scale {lin.full_scale_output:.6g} "
                          f"(not resolved: largest deviation {lin.linearity_percent:.2g} % is within the noise)")
        else:
            console.print(f"linearity = {lin.linearity_percent:.3g} % of full scale {lin.full_scale_output:.6g} "
                          f"(U = {2 * lin.u_linearity_percent:.2g} %, k=2, Monte Carlo)")

    _finish(result, doc, cert_warns, locals(), method="amplitude linearity, best straight line (Qin, seed 003)",
            figure=figure, show=show)


# ---------------------------------------------------------------------------
# simulators
# ---------------------------------------------------------------------------

OutOpt = Annotated[Path, typer.Option("--out", help="Output folder.")]
SeedOpt = Annotated[Optional[int], typer.Option("--seed", help="Random seed.")]


def _opt_floats(text: str | None, what: str):
    return None if text is None else parse_floats(text, what)


@simulate_app.command("hydraulic")
@units(freqs=ListOf('Hz'), sensitivity='V/(m/s)', noise='V')
def simulate_hydraulic_cmd(
    out: OutOpt, seed: SeedOpt = None,
    freqs: Annotated[Optional[str], typer.Option("--freqs", help="Frequencies in Hz, comma separated (default 1..5.5 Hz, 10 points).")] = None,
    sensitivity: Annotated[str, typer.Option("--sensitivity", help="Velocity-sensor sensitivity, V/(m/s).")] = "0.1368",
    noise: Annotated[str, typer.Option("--noise", help="Velocity-sensor noise, V.")] = "3e-4",
    distortion: Annotated[float, typer.Option("--distortion", help="Third harmonic of the motion, relative.")] = 0.0,
    sensitivity_scatter: Annotated[float, typer.Option("--sensitivity-scatter", help="Departure: relative standard deviation of the sensitivity from record to record.")] = 0.0,
) -> None:
    """Hydraulic rig: position reference and velocity sensor, one CSV per frequency, truth JSON."""
    from senscal.simulate.vibration import simulate_hydraulic

    recs, truth = simulate_hydraulic(frequencies=_opt_floats(freqs, "--freqs"), sensitivity=sensitivity,
                                     velocity_noise=noise, distortion=distortion,
                                     sensitivity_scatter=sensitivity_scatter, seed=seed)
    paths = write_simulation(recs, truth, out, "hydraulic")
    console.print(f"wrote {len(paths)} recordings and hydraulic_truth.json to {out}")


@simulate_app.command("centrifuge")
@units(freqs=ListOf('Hz'), accelerations=ListOf('m/s^2'), static_sensitivity='V/(m/s^2)', natural_frequency='Hz',
       noise='V', phase_reference_freq='Hz')
def simulate_centrifuge_cmd(
    out: OutOpt, seed: SeedOpt = None,
    freqs: Annotated[str, typer.Option("--freqs", help="Turntable frequencies, Hz.")] = "0.1,1,5,10",
    accelerations: Annotated[str, typer.Option("--accelerations", help="Peak accelerations a0, m/s^2 (one record per frequency and a0).")] = "100",
    static_sensitivity: Annotated[str, typer.Option("--static-sensitivity", help="S0, V/(m/s^2).")] = "0.05",
    natural_frequency: Annotated[str, typer.Option("--natural-frequency", help="Accelerometer natural frequency, Hz.")] = "40.0",
    damping: Annotated[float, typer.Option("--damping", help="Damping ratio.")] = 0.6,
    noise: Annotated[str, typer.Option("--noise", help="Output noise, V.")] = "2e-3",
    cubic: Annotated[float, typer.Option("--cubic", help="Cubic nonlinearity, 1/(m/s^2)^2.")] = 0.0,
    encoder_zero_deg: Annotated[float, typer.Option("--encoder-zero-deg", help="Departure: encoder zero this many degrees off the field direction (phi_0 = 90 + offset).")] = 0.0,
    sensitivity_scatter: Annotated[float, typer.Option("--sensitivity-scatter", help="Departure: relative standard deviation of S0 from record to record (remounting).")] = 0.0,
    input_scatter: Annotated[float, typer.Option("--input-scatter", help="Departure: relative standard deviation of the actual a0 about the nominal, per record.")] = 0.0,
    encoder_lines: Annotated[int, typer.Option("--encoder-lines", help="Departure: the angle comes from an encoder with this many counts per revolution, read as a counter (0 = exact angle).")] = 0,
    phase_reference_freq: Annotated[Optional[str], typer.Option("--phase-reference-freq", help="Also write a start-up run at this turntable frequency (Hz) as phaseref.csv, for --phase-reference.")] = None,
) -> None:
    """Double centrifuge: angle (deg) and accelerometer output (V), one CSV per point, truth JSON."""
    from senscal.simulate.vibration import simulate_centrifuge

    common = dict(static_sensitivity=static_sensitivity, natural_frequency=natural_frequency, damping=damping,
                  noise=noise, cubic=cubic, encoder_zero_deg=encoder_zero_deg, encoder_lines=encoder_lines)
    recs, truth = simulate_centrifuge(frequencies=parse_floats(freqs, "--freqs"),
                                      accelerations=parse_floats(accelerations, "--accelerations"),
                                      sensitivity_scatter=sensitivity_scatter, input_scatter=input_scatter,
                                      seed=seed, **common)
    extra = ""
    if phase_reference_freq is not None:
        from senscal.io import write_recording

        accs = parse_floats(accelerations, "--accelerations")
        # its own random stream: the response records stay those of --seed
        ref, rt = simulate_centrifuge(frequencies=[phase_reference_freq], accelerations=accs[:1],
                                      seed=None if seed is None else seed + 1_000_003, **common)
        write_recording(ref[0], Path(out) / "phaseref.csv")
        truth["phase_reference_run"] = {"file": "phaseref.csv", **rt["points"][0]}
        extra = " and phaseref.csv"
    paths = write_simulation(recs, truth, out, "centrifuge")
    console.print(f"wrote {len(paths)} recordings{extra} and centrifuge_truth.json to {out}")


@simulate_app.command("shaker")
@units(freqs=ListOf('Hz'), reference_sensitivity='V/(m/s^2)')
def simulate_shaker_cmd(
    out: OutOpt, seed: SeedOpt = None,
    freqs: Annotated[Optional[str], typer.Option("--freqs", help="Frequencies in Hz (default 20..1250 Hz).")] = None,
    reference_sensitivity: Annotated[str, typer.Option("--reference-sensitivity", help="Reference sensitivity, V/(m/s^2).")] = "0.0102",
) -> None:
    """Back-to-back shaker: reference and DUT accelerometers, one CSV per frequency, truth JSON."""
    from senscal.simulate.vibration import simulate_shaker

    kw = {} if freqs is None else {"frequencies": parse_floats(freqs, "--freqs")}
    recs, truth = simulate_shaker(reference_sensitivity=reference_sensitivity, seed=seed, **kw)
    paths = write_simulation(recs, truth, out, "shaker")
    console.print(f"wrote {len(paths)} recordings and shaker_truth.json to {out}")
