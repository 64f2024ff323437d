"""``senscal primary`` and ``senscal simulate interferometer`` (ISO 16063-11 method 3, issue 28)."""

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
from senscal.cli.option_groups import READ, REGISTRY, command_params, save_registered, with_options
from senscal.cli.registry_opts import StandardOpt, use_standards
from senscal.cli.common import JsonOpt, StrictOpt, console, emit_warnings, print_json, progress_bar, table
from senscal.jobs._base import with_read_options


@with_read_options
def _primary_options(*, quadrature: str = "I,Q", output: str = "out", wavelength_nm: float = 632.8,
                     freq: float | None = None, harmonics: int = 3, drift: bool = True, slices: int = 10,
                     u_wavelength_rel: float = 0.0, u_gain_rel: float = 0.0, u_gain_phase_deg: float = 0.0,
                     u_other_rel: float = 0.0, u_other_phase_deg: float = 0.0, sign_check: bool = True,
                     heterodyne: str | None = None, carrier_hz: float | None = None,
                     carrier_channel: str | None = None, carrier_sign: int = 1, **_):
    """``PrimaryOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.cli.common import parse_relative
    from senscal.jobs.primary import PrimaryOptions

    def rel(v, what):  # '0.2%' or a fraction, as --u-other of 'senscal shock'; numbers from batch as they are
        return float(v) if isinstance(v, (int, float)) else parse_relative(str(v), what)

    return PrimaryOptions(quadrature=quadrature, output=output, wavelength_nm=wavelength_nm, freq=freq,
                          harmonics=harmonics, drift=drift, slices=slices,
                          u_wavelength_rel=rel(u_wavelength_rel, "--u-wavelength-rel"),
                          u_gain_rel=rel(u_gain_rel, "--u-gain-rel"), u_gain_phase_deg=u_gain_phase_deg,
                          u_other_rel=rel(u_other_rel, "--u-other-rel"),
                          u_other_phase_deg=u_other_phase_deg, sign_check=sign_check, heterodyne=heterodyne,
                          carrier_hz=carrier_hz, carrier_channel=carrier_channel, carrier_sign=carrier_sign)


# What `senscal batch` turns the job's option words into (see senscal.jobs).
JOB_OPTIONS = {"primary": _primary_options}


@app.command("primary")
@units(wavelength_nm='nm', freq='Hz', carrier_hz='Hz')
@with_options(READ, REGISTRY)
def primary_cmd(
    files: Annotated[List[Path], typer.Argument(help="Recordings, one per frequency, with the interferometer's I and Q outputs and the accelerometer's output.")],
    quadrature: Annotated[str, typer.Option("--quadrature", help="Channels of the quadrature outputs, I,Q.")] = "I,Q",
    output: Annotated[str, typer.Option("--output", help="Channel of the accelerometer's output.")] = "out",
    wavelength_nm: Annotated[str, typer.Option("--wavelength-nm", help="Laser wavelength in nm (632.8: HeNe).")] = "632.8",
    freq: Annotated[Optional[str], typer.Option("--freq", help="Excitation frequency, Hz (default: estimated per file).")] = None,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Harmonics fitted with the fundamental (exciter distortion).")] = 3,
    drift: Annotated[bool, typer.Option("--drift/--no-drift", help="Fit a linear drift of the offsets.")] = True,
    slices: Annotated[int, typer.Option("--slices", help="Per-period (sliced) fits for the type A term of what the model lacks.")] = 10,
    u_wavelength_rel: Annotated[str, typer.Option("--u-wavelength-rel", help="Type B: relative standard u of the wavelength (a fraction or e.g. 0.001%).")] = "0",
    u_gain_rel: Annotated[str, typer.Option("--u-gain-rel", help="Type B: relative standard u of the output voltage measurement (a fraction or e.g. 0.1%).")] = "0",
    u_gain_phase_deg: Annotated[float, typer.Option("--u-gain-phase-deg", help="Type B: standard u of the output channel's phase, deg.")] = 0.0,
    u_other_rel: Annotated[str, typer.Option("--u-other-rel", help="Type B: other relative standard u (transverse motion, base strain ...; a fraction or e.g. 0.2%).")] = "0",
    u_other_phase_deg: Annotated[float, typer.Option("--u-other-phase-deg", help="Type B: other phase standard u, deg.")] = 0.0,
    sign_check: Annotated[bool, typer.Option("--sign-check/--no-sign-check", help="Refuse an output near 180 deg from the acceleration (I/Q swapped); off for an inverting amplifier.")] = True,
    heterodyne: Annotated[Optional[str], typer.Option("--heterodyne", help="Channel of a heterodyne interferometer's carrier (ISO 16063-41 style), instead of --quadrature.")] = None,
    carrier_hz: Annotated[Optional[str], typer.Option("--carrier-hz", help="Nominal carrier (frequency shift) of --heterodyne, Hz.")] = None,
    carrier_channel: Annotated[Optional[str], typer.Option("--carrier-channel", help="Channel of the reference carrier (cancels the carrier's offset and drift).")] = None,
    carrier_sign: Annotated[int, typer.Option("--carrier-sign", help="-1 when the Doppler phase runs against the displacement (the other arm is shifted).")] = 1,
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
    """Primary accelerometer calibration by laser interferometry (ISO 16063-11 method 3): sensitivity and phase."""
    from senscal.jobs.primary import primary

    used_standards = use_standards(standard, db=opts["db"], date=opts["date"], calibration_date=calibration_date)
    params = command_params(locals(), opts)
    params.pop("files")
    with progress_bar("calibrating", None):
        popts = _primary_options(**params)  # the type B inputs parsed ('0.1%' -> 0.001)
        res = primary(list(files), popts)
    doc = res.to_dict()
    # certificates and the registry as for `senscal response`: the points as a frequency response
    method = ("Primary calibration by laser interferometry (ISO 16063-11 method 3): homodyne quadrature "
              "interferometer, Heydemann correction, sine approximation of the displacement") if not heterodyne else (
        "Primary calibration by laser interferometry: heterodyne interferometer (ISO 16063-41 style carrier), "
        "quadrature mixing and low-pass demodulation, sine approximation of the displacement")
    resp = res.response(output_unit) if report is not None or dcc is not None else None
    cond = {} if resp is None else {
        "frequency points": len(res.points), "laser wavelength": f"{res.wavelength_nm:g} nm",
        ("heterodyne, carrier channels" if heterodyne else "quadrature channels"): ",".join(res.quadrature),
        "output channel": res.output,
        "type B inputs (relative u)": (f"wavelength {popts.u_wavelength_rel:g}, output gain {popts.u_gain_rel:g}, "
                                       f"other {popts.u_other_rel:g}")}
    cert_warns = certify("response", resp, report=report, dcc=dcc, unit=resp.unit if resp else "", method=method,
                         conditions=cond, files=[str(f) for f in files], warnings=res.warnings,
                         **cert_fields(params))
    doc["warnings"] = [*doc.get("warnings", []), *cert_warns]
    if report is not None:
        doc["report"] = str(report)
    save_registered(res, opts, method=method, input_files=files, certificate=report, standards=used_standards)
    if json_out:
        print_json(doc)
        emit_warnings([*res.warnings, *cert_warns], strict)
        return
    def fc_diff(p):
        # fringe counting's cross-check where the count resolves the displacement to 1e-3, else "-"
        fc = p.get("fringe_count")
        return f"{fc['difference_rel']:+.2e}" if fc and fc["applies"] else "-"

    rows = [[f"{p['frequency_hz']:.6g}", p["sensitivity"], 2 * p["u_sensitivity"], p["phase_deg"], 2 * p["u_phase_deg"],
             f"{p['fringes']:.1f}", fc_diff(p)] for p in doc["points"]]
    console.print(table(f"Primary calibration ({doc['method']}); U at k=2; SA/FC - 1: sine approximation over "
                        "fringe counting",
                        ["f / Hz", f"S / {doc['sensitivity_unit']}", "U(S)", "phase / deg", "U(phase) / deg",
                         "fringes", "SA/FC - 1"], rows))
    if report is not None:
        console.print(f"certificate written to {report}")
    emit_warnings([*res.warnings, *cert_warns], strict)


@simulate_app.command("interferometer")
@units(freqs=ListOf('Hz'), fs='Hz', duration='s', sensitivity='V/(m/s^2)', phase_deg='deg',
       acceleration=ListOf('m/s^2'), carrier_hz='Hz', carrier_offset_hz='Hz', carrier_drift_hz='Hz')
def simulate_interferometer_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    freqs: Annotated[str, typer.Option("--freqs", help="Excitation frequencies, Hz, comma separated.")] = "10,160,1000,5000",
    fs: Annotated[str, typer.Option("--fs", help="Sample rate, Hz.")] = "200000.0",
    duration: Annotated[str, typer.Option("--duration", help="Record length per frequency, s.")] = "1.0",
    sensitivity: Annotated[str, typer.Option("--sensitivity", help="Accelerometer sensitivity, V per m/s^2.")] = "0.01",
    phase_deg: Annotated[str, typer.Option("--phase-deg", help="Output phase minus acceleration phase, deg.")] = "-2.0",
    acceleration: Annotated[Optional[str], typer.Option("--acceleration", help="Acceleration amplitude, m/s^2: one for all frequencies or one per frequency (default 1 m/s^2, at least 0.5 um).")] = None,
    laser_noise: Annotated[float, typer.Option("--laser-noise", help="Noise on I and Q relative to their amplitude.")] = 2e-3,
    harmonic_distortion: Annotated[float, typer.Option("--harmonic-distortion", help="Exciter's 2nd harmonic acceleration relative to the fundamental's.")] = 0.0,
    output_drift: Annotated[float, typer.Option("--output-drift", help="Linear output drift over the record, relative.")] = 0.0,
    hum: Annotated[float, typer.Option("--hum", help="50 Hz hum on the output, relative.")] = 0.0,
    swap_iq: Annotated[bool, typer.Option("--swap-iq", help="Write I and Q swapped (a wiring mistake).")] = False,
    heterodyne: Annotated[bool, typer.Option("--heterodyne", help="A heterodyne interferometer instead: carrier channel H and reference carrier ref.")] = False,
    carrier_hz: Annotated[str, typer.Option("--carrier-hz", help="Heterodyne carrier (frequency shift), Hz.")] = "250000.0",
    carrier_offset_hz: Annotated[str, typer.Option("--carrier-offset-hz", help="The true carrier's offset from --carrier-hz, Hz.")] = "0.0",
    carrier_drift_hz: Annotated[str, typer.Option("--carrier-drift-hz", help="The carrier's linear change over the record, Hz.")] = "0.0",
    am_depth: Annotated[float, typer.Option("--am-depth", help="Amplitude modulation depth of the carrier (37 Hz).")] = 0.0,
    reference: Annotated[bool, typer.Option("--reference/--no-reference", help="Write the reference carrier channel ref (heterodyne).")] = True,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
) -> None:
    """Quadrature interferometer and accelerometer recordings with Heydemann errors: interferometer_NN.csv + truth."""
    from senscal.cli.common import parse_floats
    from senscal.errors import InputError
    from senscal.simulate.common import write_simulation
    from senscal.simulate.interferometer import simulate_interferometer

    fl = parse_floats(freqs, "--freqs")
    if not fl or not fs > 0 or not duration > 0 or any(not 0 < f < fs / 2 for f in fl):
        raise InputError("--freqs must lie between 0 and fs/2, --fs and --duration must be positive")
    if heterodyne and not 0 < carrier_hz + carrier_offset_hz < fs / 2:
        raise InputError(f"--carrier-hz {carrier_hz:g} Hz must lie between 0 and the Nyquist frequency {fs / 2:g} Hz")
    acc = [None] * len(fl) if acceleration is None else parse_floats(acceleration, "--acceleration")
    if len(acc) == 1:
        acc = acc * len(fl)
    if len(acc) != len(fl) or any(a is not None and not a > 0 for a in acc):
        raise InputError("--acceleration takes one positive amplitude for all frequencies or one per frequency")
    import math

    from senscal.simulate.interferometer import default_acceleration

    # NaN went through to the channels (refused later as "bad samples" of the simulation), negative noise silently
    for opt, v, nonneg in (("--sensitivity", sensitivity, False), ("--phase-deg", phase_deg, False),
                           ("--laser-noise", laser_noise, True), ("--harmonic-distortion", harmonic_distortion, True),
                           ("--output-drift", output_drift, False), ("--hum", hum, True), ("--am-depth", am_depth, True)):
        if not math.isfinite(v) or (nonneg and v < 0):
            raise InputError(f"{opt} must be a finite number{' of 0 or more' if nonneg else ''}, got {v!r}")
    if sensitivity == 0:
        raise InputError("--sensitivity must not be 0 (an accelerometer without output has nothing to calibrate)")
    for f, a in zip(fl, acc):
        # homodyne fringes alias when the phase 4 pi s / lambda steps by pi per sample: peak velocity < lambda fs / 4
        v_peak = (default_acceleration(f) if a is None else a) / (2 * math.pi * f)
        if not heterodyne and v_peak > 632.8e-9 * fs / 4:
            raise InputError(f"--acceleration at {f:g} Hz moves {v_peak:.3g} m/s at its peak; the fringes alias above "
                             f"{632.8e-9 * fs / 4:.3g} m/s at --fs {fs:g} Hz: lower the acceleration or raise --fs")
    recs, pts = [], []
    for i, f in enumerate(fl):
        rec, tr = simulate_interferometer(freq=f, acceleration=acc[i], fs=fs, duration=duration, sensitivity=sensitivity,
                                          phase_deg=phase_deg, laser_noise=laser_noise,
                                          harmonic_distortion=harmonic_distortion, output_drift_rel=output_drift,
                                          hum_rel=hum, swap_iq=swap_iq, heterodyne=heterodyne, carrier_hz=carrier_hz,
                                          carrier_offset_hz=carrier_offset_hz, carrier_drift_hz=carrier_drift_hz,
                                          am_depth=am_depth, reference=reference,
                                          seed=None if seed is None else seed + i)
        recs.append(rec)
        pts.append(tr)
    paths = write_simulation(recs, {"points": pts}, out, "interferometer")
    console.print(f"wrote {len(paths)} recordings and interferometer_truth.json to {out}")
