"""``senscal triaxial calibrate|apply`` and ``senscal simulate magnetometer``."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli.app import app, simulate_app
from senscal.cli.common import (
    FsOpt, JsonOpt, NamesOpt, SkipRowsOpt, emit_warnings, TimeColumnOpt, console, err_console, load, print_json, progress_bar, split_names, table,
    write_json,
)
from senscal.cli.registry_opts import (
    CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt, quoted, save_if_requested,
)
from senscal.errors import InputError

triaxial_app = typer.Typer(help="Three-axis magnetometer / accelerometer calibration without a reference.",
                           no_args_is_help=True)
app.add_typer(triaxial_app, name="triaxial")

ANGLES = ("alpha", "beta", "gamma")


def _channels(text: str) -> list[str]:
    names = split_names(text) or []
    if len(names) != 3:
        raise InputError(f"--channels needs exactly three names X,Y,Z, got {text!r}")
    return names


def parameter_table(params: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Parameters in the seed's terms for JSON: angles in degrees, U = 2u (k=2)."""
    out = {}
    for n, p in params.items():
        v, u = p["value"], p["u"]
        key, unit = n, p["unit"]
        if n in ANGLES:
            key, unit = f"{n}_deg", "deg"
            v = None if v is None else math.degrees(v)
            u = None if u is None else math.degrees(u)
        out[key] = {"value": v, "u": u, "U_k2": None if u is None else 2 * u, "unit": unit}
    return out


def calibrate_document(res, *, file: Path, channels: list[str], static=None) -> dict[str, Any]:
    """The JSON document of ``senscal triaxial calibrate`` (CLI contract)."""
    from senscal.triaxial.heading import summary as heading_summary

    doc = {
        "file": str(file), "channels": channels, "model": res.model, "method": res.method,
        "field": {"value": res.field,
                  "u": res.parameters.get("field", res.parameters.get("plane_field", {})).get("u"),
                  "estimated": res.field_estimated, "note": res.scale_note},
        "parameters": parameter_table(res.parameters),
        "unidentifiable": list(res.unidentifiable), "model_choice": list(res.model_choice),
        "coverage": res.coverage, "planarity": res.planarity, "conditioning": res.conditioning,
        "noise": res.noise, "norm_error_before": res.norm_error_before, "norm_error_after": res.norm_error_after,
        "outliers": {"count": len(res.outliers), "indices": list(res.outliers)},
        "saturated": {"count": len(res.saturated)}, "plausibility": list(res.plausibility),
        "warnings": list(res.warnings), "lms_vs_least_squares": res.lms_vs_least_squares,
        "n_samples": res.n_samples, "n_used": res.n_used,
        "model_evidence": list(res.model_evidence),
        "heading": heading_summary(res.heading) if res.heading is not None else None,
        "calibration": res.calibration.to_dict(),
    }
    if static is not None:
        doc["static"] = {"n_poses": static.n_poses, "starts": static.starts.tolist(), "stops": static.stops.tolist(),
                         "samples_per_pose_min": int(static.counts.min()) if static.n_poses else 0,
                         "threshold": static.threshold}
    return doc


def triaxial_quantities(doc: dict) -> list:
    """The registry quantities: every parameter the data determined (unidentifiable ones are left out)."""
    return [quoted(doc, name, f"parameters.{name}.value", f"parameters.{name}.u", p["unit"])
            for name, p in doc["parameters"].items() if p["value"] is not None and p["u"] is not None]


