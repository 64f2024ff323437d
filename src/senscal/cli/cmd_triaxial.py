"""``senscal triaxial calibrate|apply`` and ``senscal simulate magnetometer``."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import app, simulate_app
from senscal.cli.common import (
    FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings, err_console, print_json, progress_bar,
    table,
)
from senscal.cli.common import StartOpt, StopOpt
from senscal.cli.option_groups import READ, REGISTRY, command_params, save_registered, with_options
from senscal.cli.registry_opts import StandardOpt, note_standards, use_standards
from senscal.errors import InputError
from senscal.jobs._base import with_read_options

triaxial_app = typer.Typer(help="Three-axis magnetometer / accelerometer calibration without a reference.",
                           no_args_is_help=True)
app.add_typer(triaxial_app, name="triaxial")


@with_read_options
def _calibrate_options(*, channels: str = "x,y,z", field: float | None = None, method: str = "auto",
                       model: str | None = None, lr: float = 0.01, epochs: int = 50, strict: bool = False,
                       static: bool = False, static_window: float = 0.5, min_pose: float = 1.0,
                       outlier_sigma: float = 5.0, accel_channels: str | None = None, **_):
    """``TriaxialCalibrateOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.triaxial import TriaxialCalibrateOptions

    return TriaxialCalibrateOptions(
        channels=channels, field=field, method=method, model=model, lr=lr, epochs=epochs, strict=strict,
        static=static, static_window=static_window, min_pose=min_pose, outlier_sigma=outlier_sigma,
        accel_channels=accel_channels)


