"""``senscal shock`` and ``senscal simulate shock`` (ISO 16063-22 comparison, ISO 16063-13 laser primary, issue 28)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import ListOf, units
from senscal.cli.app import app, simulate_app
from senscal.cli.cert_opts import (CalDateOpt, CertIdOpt, CustomerOpt, DccOpt, EnvOpt, ItemOpt, LabOpt, LocationOpt,
                                   ManufacturerOpt, ModelOpt, ReportOpt, RunFileOpt, SensorIdOpt, SignCertOpt,
                                   SignKeyOpt, cert_fields, certify)
from senscal.cli.common import (JsonOpt, StrictOpt, console, emit_warnings, parse_relative, print_json, progress_bar,
                                table)
from senscal.cli.option_groups import READ, REGISTRY, command_params, save_registered, with_options
from senscal.cli.registry_opts import StandardOpt, use_standards
from senscal.jobs._base import with_read_options


@with_read_options
def _shock_options(*, output: str = "out", reference: str | None = None, reference_sensitivity: str | None = None,
                   u_reference: str | None = None, laser: str | None = None, laser_quantity: str | None = None,
                   lowpass_hz: float | None = None, lowpass_order: int = 4, u_other: str | None = None, **_):
    """``ShockOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.shock import ShockOptions

    def rel(v, what):
        return 0.0 if v is None else (float(v) if isinstance(v, (int, float)) else parse_relative(v, what))

    return ShockOptions(output=output, reference=reference, reference_sensitivity=reference_sensitivity,
                        u_reference=rel(u_reference, "--u-reference"), laser=laser, laser_quantity=laser_quantity,
                        lowpass_hz=lowpass_hz, lowpass_order=lowpass_order, u_other=rel(u_other, "--u-other"))


# What `senscal batch` turns the job's option words into (see senscal.jobs).
JOB_OPTIONS = {"shock": _shock_options}