@triaxial_app.command("calibrate")
def calibrate_cmd(
    file: Annotated[Path, typer.Argument(help="Recording with three field channels.")],
    channels: Annotated[str, typer.Option("--channels", help="The X,Y,Z channel names, comma separated.")],
    field: Annotated[Optional[float], typer.Option("--field", help="Field magnitude (50000 nT, 9.80665 m/s^2 ...); estimated when omitted (scale then arbitrary).")] = None,
    method: Annotated[str, typer.Option("--method", help="auto | ml | ellipsoid | linear | lms.")] = "auto",
    model: Annotated[Optional[str], typer.Option("--model", help="Force full | diagonal | offsets | planar (default: richest the data support).")] = None,
    lr: Annotated[float, typer.Option("--lr", help="LMS learning rate (on field-scaled features).")] = 0.01,
    epochs: Annotated[int, typer.Option("--epochs", help="LMS passes over the data.")] = 50,
    strict: Annotated[bool, typer.Option("--strict", help="Insufficient coverage or implausible parameters -> error (exit 3).")] = False,
    static: Annotated[bool, typer.Option("--static", help="Accelerometer session: detect static poses and fit their means.")] = False,
    static_window: Annotated[float, typer.Option("--static-window", help="Moving-variance window for --static, s.")] = 0.5,
    min_pose: Annotated[float, typer.Option("--min-pose", help="Shortest static pose kept, s.")] = 1.0,
    outlier_sigma: Annotated[float, typer.Option("--outlier-sigma", help="Exclude readings this many robust sigma off (0: keep all).")] = 5.0,
    out: Annotated[Optional[Path], typer.Option("--out", help="Write the parameters (for 'triaxial apply') as JSON.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Sphere projections and norm error before/after (PNG); a one-axis turn or --accel-channels also writes <name>_heading.png.")] = None,
    accel_channels: Annotated[Optional[str], typer.Option("--accel-channels", help="An accelerometer recorded alongside (X,Y,Z names): it is calibrated too, and the tilt-compensated heading error and dip-angle spread are reported before/after.")] = None,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    skip_rows: SkipRowsOpt = None,
    json_out: JsonOpt = False,
    save: SaveOpt = False,
    sensor: SensorOpt = None,
    db: DbOpt = None,
    create_sensor: CreateSensorOpt = None,
    date: DateOpt = None,
    operator: OperatorOpt = None,
) -> None:
    """Identify non-orthogonality, gains and offsets from readings in a constant field."""
    from senscal.triaxial import calibrate, detect_static

    chans = _channels(channels)
    extra = _channels(accel_channels) if accel_channels is not None else []
    # Only --static uses time: a headerless x,y,z file needs no --fs otherwise.
    rec = load(file, time_column=time_column, fs=fs, names=names, channels=chans + extra, skip_rows=skip_rows,
               time_required=static)
    h = rec.data(chans)
    unit = rec.units.get(chans[0], "")
    st = None
    if static:
        st = detect_static(h, rec.sample_rate, window_s=static_window, min_duration_s=min_pose)
        if st.n_poses < 5:
            raise InputError(f"found {st.n_poses} static poses in {file}; a calibration needs many (>= 9 for the "
                             "full model): hold the sensor still longer in more orientations or adjust --static-window")
        h = st.means
    with progress_bar("calibrating", None):
        res = calibrate(h, field=field, method=method, model=model, lr=lr, epochs=epochs, strict=strict,
                        outlier_sigma=None if outlier_sigma == 0 else outlier_sigma, unit=unit, channels=chans)
    doc = calibrate_document(res, file=file, channels=chans, static=st)
    tilt = None
    if accel_channels is not None:
        from senscal.triaxial.heading import summary, tilt_heading_report

        achans = _channels(accel_channels)
        if static:
            raise InputError("--accel-channels needs the readings themselves, not --static pose means; drop --static")
        if set(achans) & set(chans):
            raise InputError("--accel-channels must name the accelerometer's channels, not the calibrated ones")
        a = rec.data(achans)
        with progress_bar("calibrating the accelerometer", None):
            ra = calibrate(a, outlier_sigma=None if outlier_sigma == 0 else outlier_sigma,
                           unit=rec.units.get(achans[0], ""), channels=achans)
        tilt = tilt_heading_report(h, res.calibration.apply(h), a, ra.calibration.apply(a))
        doc["tilt_heading"] = {**summary(tilt), "accelerometer": {
            "channels": achans, "model": ra.model, "method": ra.method, "norm_error_after": ra.norm_error_after,
            "warnings": list(ra.warnings), "calibration": ra.calibration.to_dict()}}
    if out is not None:
        write_json(doc, out)
    save_if_requested(doc, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date, operator=operator,
                      job="triaxial", method=f"{res.model} model, {res.method}",
                      quantities=lambda: triaxial_quantities(doc), input_files=[file],
                      conditions={"field": res.field, "field_estimated": res.field_estimated,
                                  "coverage": res.coverage["fraction"]})
    if plot is not None:
        from senscal.triaxial.plots import plot_calibration

        corr = res.calibration.apply(h)
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
    # The accelerometer's own warnings count too: a bad tilt spoils the heading.
    warnings = list(res.warnings) + list(doc.get("tilt_heading", {}).get("accelerometer", {}).get("warnings", []))
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
    json_out: JsonOpt = False,
) -> None:
    """Correct three field channels with saved parameters; other channels are copied."""
    from senscal.io import Recording, write_recording
    from senscal.triaxial import load_calibration

    cal = load_calibration(params)
    chans = _channels(channels)
    rec = load(file, time_column=time_column, fs=fs, names=names)
    rec.data(chans)  # unknown channel -> one-line error listing the channels
    for c in chans:
        u = rec.units.get(c, "")
        if cal.unit and u and u != cal.unit:
            raise InputError(f"channel '{c}' is in {u} but the calibration was made from data in {cal.unit}; "
                             "convert the data or calibrate again")
    if Path(out).resolve() == Path(file).resolve():
        raise InputError("--out must differ from the input file; input files are never modified")
    corr = cal.apply(rec.data(chans))
    new = dict(rec.channels)
    for k, c in enumerate(chans):
        new[c] = corr[k]
    res = Recording(channels=new, t=rec.t, fs=rec.fs, t0=rec.t0, units=rec.units,
                    metadata={**rec.metadata, "triaxial_calibration": f"{cal.model}/{cal.method} from {params}"})
    p = write_recording(res, out)
    norm = np.linalg.norm(corr, axis=0)
    summary = {"file": str(file), "out": str(p), "model": cal.model, "method": cal.method,
               "n_samples": int(norm.size), "corrected_norm_mean": float(norm.mean()),
               "corrected_norm_std": float(norm.std(ddof=1)) if norm.size > 1 else 0.0, "field": cal.field}
    if json_out:
        print_json(summary)
    else:
        console.print(f"wrote {p}: {norm.size} samples corrected with the {cal.model} model ({cal.method}); "
                      f"|H| = {summary['corrected_norm_mean']:.6g} +/- {summary['corrected_norm_std']:.3g} "
                      f"(field {cal.field:.6g})")