@with_read_options
def _apply_options(*, params: Path | str | None = None, channels: str = "x,y,z", **_):
    """``TriaxialApplyOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.triaxial import TriaxialApplyOptions

    return TriaxialApplyOptions(params=params, channels=channels)


# What `senscal batch` turns a job's option words into (see senscal.jobs).
JOB_OPTIONS = {"triaxial-calibrate": _calibrate_options, "triaxial-apply": _apply_options}


@triaxial_app.command("calibrate")
@units(static_window='s', min_pose='s')
@with_options(READ, REGISTRY)
def calibrate_cmd(
    file: Annotated[Path, typer.Argument(help="Recording with three field channels.")],
    channels: Annotated[str, typer.Option("--channels", help="The X,Y,Z channel names, comma separated.")],
    field: Annotated[Optional[str], typer.Option("--field", metavar="<qty>", help="Field magnitude in the readings' unit (50000 for nT data), or with a unit converted to theirs ('50 uT', '1 g'); estimated when omitted (scale then arbitrary).")] = None,
    method: Annotated[str, typer.Option("--method", help="auto | ml | ellipsoid | linear | lms.")] = "auto",
    model: Annotated[Optional[str], typer.Option("--model", help="Force full | diagonal | offsets | planar (default: richest the data support).")] = None,
    lr: Annotated[float, typer.Option("--lr", help="LMS learning rate (on field-scaled features).")] = 0.01,
    epochs: Annotated[int, typer.Option("--epochs", help="LMS passes over the data.")] = 50,
    strict: Annotated[bool, typer.Option("--strict", help="Insufficient coverage or implausible parameters -> error (exit 3).")] = False,
    static: Annotated[bool, typer.Option("--static", help="Accelerometer session: detect static poses and fit their means.")] = False,
    static_window: Annotated[str, typer.Option("--static-window", help="Moving-variance window for --static, s.")] = "0.5",
    min_pose: Annotated[str, typer.Option("--min-pose", help="Shortest static pose kept, s.")] = "1.0",
    outlier_sigma: Annotated[float, typer.Option("--outlier-sigma", help="Exclude readings this many robust sigma off (0: keep all).")] = 5.0,
    out: Annotated[Optional[Path], typer.Option("--out", help="Write the parameters (for 'triaxial apply') as JSON, or HDF5 for .h5; - for stdout.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Sphere projections and norm error before/after (PNG); a one-axis turn or --accel-channels also writes <name>_heading.png.")] = None,
    accel_channels: Annotated[Optional[str], typer.Option("--accel-channels", help="An accelerometer recorded alongside (X,Y,Z names): it is calibrated too, and the tilt-compensated heading error and dip-angle spread are reported before/after.")] = None,
    json_out: JsonOpt = False,
    standard: StandardOpt = None,
    **opts,
) -> None:
    """Identify non-orthogonality, gains and offsets from readings in a constant field."""
    from senscal.jobs.triaxial import triaxial_calibrate

    used_standards = use_standards(standard, db=opts["db"], date=opts["date"])
    with progress_bar("calibrating", None):
        result = triaxial_calibrate(file, _calibrate_options(**command_params(locals(), opts)))
    res, h, unit, tilt = result.calibration, result.readings, result.unit, result.tilt
    doc = result.to_dict()
    if out is not None:
        res.calibration.save(out, extra=doc)  # type + format_version; JSON, or HDF5 for .h5 (senscal.persist)
    save_registered(result, opts, job="triaxial", method=result.method, input_files=[file],
                    conditions=result.conditions, standards=used_standards)
    if plot is not None:
        from senscal.triaxial.plots import plot_calibration

        corr = result.corrected()
        raw = h
        f = res.field
        if res.model == "planar":
            k = 3 - sum(res.calibration.plane_axes)
            raw, corr = h.copy(), corr.copy()
            raw[k] = 0.0
            corr[k] = 0.0
        plot_calibration(raw, corr, f, plot, unit=unit, title=f"{file.name}: {res.model} model, {res.method}")
        if res.heading is not None or tilt is not None:
            from senscal.triaxial.plots import plot_heading

            hp = plot_heading(tilt if tilt is not None else res.heading, plot.with_name(f"{plot.stem}_heading{plot.suffix}"),
                              title=f"{file.name}: {'tilt-compensated ' if tilt is not None else ''}heading error "
                                    "before / after")
            err_console.print(f"wrote {hp}")
    warnings = [*result.warnings, *note_standards(doc, used_standards)]
    if json_out:
        print_json(doc)
        emit_warnings(warnings, strict)
        return
    rows = []
    for n, p in doc["parameters"].items():
        rows.append([n, p["value"], p["U_k2"], p["unit"]])
    console.print(table(f"Triaxial calibration of {file}: {res.model} model by {res.method} "
                        "(U = expanded uncertainty, k=2)", ["parameter", "value", "U", "unit"], rows))
    b, a = res.norm_error_before, res.norm_error_after
    console.print(f"field {res.field:.6g}{' (estimated: scale arbitrary)' if res.field_estimated else ''}; "
                  f"coverage {res.coverage['fraction']:.0%} of sphere cells; noise {res.noise:.4g}")
    console.print(f"|H| - F before: mean {b['mean']:.4g}, std {b['std']:.4g}, max {b['max_abs']:.4g} "
                  f"({b['std_percent']:.3g} % std)")
    console.print(f"|H| - F after:  mean {a['mean']:.4g}, std {a['std']:.4g}, max {a['max_abs']:.4g} "
                  f"({a['std_percent']:.3g} % std)")
    tt = res.time_terms or {}
    if tt.get("note"):
        console.print(tt["note"])
    for g in res.unidentifiable:
        console.print(f"unidentifiable: {g['reason']}")
    for c in res.model_choice:
        console.print(f"rejected {c}")
    if res.heading is not None:
        hb, ha = res.heading["deviation_before_deg"], res.heading["U_after_deg"]
        console.print(f"turn about one axis: heading error before {hb['rms']:.3g} deg rms ({hb['max_abs']:.3g} max); "
                      f"after, U(k=2) {ha['rms']:.3g} deg rms ({ha['max_abs']:.3g} max)")
    if tilt is not None:
        tb, d0, d1 = tilt["deviation_before_deg"], tilt["dip_before_deg"], tilt["dip_after_deg"]
        console.print(f"tilt-compensated heading: raw minus calibrated {tb['rms']:.3g} deg rms ({tb['max_abs']:.3g} "
                      f"max); dip angle spread {d0['std']:.3g} deg before, {d1['std']:.3g} deg after")
    emit_warnings(warnings, strict)


@triaxial_app.command("apply")
def apply_cmd(
    file: Annotated[Path, typer.Argument(help="Recording to correct (never modified).")],
    params: Annotated[Path, typer.Option("--params", help="Parameter file written by 'triaxial calibrate --out'.")],
    channels: Annotated[str, typer.Option("--channels", help="The X,Y,Z channel names, comma separated.")],
    out: Annotated[Path, typer.Option("--out", help="Corrected recording (CSV, Parquet, HDF5, NPZ).")],
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    strict: StrictOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Correct three field channels with saved parameters; other channels are copied."""
    from senscal.io import write_recording
    from senscal.jobs.triaxial import triaxial_apply

    result = triaxial_apply(file, _apply_options(**locals()))
    if Path(out).resolve() == Path(file).resolve():
        raise InputError("--out must differ from the input file; input files are never modified")
    # 'x [nT]': the corrected units travel with the data (read back, an unlabelled file would be a unit assumed)
    p = write_recording(result.recording, out, units_in_header=True)
    summary = result.to_dict()
    summary["out"] = str(p)
    cal, norm = result.calibration, result.corrected_norm
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {p}: {norm.size} samples corrected with the {cal.model} model ({cal.method}); "
                      f"|H| = {summary['corrected_norm_mean']:.6g} +/- {summary['corrected_norm_std']:.3g} "
                      f"(field {cal.field:.6g})")
    emit_warnings(result.warnings, strict)