@app.command("shock")
@units(lowpass_hz="Hz")
@with_options(READ, REGISTRY)
def shock_cmd(
    files: Annotated[List[Path], typer.Argument(help="Recordings of half-sine shock pulses: the accelerometer's output and a reference accelerometer or a laser.")],
    output: Annotated[str, typer.Option("--output", help="Channel of the accelerometer under test.")] = "out",
    reference: Annotated[Optional[str], typer.Option("--reference", help="ISO 16063-22: channel of the reference accelerometer.")] = None,
    reference_sensitivity: Annotated[Optional[str], typer.Option("--reference-sensitivity", help="Reference sensitivity: in the reference channel's unit per m/s^2, or with a unit ('0.1 mV/(m/s^2)').")] = None,
    u_reference: Annotated[Optional[str], typer.Option("--u-reference", help="Type B relative standard u of the reference sensitivity, e.g. 0.5%.")] = None,
    laser: Annotated[Optional[str], typer.Option("--laser", help="ISO 16063-13: channel of the laser, velocity (m/s) or displacement (m) by its unit.")] = None,
    laser_quantity: Annotated[Optional[str], typer.Option("--laser-quantity", help="velocity or displacement, when the laser channel's unit is not in the file.")] = None,
    lowpass_hz: Annotated[Optional[str], typer.Option("--lowpass-hz", help="The stated low-pass (zero-phase Butterworth, -6 dB here, Hz) on both channels.")] = None,
    lowpass_order: Annotated[int, typer.Option("--lowpass-order", help="Order of the low-pass.")] = 4,
    u_other: Annotated[Optional[str], typer.Option("--u-other", help="Type B: other relative standard u (transverse motion, mounting ...), e.g. 0.3%.")] = None,
    strict: StrictOpt = False,
    json_out: JsonOpt = False,
    output_unit: Annotated[Optional[str], typer.Option("--output-unit", help="Unit of the accelerometer output for the certificate when the file's header gives none (default V).")] = None,
    report: ReportOpt = None, dcc: DccOpt = None, sensor_id: SensorIdOpt = None, model: ModelOpt = None,
    lab: LabOpt = None, run_file: RunFileOpt = None, customer: CustomerOpt = None, item: ItemOpt = None,
    manufacturer: ManufacturerOpt = None, location: LocationOpt = None, certificate_id: CertIdOpt = None,
    calibration_date: CalDateOpt = None, env: EnvOpt = None, sign_key: SignKeyOpt = None, sign_cert: SignCertOpt = None,
    standard: StandardOpt = None,
    **opts,
) -> None:
    """Shock sensitivity (peak ratio) and transfer function from half-sine pulses (ISO 16063-22, -13)."""
    from senscal.jobs.shock import shock

    used_standards = use_standards(standard, db=opts["db"], date=opts["date"], calibration_date=calibration_date)
    params = command_params(locals(), opts)
    params.pop("files")
    with progress_bar("calibrating", None):
        res = shock(list(files), _shock_options(**params))
    doc = res.to_dict()
    # certificates and the registry through the code every job uses; the budget names ISO 16063-22 / -13
    method = (f"Shock calibration, {res.method}, from half-sine pulses; uncertainty budget with the components of "
              f"ISO {'16063-22' if res.comparison else '16063-13'}")
    unit = res.sensitivity_unit(output_unit)
    cond = {} if report is None and dcc is None else {
        "pulses": len(res.pulses), "records": len(set(res.sources)), "filter": res.filter,
        "output channel": output,
        ("reference channel" if res.comparison else "laser channel"): reference or laser,
        "type B inputs (relative u)": (f"reference sensitivity {u_reference or 0}, other {u_other or 0}"
                                       if res.comparison else f"other {u_other or 0}")}
    cert_warns = certify("shock", res, report=report, dcc=dcc, unit=unit, method=method, conditions=cond,
                         files=[str(f) for f in files], warnings=res.warnings, **cert_fields(params))
    doc["warnings"] = [*doc.get("warnings", []), *cert_warns]
    if report is not None:
        doc["report"] = str(report)
    save_registered(res, opts, method=method, input_files=files, certificate=report, standards=used_standards)
    if json_out:
        print_json(doc)
        emit_warnings([*res.warnings, *cert_warns], strict)
        return
    rows = [[p["file"], str(p["index"]), f"{p['duration_ms']:.3g}", f"{p['peak_acceleration']:.4g}", p["sensitivity"],
             2 * p["u_sensitivity"]] for p in doc["pulses"]]
    console.print(table(f"Shock calibration ({doc['method']}; filter: {doc['filter']}); U at k=2",
                        ["file", "pulse", "T / ms", "peak / m/s^2", f"S / {doc['sensitivity_unit']}", "U(S)"], rows))
    if report is not None:
        console.print(f"certificate written to {report}")
    emit_warnings([*res.warnings, *cert_warns], strict)


@simulate_app.command("shock")
@units(durations_ms=ListOf("ms"), peak="m/s^2", fs="Hz", sensitivity="V/(m/s^2)", reference_sensitivity="V/(m/s^2)",
       resonance_hz="Hz")
