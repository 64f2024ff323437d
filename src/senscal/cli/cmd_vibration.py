"""``senscal velocity``, ``senscal response``, ``senscal linearity`` and the
``hydraulic``, ``centrifuge``, ``shaker`` simulators."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import List, Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app, simulate_app
from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt, quoted,
                                       save_if_requested)
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings, err_console,
                                load, parse_floats, parse_relative, print_json, table, track)
from senscal.cli.common import TimeUnitOpt, time_checked
from senscal.errors import InputError

FilesArg = Annotated[List[Path], typer.Argument(help="Recording files, one per frequency point / input level.")]
FreqOpt = Annotated[Optional[List[str]], typer.Option(
    "--freq", help="Known frequency in Hz: one for all files or one per file (repeat or comma-separate); estimated when omitted.")]
ReportOpt = Annotated[Optional[Path], typer.Option("--report", help="Write an HTML calibration certificate to this file.")]
PlotOpt = Annotated[Optional[Path], typer.Option("--plot", help="Write the key plot to this PNG file.")]
SensorIdOpt = Annotated[str, typer.Option("--sensor-id", help="Identification of the item calibrated (certificate).")]
ModelOpt = Annotated[str, typer.Option("--model", help="Sensor model / manufacturer (certificate).")]
ConditionOpt = Annotated[Optional[List[str]], typer.Option(
    "--condition", help="Calibration condition for the certificate, KEY=VALUE (repeatable), e.g. 'temperature=23.1 C'.")]
UnitOpt = Annotated[Optional[str], typer.Option("--output-unit", help="Unit of the sensor output (default: from the file, else V).")]


def _freqs(values: list[str] | None, n: int) -> list[float | None]:
    if not values:
        return [None] * n
    fl = [f for v in values for f in parse_floats(v, "--freq")]
    if any(not (f > 0 and math.isfinite(f)) for f in fl):
        raise InputError("--freq values must be positive numbers of Hz")
    if len(fl) == 1:
        return fl * n
    if len(fl) != n:
        raise InputError(f"give one --freq for all files or one per file: got {len(fl)} frequencies for {n} files")
    return fl


def _distinct(files) -> None:
    """Refuse a recording given twice: it would count as two independent points."""
    seen: dict[str, Path] = {}
    for f in files:
        key = os.path.normcase(os.path.realpath(f))
        if key in seen:
            raise InputError(f"{f} is given more than once (also as {seen[key]}); each recording is one point")
        seen[key] = f


def _rel(text: str | None, what: str) -> float:
    return 0.0 if text is None else parse_relative(text, what)


def _unit(rec, name: str, given: str | None) -> str:
    return given or (rec.units.get(name) if rec.units.get(name) else "V")


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


def _response_quantities(doc: dict) -> list:
    """Registry quantities of a response: per frequency point, with their standard uncertainties."""
    from senscal.registry import Quantity

    qs = []
    for p in doc["points"]:
        tag = f"{p['frequency_hz']:.4g}Hz"
        qs.append(Quantity(f"sensitivity@{tag}", p["sensitivity"], p["u_sensitivity"], doc["unit"]))
        if p.get("normalized_sensitivity") is not None:
            qs.append(Quantity(f"normalized_sensitivity@{tag}", p["normalized_sensitivity"],
                               p["u_normalized_sensitivity"], "1"))
        if p.get("phase_delay_deg") is not None:
            qs.append(Quantity(f"phase_delay@{tag}", p["phase_delay_deg"], p["u_phase_delay_deg"], "deg"))
    return qs


def _k2(u):
    return None if u is None else 2.0 * u


def _expanded(budget):
    """Expanded uncertainty of a budget (its own k), None without one."""
    return None if budget is None else budget.expanded


def _u2(u) -> str:
    """An uncertainty for a table: 2 significant digits (GUM 7.2.6)."""
    return "-" if u is None else f"{u:.2g}"


def _deg(x):
    return None if x is None else math.degrees(x)


# ---------------------------------------------------------------------------
# velocity
# ---------------------------------------------------------------------------

@app.command("velocity")
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
    json_out: JsonOpt = False, report: ReportOpt = None, plot: PlotOpt = None,
    sensor_id: SensorIdOpt = "not stated", model: ModelOpt = "not stated", condition: ConditionOpt = None,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, strict: StrictOpt = False,
) -> None:
    """Velocity-sensor sensitivity S = A_s / (w A_p) against a position reference, per file and mean."""
    from senscal.vibration import velocity_calibration, velocity_point

    ub = _rel(u_position, "--u-position")
    _distinct(files)
    freqs = _freqs(freq, len(files))
    points, unit = [], None
    for path, f in zip(track(files, "fitting"), freqs):
        rec = load(path, time_column=time_column, fs=fs, names=names, channels=[position, velocity], time_unit=time_unit)
        unit = unit or _unit(rec, velocity, output_unit) + "/(m/s)"
        points.append(time_checked(rec, "velocity", velocity_point(
            rec[position], rec[velocity], rec.time, freq=f, drift=drift, harmonics=harmonics, u_position=ub,
            source=str(path), unit=unit), channel=position, known_hz=f))
    cal = velocity_calibration(points, u_position=ub, unit=unit)
    doc = {
        "points": [{"file": p.source, "frequency_hz": p.frequency, "u_frequency_hz": p.u_frequency,
                    "sensitivity": p.sensitivity, "u_sensitivity": p.u_sensitivity, "U_sensitivity": p.budget.expanded,
                    "phase_deg": math.degrees(p.phase), "u_phase_deg": math.degrees(p.u_phase),
                    "position_amplitude_m": p.position_amplitude, "output_amplitude": p.output_amplitude,
                    "snr_db": p.snr_db, "budget": p.budget} for p in cal.points],
        "sensitivity": cal.sensitivity, "sensitivity_std": cal.sensitivity_std, "u_sensitivity": cal.u_sensitivity,
        "U_sensitivity": cal.budget.expanded, "coverage_factor": cal.budget.coverage_factor,
        "effective_dof": cal.budget.effective_dof, "birge_ratio": cal.birge_ratio, "chi2_p": cal.chi2_p,
        "unit": unit, "budget": cal.budget, "warnings": list(cal.warnings),
    }
    if report is not None:
        from senscal.report.certificate import write_certificate

        write_certificate(report, "velocity", cal, sensor_id=sensor_id, model=model, unit=unit, files=[str(f) for f in files],
                          method="Sinusoidal excitation against a position reference; least-squares sine fits of "
                                 "position and sensor output at one shared frequency; S = A_s / (w A_p) (Yang et al. 2014).",
                          conditions={"frequency points": len(points),
                                      "frequencies (Hz)": ", ".join(f"{p.frequency:.4g}" for p in cal.points),
                                      "offset drift fitted": "yes" if drift else "no",
                                      "position reference u (type B)": f"{100 * ub:g} %", **_conditions(condition)})
        doc["report"] = str(report)
    save_if_requested(doc, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date, operator=operator,
                      job="velocity", method="sine fit against a position reference (Yang et al. 2014)",
                      quantities=lambda: [quoted(doc, "sensitivity", "sensitivity", "u_sensitivity", unit)],
                      input_files=files, certificate=report, conditions=_conditions(condition))
    if plot is not None:
        from senscal.report.certificate import velocity_figure

        _save_plot(velocity_figure(cal), plot)
    if json_out:
        print_json(doc)
    else:
        rows = [[Path(p.source).stem, p.frequency, p.sensitivity, _u2(p.budget.expanded), math.degrees(p.phase),
                 _u2(2 * math.degrees(p.u_phase)), f"{p.snr_db:.1f}"] for p in cal.points]
        console.print(table(f"Velocity-sensor sensitivity ({unit}; U = expanded, k=2)",
                            ["file", "f (Hz)", "S", "U S", "phase vs v (deg)", "U phase", "SNR dB"], rows))
        console.print(f"mean S = {cal.sensitivity:.6g} {unit}, U = {cal.budget.expanded:.2g} "
                      f"(k={cal.budget.coverage_factor:.3g}), std over points = {cal.sensitivity_std:.2g}")
        if report is not None:
            console.print(f"certificate written to {report}")
    emit_warnings(cal.warnings, strict)


# ---------------------------------------------------------------------------
# response
# ---------------------------------------------------------------------------

def _response_points(files, freqs, *, output, input_amplitudes, reference, reference_sensitivity, angle, static_sensitivity,
                     initial_phase_deg, u_input, u_reference, u_static, drift, harmonics, time_column, fs, names,
                     output_unit, u_initial_phase_deg=0.0, time_unit=None):
    from senscal.vibration import response_point

    _distinct(files)
    chans = [output] + ([reference] if reference else []) + ([angle] if angle else [])
    points, unit = [], None
    for path, f, a in zip(track(files, "fitting"), freqs, input_amplitudes):
        rec = load(path, time_column=time_column, fs=fs, names=names, channels=chans, time_unit=time_unit)
        unit = unit or _unit(rec, output, output_unit) + "/(m/s^2)"
        points.append(time_checked(rec, "response", response_point(
            rec[output], rec.time, input_amplitude=a, reference=rec[reference] if reference else None,
            reference_sensitivity=reference_sensitivity, angle_deg=rec[angle] if angle else None, freq=f,
            static_sensitivity=static_sensitivity,
            initial_phase=None if initial_phase_deg is None else math.radians(initial_phase_deg),
            u_input_phase=math.radians(u_initial_phase_deg),
            u_input=u_input, u_reference_sensitivity=u_reference, u_static_sensitivity=u_static, drift=drift,
            harmonics=harmonics, source=str(path), unit=unit), channel=output, known_hz=f))
    return points, unit


def _check_input(input_amplitude, reference, reference_sensitivity, angle):
    if (input_amplitude is None) == (reference is None):
        raise InputError("give either --input-amplitude A (m/s^2) or --reference NAME with --reference-sensitivity S")
    if reference is not None and reference_sensitivity is None:
        raise InputError("--reference needs --reference-sensitivity (reference output unit per m/s^2)")
    if reference is not None and angle is not None:
        raise InputError("--angle applies to a known input (double centrifuge), not to a back-to-back comparison")


@app.command("response")
def response_cmd(
    files: FilesArg,
    output: Annotated[str, typer.Option("--output", help="Accelerometer output channel.")],
    input_amplitude: Annotated[Optional[float], typer.Option("--input-amplitude", help="Known peak input acceleration, m/s^2.")] = None,
    reference: Annotated[Optional[str], typer.Option("--reference", help="Reference accelerometer channel (back-to-back).")] = None,
    reference_sensitivity: Annotated[Optional[float], typer.Option("--reference-sensitivity", help="Reference sensitivity, its unit per m/s^2.")] = None,
    angle: Annotated[Optional[str], typer.Option("--angle", help="Turntable angle channel (deg): cut to whole revolutions, input phase from it.")] = None,
    static_sensitivity: Annotated[Optional[float], typer.Option("--static-sensitivity", help="Static sensitivity S0 for S_i/S0.")] = None,
    initial_phase_deg: Annotated[Optional[float], typer.Option("--initial-phase-deg", help="Input phase phi_0 (deg, sine convention) from a start-up test: at t=0, or at encoder angle 0 with --angle (90 when encoder zero lies along the field).")] = None,
    u_initial_phase_deg: Annotated[float, typer.Option("--u-initial-phase-deg", help="Standard uncertainty of --initial-phase-deg, deg (type B in the phase-delay budget).")] = 0.0,
    phase_reference: Annotated[Optional[Path], typer.Option("--phase-reference", help="Start-up / lowest-frequency double-centrifuge run (same channels) that gives phi_0 (needs --angle).")] = None,
    freq: FreqOpt = None,
    u_input: Annotated[Optional[str], typer.Option("--u-input", help="Type B standard uncertainty of the input amplitude, e.g. 0.2%.")] = None,
    u_reference: Annotated[Optional[str], typer.Option("--u-reference", help="Type B standard uncertainty of the reference sensitivity, e.g. 0.5%.")] = None,
    u_static: Annotated[Optional[str], typer.Option("--u-static-sensitivity", help="Type B standard uncertainty of S0, e.g. 0.05%.")] = None,
    drift: Annotated[bool, typer.Option("--drift/--no-drift", help="Fit a linear offset drift.")] = False,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Harmonics fitted with the fundamental (3 for a nonlinear sensor or a distorted excitation).")] = 1,
    output_unit: UnitOpt = None,
    time_column: TimeColumnOpt = "t", fs: FsOpt = None, names: NamesOpt = None, time_unit: TimeUnitOpt = None,
    json_out: JsonOpt = False, report: ReportOpt = None, plot: PlotOpt = None,
    sensor_id: SensorIdOpt = "not stated", model: ModelOpt = "not stated", condition: ConditionOpt = None,
    save_response_to: Annotated[Optional[Path], typer.Option("--save-response", help="Save the response (JSON with type and version) for later use.")] = None,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, strict: StrictOpt = False,
) -> None:
    """Accelerometer frequency response: sensitivity, S_i/S0, phase delay with GUM budgets."""
    from senscal.vibration import combine_repeats, frequency_response

    _check_input(input_amplitude, reference, reference_sensitivity, angle)
    if initial_phase_deg is not None and reference is not None:
        raise InputError("--initial-phase-deg is for a known input; with --reference the input phase is the reference channel's")
    if initial_phase_deg is not None and not math.isfinite(initial_phase_deg):
        raise InputError(f"--initial-phase-deg must be a finite number of degrees, got {initial_phase_deg!r}")
    if not (math.isfinite(u_initial_phase_deg) and 0 <= u_initial_phase_deg < 180):
        raise InputError(f"--u-initial-phase-deg must be a standard uncertainty in [0, 180) deg, got {u_initial_phase_deg!r}")
    if u_initial_phase_deg > 0 and initial_phase_deg is None:
        raise InputError("--u-initial-phase-deg is the uncertainty of --initial-phase-deg: give that too")
    if phase_reference is not None:
        if angle is None:
            raise InputError("--phase-reference is a double-centrifuge run fitted against the turntable angle: give --angle")
        if initial_phase_deg is not None:
            raise InputError("give either --initial-phase-deg (phi_0 entered) or --phase-reference FILE (phi_0 measured), not both")
    points, unit = _response_points(
        files, _freqs(freq, len(files)), output=output, input_amplitudes=[input_amplitude] * len(files),
        reference=reference, reference_sensitivity=reference_sensitivity, angle=angle,
        static_sensitivity=static_sensitivity, initial_phase_deg=initial_phase_deg,
        u_input=_rel(u_input, "--u-input"), u_reference=_rel(u_reference, "--u-reference"),
        u_static=_rel(u_static, "--u-static-sensitivity"), drift=drift, harmonics=harmonics, time_column=time_column, fs=fs, names=names,
        output_unit=output_unit, u_initial_phase_deg=u_initial_phase_deg, time_unit=time_unit)
    phase_ref_text = None
    if phase_reference is not None:
        from senscal.vibration import apply_phase_reference, phase_reference_run

        rec = load(phase_reference, time_column=time_column, fs=fs, names=names, channels=[output, angle],
                   time_unit=time_unit)
        # The reference may be one of the response records (the lowest-frequency run): same label, one fit.
        same = [str(f) for f in files if os.path.realpath(f) == os.path.realpath(phase_reference)]
        ref = phase_reference_run(rec[output], rec.time, rec[angle], harmonics=harmonics, drift=drift,
                                  source=same[0] if same else str(phase_reference))
        points = list(apply_phase_reference(points, ref))
        phase_ref_text = (f"phi_0 = {math.degrees(ref.phase):.4f} deg at encoder zero from the {ref.frequency:.4g} Hz "
                          f"run {phase_reference} (its own delay extrapolated from the points above it, odd cubic in frequency)")
    elif initial_phase_deg is not None:
        phase_ref_text = (f"phi_0 = {initial_phase_deg:g} deg entered (u = {u_initial_phase_deg:g} deg)"
                          + (" at encoder zero" if angle else " at t = 0"))
    resp = frequency_response(points, unit=unit, static_sensitivity=static_sensitivity, phase_reference=phase_ref_text)
    doc = {
        "points": [{"file": p.source, "frequency_hz": p.frequency, "u_frequency_hz": p.u_frequency,
                    "input_amplitude": p.input_amplitude, "output_amplitude": p.output_amplitude,
                    "u_output_amplitude": p.u_output_amplitude,
                    "sensitivity": p.sensitivity, "u_sensitivity": p.u_sensitivity,
                    "U_sensitivity": p.sensitivity_budget.expanded,
                    "normalized_sensitivity": p.normalized_sensitivity, "u_normalized_sensitivity": p.u_normalized_sensitivity,
                    "U_normalized_sensitivity": _expanded(p.normalized_budget),
                    "phase_deg": math.degrees(p.phase), "u_phase_deg": math.degrees(p.u_phase),
                    "phase_delay_deg": _deg(p.phase_delay), "u_phase_delay_deg": _deg(p.u_phase_delay),
                    "U_phase_delay_deg": _deg(_expanded(p.phase_delay_budget)), "phase_reference": p.phase_reference,
                    "warnings": list(p.warnings),
                    "revolutions": p.sync.revolutions if p.sync else None, "n_samples": p.n_samples,
                    "snr_db": p.snr_db, "method": p.method,
                    "sensitivity_budget": p.sensitivity_budget, "normalized_budget": p.normalized_budget,
                    "phase_delay_budget": p.phase_delay_budget} for p in resp.points],
        "unit": unit, "static_sensitivity": static_sensitivity,
        "coverage_factor": max(b.coverage_factor for p in resp.points
                               for b in (p.sensitivity_budget, p.normalized_budget, p.phase_delay_budget) if b is not None),
        "method": resp.points[0].method, "phase_reference": resp.phase_reference,
    }
    warns = list(resp.warnings)
    reps = combine_repeats(resp.points)
    if len(reps) < len(resp.points):
        doc["repeats"] = [{"frequency_hz": g.frequency, "n_repeats": g.n_repeats, "files": list(g.sources),
                           "sensitivity": g.sensitivity, "u_sensitivity": g.u_sensitivity,
                           "U_sensitivity": g.sensitivity_budget.expanded,
                           "sensitivity_std": g.sensitivity_std, "normalized_sensitivity": g.normalized_sensitivity,
                           "u_normalized_sensitivity": g.u_normalized_sensitivity,
                           "U_normalized_sensitivity": _expanded(g.normalized_budget),
                           "phase_delay_deg": _deg(g.phase_delay), "u_phase_delay_deg": _deg(g.u_phase_delay),
                           "U_phase_delay_deg": _deg(_expanded(g.phase_delay_budget)),
                           "coverage_factor": g.sensitivity_budget.coverage_factor,
                           "sensitivity_budget": g.sensitivity_budget, "normalized_budget": g.normalized_budget,
                           "phase_delay_budget": g.phase_delay_budget, "warnings": list(g.warnings)} for g in reps]
        from senscal.vibration.budget import unique_warnings

        warns = list(unique_warnings(warns, *(g.warnings for g in reps)))
    doc["warnings"] = warns
    if report is not None:
        from senscal.report.certificate import write_certificate

        cond = {"frequency points": len(points), "method": resp.points[0].method}
        if input_amplitude is not None:
            cond["peak input acceleration (m/s^2)"] = input_amplitude
            cond["input amplitude u (type B)"] = f"{100 * _rel(u_input, '--u-input'):g} %"
        else:
            cond["reference sensitivity"] = f"{reference_sensitivity:g} (u = {100 * _rel(u_reference, '--u-reference'):g} %)"
        if static_sensitivity is not None:
            cond["static sensitivity S0"] = f"{static_sensitivity:g} {unit} (u = {100 * _rel(u_static, '--u-static-sensitivity'):g} %)"
        if angle:
            cond["turntable angle synchronisation"] = "records cut to whole revolutions from a 360 deg crossing"
        cond["input phase phi_0"] = resp.phase_reference
        cond.update(_conditions(condition))
        meth = ("Double-centrifuge / known sinusoidal input; least-squares sine fit of the output "
                "(against the turntable angle when synchronised; Qin, seed 003)" if input_amplitude is not None
                else "Back-to-back comparison with a reference accelerometer (ISO 16063-21); sine fits at one shared frequency")
        write_certificate(report, "response", resp, sensor_id=sensor_id, model=model, unit=unit, method=meth,
                          conditions=cond, files=[str(f) for f in files]
                          + ([f"{phase_reference} (phase reference)"] if phase_reference is not None else []),
                          warnings=warns)
        doc["report"] = str(report)
    if save_response_to is not None:
        from senscal.vibration import save_response

        doc["saved"] = str(save_response(resp, save_response_to))
    save_if_requested(doc, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date, operator=operator,
                      job="response", method=doc["method"], quantities=lambda: _response_quantities(doc),
                      input_files=files, certificate=report, conditions=_conditions(condition))
    if plot is not None:
        from senscal.report.certificate import response_figure

        _save_plot(response_figure(resp), plot)
    if json_out:
        print_json(doc)
    else:
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
        if report is not None:
            console.print(f"certificate written to {report}")
    emit_warnings(warns, strict)


# ---------------------------------------------------------------------------
# linearity
# ---------------------------------------------------------------------------

@app.command("linearity")
def linearity_cmd(
    files: FilesArg,
    output: Annotated[str, typer.Option("--output", help="Accelerometer output channel.")],
    input_amplitudes: Annotated[str, typer.Option("--input-amplitudes", help="Peak input of each file, m/s^2, comma separated.")],
    freq: Annotated[Optional[float], typer.Option("--freq", help="Known frequency in Hz (estimated per file when omitted).")] = None,
    angle: Annotated[Optional[str], typer.Option("--angle", help="Turntable angle channel (deg): fit against the angle.")] = None,
    drift: Annotated[bool, typer.Option("--drift/--no-drift", help="Fit a linear offset drift.")] = False,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Harmonics fitted with the fundamental (3 for a nonlinear sensor or a distorted excitation).")] = 1,
    u_input: Annotated[Optional[str], typer.Option("--u-input", help="Standard uncertainty of each input level, random from level to level (e.g. main-arm speed set anew), e.g. 0.05%.")] = None,
    output_unit: UnitOpt = None,
    time_column: TimeColumnOpt = "t", fs: FsOpt = None, names: NamesOpt = None, time_unit: TimeUnitOpt = None,
    json_out: JsonOpt = False, report: ReportOpt = None, plot: PlotOpt = None,
    sensor_id: SensorIdOpt = "not stated", model: ModelOpt = "not stated", condition: ConditionOpt = None,
    save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None, create_sensor: CreateSensorOpt = None,
    date: DateOpt = None, operator: OperatorOpt = None, strict: StrictOpt = False,
) -> None:
    """Amplitude linearity at a fixed frequency: best straight line, deviations, linearity in % of full scale."""
    from senscal.vibration import amplitude_linearity

    amps = parse_floats(input_amplitudes, "--input-amplitudes")
    if len(amps) != len(files):
        raise InputError(f"give one input amplitude per file: {len(amps)} amplitudes for {len(files)} files")
    if any(not a > 0 for a in amps):
        raise InputError("--input-amplitudes must be positive (m/s^2)")
    points, unit = _response_points(
        files, [freq] * len(files), output=output, input_amplitudes=amps, reference=None, reference_sensitivity=None,
        angle=angle, static_sensitivity=None, initial_phase_deg=None, u_input=0.0, u_reference=0.0, u_static=0.0,
        drift=drift, harmonics=harmonics, time_column=time_column, fs=fs, names=names, output_unit=output_unit,
        time_unit=time_unit)
    u_in = _rel(u_input, "--u-input")
    lin = amplitude_linearity(amps, [p.output_amplitude for p in points], [p.u_output_amplitude for p in points],
                              [p.source for p in points], u_input=u_in)
    warns = list(lin.warnings) + [w for w in dict.fromkeys(w for p in points for w in p.warnings)
                                  if not w.startswith("phase-reference-unknown:")]
    out_unit = unit.split("/(m/s^2)")[0]
    doc = {"points": [{"file": p.source, "input_amplitude": p.input_amplitude, "output_amplitude": p.output_amplitude,
                       "u_output_amplitude": p.u_output_amplitude, "deviation": p.deviation,
                       "deviation_percent": p.deviation_percent, "frequency_hz": rp.frequency}
                      for p, rp in zip(lin.points, points)],
           "slope": lin.slope, "u_slope": lin.u_slope, "U_slope": lin.coverage_factor * lin.u_slope,
           "intercept": lin.intercept, "u_intercept": lin.u_intercept,
           "U_intercept": lin.coverage_factor * lin.u_intercept, "coverage_factor": lin.coverage_factor,
           "dof": lin.dof, "birge_ratio": lin.birge_ratio, "chi2_p": lin.chi2_p,
           "linearity_percent": lin.linearity_percent, "u_linearity_percent": lin.u_linearity_percent,
           "U_linearity_percent": 2 * lin.u_linearity_percent, "linearity_resolved": lin.linearity_resolved,
           "linearity_bound_percent": lin.linearity_bound_percent,
           "full_scale_output": lin.full_scale_output, "unit": unit, "output_unit": out_unit, "warnings": warns}
    if report is not None:
        from senscal.report.certificate import write_certificate

        write_certificate(report, "linearity", lin, sensor_id=sensor_id, model=model, unit=unit,
                          files=[str(f) for f in files],
                          method="Fixed frequency, input amplitude stepped; least-squares sine fit of each record; "
                                 "best straight line through (input, output amplitude) (Qin, seed 003)",
                          conditions={"input levels": len(files),
                                      "frequency (Hz)": f"{sum(p.frequency for p in points) / len(points):.4g}",
                                      "input range (m/s^2)": f"{min(amps):g} .. {max(amps):g}",
                                      "input level u (random per level)": f"{100 * u_in:g} %",
                                      "angle synchronisation": "yes" if angle else "no", **_conditions(condition)},
                          warnings=warns)
        doc["report"] = str(report)
    save_if_requested(doc, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date, operator=operator,
                      job="linearity", method="amplitude linearity, best straight line (Qin, seed 003)",
                      quantities=lambda: [quoted(doc, "linearity_slope", "slope", "u_slope", unit),
                                          quoted(doc, "linearity_percent", "linearity_percent", "u_linearity_percent", "%")],
                      input_files=files, certificate=report, conditions=_conditions(condition))
    if plot is not None:
        from senscal.report.certificate import linearity_figure

        _save_plot(linearity_figure(lin, f"({out_unit})"), plot)
    if json_out:
        print_json(doc)
    else:
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
        if report is not None:
            console.print(f"certificate written to {report}")
    emit_warnings(warns, strict)


# ---------------------------------------------------------------------------
# simulators
# ---------------------------------------------------------------------------

OutOpt = Annotated[Path, typer.Option("--out", help="Output folder.")]
SeedOpt = Annotated[Optional[int], typer.Option("--seed", help="Random seed.")]


def write_simulation(recs, truth, out: Path, stem: str) -> list[Path]:
    """Write recordings ``<stem>_NN.csv`` and ``<stem>_truth.json`` (file names added to the truth points)."""
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth

    paths = []
    for i, (rec, pt) in enumerate(zip(recs, truth["points"]), start=1):
        p = write_recording(rec, Path(out) / f"{stem}_{i:02d}.csv")
        pt["file"] = p.name
        paths.append(p)
    write_truth(truth, Path(out) / f"{stem}_truth.json")
    return paths


def _opt_floats(text: str | None, what: str):
    return None if text is None else parse_floats(text, what)


@simulate_app.command("hydraulic")
def simulate_hydraulic_cmd(
    out: OutOpt, seed: SeedOpt = None,
    freqs: Annotated[Optional[str], typer.Option("--freqs", help="Frequencies in Hz, comma separated (default 1..5.5 Hz, 10 points).")] = None,
    sensitivity: Annotated[float, typer.Option("--sensitivity", help="Velocity-sensor sensitivity, V/(m/s).")] = 0.1368,
    noise: Annotated[float, typer.Option("--noise", help="Velocity-sensor noise, V.")] = 3e-4,
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
def simulate_centrifuge_cmd(
    out: OutOpt, seed: SeedOpt = None,
    freqs: Annotated[str, typer.Option("--freqs", help="Turntable frequencies, Hz.")] = "0.1,1,5,10",
    accelerations: Annotated[str, typer.Option("--accelerations", help="Peak accelerations a0, m/s^2 (one record per frequency and a0).")] = "100",
    static_sensitivity: Annotated[float, typer.Option("--static-sensitivity", help="S0, V/(m/s^2).")] = 0.05,
    natural_frequency: Annotated[float, typer.Option("--natural-frequency", help="Accelerometer natural frequency, Hz.")] = 40.0,
    damping: Annotated[float, typer.Option("--damping", help="Damping ratio.")] = 0.6,
    noise: Annotated[float, typer.Option("--noise", help="Output noise, V.")] = 2e-3,
    cubic: Annotated[float, typer.Option("--cubic", help="Cubic nonlinearity, 1/(m/s^2)^2.")] = 0.0,
    encoder_zero_deg: Annotated[float, typer.Option("--encoder-zero-deg", help="Departure: encoder zero this many degrees off the field direction (phi_0 = 90 + offset).")] = 0.0,
    sensitivity_scatter: Annotated[float, typer.Option("--sensitivity-scatter", help="Departure: relative standard deviation of S0 from record to record (remounting).")] = 0.0,
    input_scatter: Annotated[float, typer.Option("--input-scatter", help="Departure: relative standard deviation of the actual a0 about the nominal, per record.")] = 0.0,
    phase_reference_freq: Annotated[Optional[float], typer.Option("--phase-reference-freq", help="Also write a start-up run at this turntable frequency (Hz) as phaseref.csv, for --phase-reference.")] = None,
) -> None:
    """Double centrifuge: angle (deg) and accelerometer output (V), one CSV per point, truth JSON."""
    from senscal.simulate.vibration import simulate_centrifuge

    common = dict(static_sensitivity=static_sensitivity, natural_frequency=natural_frequency, damping=damping,
                  noise=noise, cubic=cubic, encoder_zero_deg=encoder_zero_deg)
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
def simulate_shaker_cmd(
    out: OutOpt, seed: SeedOpt = None,
    freqs: Annotated[Optional[str], typer.Option("--freqs", help="Frequencies in Hz (default 20..1250 Hz).")] = None,
    reference_sensitivity: Annotated[float, typer.Option("--reference-sensitivity", help="Reference sensitivity, V/(m/s^2).")] = 0.0102,
) -> None:
    """Back-to-back shaker: reference and DUT accelerometers, one CSV per frequency, truth JSON."""
    from senscal.simulate.vibration import simulate_shaker

    kw = {} if freqs is None else {"frequencies": parse_floats(freqs, "--freqs")}
    recs, truth = simulate_shaker(reference_sensitivity=reference_sensitivity, seed=seed, **kw)
    paths = write_simulation(recs, truth, out, "shaker")
    console.print(f"wrote {len(paths)} recordings and shaker_truth.json to {out}")