@triaxial_app.command("import")
def import_cmd(
    file: Annotated[Path, typer.Argument(help="Another tool's calibration as 12 plain numbers: matrix A row by row, then offset B.")],
    out: Annotated[Path, typer.Option("--out", help="senscal parameter file for 'triaxial apply' (JSON, or HDF5 for .h5; - for stdout).")],
    form: Annotated[str, typer.Option("--form", help="affine: the tool corrects as A h + B (Dorveaux, MagnetometerCalibration); centred: as A (h - B) (Magneto).")] = "affine",
    field: Annotated[float, typer.Option("--field", help="Field magnitude the corrected data should show, in corrected units (1 when the tool normalises it).")] = 1.0,
    unit: Annotated[str, typer.Option("--unit", help="Unit of the raw readings it applies to (checked by 'triaxial apply').")] = "",
    channels: Annotated[str, typer.Option("--channels", help="The X,Y,Z channel names it is for.")] = "x,y,z",
    json_out: JsonOpt = False,
) -> None:
    """Turn a third-party calibration (A and B of A h + B, or A (h - B)) into a senscal parameter file."""
    from senscal.jobs.triaxial import TriaxialImportOptions, triaxial_import

    result = triaxial_import(file, TriaxialImportOptions(form=form, field=field, unit=unit, channels=channels))
    p = result.calibration.save(out, extra={"imported_from": result.to_dict()})
    if json_out:
        print_json(result.to_dict())
    elif str(out) != "-":
        console.print(f"wrote {p}: {result.form} calibration from {file} (apply it with 'senscal triaxial apply "
                      f"--params {p}')")


@simulate_app.command("magnetometer")
@units(tilt_deg='deg')
def simulate_magnetometer_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    motion: Annotated[str, typer.Option("--motion", help="sphere | planar (the seed's 15-reading turn) | tumble (static poses).")] = "sphere",
    n: Annotated[Optional[int], typer.Option("--n", help="Readings (sphere/planar) or poses (tumble).")] = None,
    field: Annotated[Optional[float], typer.Option("--field", help="Field magnitude (default 50000 nT; 9.80665 m/s^2 for tumble).")] = None,
    noise: Annotated[Optional[float], typer.Option("--noise", help="Noise std per axis (default 20 nT, scaled to the field).")] = None,
    alpha_deg: Annotated[float, typer.Option("--alpha-deg")] = 0.8,
    beta_deg: Annotated[float, typer.Option("--beta-deg")] = -1.1,
    gamma_deg: Annotated[float, typer.Option("--gamma-deg")] = 0.6,
    gains: Annotated[str, typer.Option("--gains", help="Kx,Ky,Kz.")] = "1.03,0.98,1.0",
    offsets: Annotated[Optional[str], typer.Option("--offsets", help="Bx,By,Bz (default 300,-200,150 nT scaled to the field).")] = None,
    tilt_deg: Annotated[str, typer.Option("--tilt-deg", help="Random tilt std of the planar turn, deg.")] = "0.0",
    outliers: Annotated[int, typer.Option("--outliers", help="Gross-error readings.")] = 0,
    clip: Annotated[Optional[float], typer.Option("--clip", help="Saturate each axis at +/- this value.")] = None,
    order: Annotated[str, typer.Option("--order", help="random | tumble (sphere: the Z axis turned from up to down, so slow changes follow the orientation).")] = "random",
    drift: Annotated[Optional[str], typer.Option("--drift", help="dBx,dBy,dBz: offset change over the session (e.g. 30,-20,25 nT).")] = None,
    drift_shape: Annotated[str, typer.Option("--drift-shape", help="linear | warmup (settles like 1 - exp(-3 s)).")] = "linear",
    field_step: Annotated[float, typer.Option("--field-step", help="The field's magnitude steps by this much (field units) at --step-at of the session.")] = 0.0,
    step_at: Annotated[float, typer.Option("--step-at", help="Session fraction of the field step.")] = 0.5,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
) -> None:
    """A rotated magnetometer (or tumbled accelerometer) with known errors: magnetometer.csv + truth JSON."""
    from senscal.cli.common import parse_floats
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.triaxial import simulate_magnetometer

    g = parse_floats(gains, "--gains")
    b = parse_floats(offsets, "--offsets") if offsets is not None else None
    d = parse_floats(drift, "--drift") if drift is not None else None
    if len(g) != 3 or (b is not None and len(b) != 3) or (d is not None and len(d) != 3):
        raise InputError("--gains, --offsets and --drift need three comma-separated numbers")
    if n is not None and n < 1:
        raise InputError("--n must be at least 1")
    rec, truth = simulate_magnetometer(motion=motion, n=n, field=field, noise=noise, alpha_deg=alpha_deg,
                                       beta_deg=beta_deg, gamma_deg=gamma_deg, gains=tuple(g),
                                       offsets=tuple(b) if b else None, tilt_deg=tilt_deg, n_outliers=outliers,
                                       clip=clip, order=order, drift=tuple(d) if d else None,
                                       drift_shape=drift_shape, field_step=field_step, step_at=step_at, seed=seed)
    p = write_recording(rec, out / "magnetometer.csv")
    q = write_truth(truth, out / "magnetometer_truth.json")
    console.print(f"wrote {p} and {q}")