def simulate_shock_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    durations_ms: Annotated[str, typer.Option("--durations-ms", help="Half-sine durations, ms, comma separated (one record each).")] = "0.1,1,10",
    peak: Annotated[str, typer.Option("--peak", help="Peak acceleration, m/s^2.")] = "1000",
    pulses: Annotated[int, typer.Option("--pulses", help="Pulses per record (each 30 % / n lower than the one before).")] = 1,
    fs: Annotated[Optional[str], typer.Option("--fs", help="Sample rate, Hz (default 200 samples a pulse, at least 100 kS/s).")] = None,
    mode: Annotated[str, typer.Option("--mode", help="comparison (reference accelerometer) or primary (laser).")] = "comparison",
    laser: Annotated[str, typer.Option("--laser", help="primary: velocity or displacement.")] = "velocity",
    sensitivity: Annotated[str, typer.Option("--sensitivity", help="Accelerometer sensitivity, V per m/s^2.")] = "1e-4",
    reference_sensitivity: Annotated[str, typer.Option("--reference-sensitivity", help="Stated reference sensitivity, V per m/s^2.")] = "1e-4",
    u_reference: Annotated[float, typer.Option("--u-reference", help="Relative standard u of the reference sensitivity; its true value is drawn from it.")] = 0.0,
    noise: Annotated[float, typer.Option("--noise", help="Output and reference noise relative to their peak.")] = 1e-3,
    noise_ar1: Annotated[float, typer.Option("--noise-ar1", help="AR(1) coefficient of the noise (coloured).")] = 0.0,
    laser_noise: Annotated[Optional[float], typer.Option("--laser-noise", help="Laser noise, m/s or m (default 1e-3 of the velocity change, or 1 nm).")] = None,
    resonance_hz: Annotated[Optional[str], typer.Option("--resonance-hz", help="The mounted sensor's resonance (ringing), Hz.")] = None,
    resonance_q: Annotated[float, typer.Option("--resonance-q", help="Its quality factor.")] = 30.0,
    zero_shift: Annotated[float, typer.Option("--zero-shift", help="Zero shift of the output across a pulse, relative to its peak.")] = 0.0,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
) -> None:
    """Half-sine shock pulses on an accelerometer with a reference or a laser: shock_NN.csv + truth."""
    from senscal.cli.common import parse_floats
    from senscal.errors import InputError
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.shock import simulate_shock

    ds = parse_floats(durations_ms, "--durations-ms")
    if not ds or any(not d > 0 for d in ds) or not peak > 0 or pulses < 1 or (fs is not None and not fs > 0):
        raise InputError("--durations-ms, --peak and --fs must be positive and --pulses at least 1")
    if mode not in ("comparison", "primary") or laser not in ("velocity", "displacement"):
        raise InputError("--mode is comparison or primary, --laser velocity or displacement")
    if not 0 <= noise_ar1 < 1 or noise < 0 or u_reference < 0:
        raise InputError("--noise-ar1 must lie in [0, 1), --noise and --u-reference must not be negative")
    import math

    # NaN passed the checks above into the channels; a negative laser noise or resonance was used as given
    for opt, v, low in (("--noise", noise, 0.0), ("--u-reference", u_reference, 0.0), ("--zero-shift", zero_shift, None),
                        ("--laser-noise", laser_noise, 0.0), ("--resonance-hz", resonance_hz, "pos"),
                        ("--resonance-q", resonance_q, "pos"), ("--sensitivity", sensitivity, "nonzero"),
                        ("--reference-sensitivity", reference_sensitivity, "nonzero")):
        if v is None:
            continue
        bad = (not math.isfinite(v) or (low == 0.0 and v < 0) or (low == "pos" and not v > 0)
               or (low == "nonzero" and v == 0))
        if bad:
            need = {0.0: " of 0 or more", "pos": " above 0", "nonzero": " other than 0"}.get(low, "")
            raise InputError(f"{opt} must be a finite number{need}, got {v!r}")
    total = sum(max(100_000.0, 200.0 / (d * 1e-3)) if fs is None else fs for d in ds) * pulses * max(ds) * 1e-3 * 12
    if total > 5e7:
        raise InputError("the records would exceed 50 million samples: fewer pulses, shorter pulses or a lower --fs")
    recs, pts = [], []
    for i, d in enumerate(ds):
        rec, tr = simulate_shock(duration_ms=d, peak=peak, pulses=pulses, fs=fs, mode=mode, laser=laser,
                                 sensitivity=sensitivity, reference_sensitivity=reference_sensitivity,
                                 u_reference_rel=u_reference, reference_noise_rel=noise, output_noise_rel=noise,
                                 laser_noise=laser_noise, noise_ar1=noise_ar1, resonance_hz=resonance_hz,
                                 resonance_q=resonance_q, zero_shift_rel=zero_shift,
                                 seed=None if seed is None else seed + i)
        recs.append(rec)
        pts.append(tr)
    # units in the header: the laser channel's unit (m/s or m) tells the job what it measures
    for i, (rec, tr) in enumerate(zip(recs, pts), start=1):
        tr["file"] = write_recording(rec, out / f"shock_{i:02d}.csv", units_in_header=True).name
    write_truth({"points": pts}, out / "shock_truth.json")
    console.print(f"wrote {len(recs)} recordings and shock_truth.json to {out}")