@simulate_app.command("magnetometer")
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
    tilt_deg: Annotated[float, typer.Option("--tilt-deg", help="Random tilt std of the planar turn, deg.")] = 0.0,
    outliers: Annotated[int, typer.Option("--outliers", help="Gross-error readings.")] = 0,
    clip: Annotated[Optional[float], typer.Option("--clip", help="Saturate each axis at +/- this value.")] = None,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
) -> None:
    """A rotated magnetometer (or tumbled accelerometer) with known errors: magnetometer.csv + truth JSON."""
    from senscal.cli.common import parse_floats
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.triaxial import simulate_magnetometer

    g = parse_floats(gains, "--gains")
    b = parse_floats(offsets, "--offsets") if offsets is not None else None
    if len(g) != 3 or (b is not None and len(b) != 3):
        raise InputError("--gains and --offsets need three comma-separated numbers")
    if n is not None and n < 1:
        raise InputError("--n must be at least 1")
    rec, truth = simulate_magnetometer(motion=motion, n=n, field=field, noise=noise, alpha_deg=alpha_deg,
                                       beta_deg=beta_deg, gamma_deg=gamma_deg, gains=tuple(g),
                                       offsets=tuple(b) if b else None, tilt_deg=tilt_deg, n_outliers=outliers,
                                       clip=clip, seed=seed)
    p = write_recording(rec, out / "magnetometer.csv")
    q = write_truth(truth, out / "magnetometer_truth.json")
    console.print(f"wrote {p} and {q}")
