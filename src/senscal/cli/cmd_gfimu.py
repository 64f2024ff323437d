"""``senscal gfimu`` and ``senscal simulate gfimu``: angular velocity from an accelerometer array."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli._quantities import ListOf, units
from senscal.cli.app import app, simulate_app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, TimeUnitOpt, console,
                                emit_warnings, err_console, parse_floats, print_json, table)
from senscal.cli.common import StartOpt, StopOpt, parse_relative
from senscal.errors import InputError
from senscal.jobs._base import with_read_options

_AXES = ("wx", "wy", "wz")


@with_read_options
def _options(*, layout_file: Path | str | None = None, distance: float | None = None, method: str = "kalman",
             observation: str = "quadratic", initial_omega: str | None = None, truth: Path | str | None = None,
             attitude: bool = False, lag: int = 1, noise_std: float | None = None, bias_std: float | None = None,
             plain: bool = False, rest: str | None = None, differential_max_u: float | None = None,
             smooth: bool = False, **_):
    """``GfimuOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.gfimu import GfimuOptions

    w0 = (0.0, 0.0, 0.0)
    if initial_omega is not None:
        w0 = tuple(parse_floats(initial_omega, "--initial-omega"))
        if len(w0) != 3:
            raise InputError(f"--initial-omega needs three numbers WX,WY,WZ in rad/s, got {initial_omega!r}")
    span = None
    if rest is not None:
        span = tuple(parse_floats(rest.replace(":", ","), "--rest"))
        if len(span) != 2:
            raise InputError(f"--rest needs START:END in s (e.g. 0:2), got {rest!r}")
    return GfimuOptions(layout=layout_file, distance=distance, method=method, observation=observation,
                        initial_omega=w0, truth=truth, attitude=attitude, lag=lag, noise_std=noise_std,
                        bias_std=bias_std, plain=plain, rest=span, differential_max_u=differential_max_u,
                        smooth=smooth)


# What `senscal batch` turns the job's option words into (see senscal.jobs).
JOB_OPTIONS = {"gfimu": _options}


@app.command("gfimu")
@units(distance='m', noise_std='m/s^2', bias_std='m/s^2', differential_max_u='rad/s', initial_omega=ListOf('rad/s'))
def gfimu_cmd(
    file: Annotated[Path, typer.Argument(help="Recording of the array's channels (m/s^2).")],
    layout_file: Annotated[Optional[Path], typer.Option("--layout", help="Layout table CSV: name,x,y,z,nx,ny,nz (m).")] = None,
    distance: Annotated[Optional[str], typer.Option("--distance", help="Mounting distance L of the paper's layout, m (default 0.04).")] = None,
    method: Annotated[str, typer.Option("--method", help="kalman, integration, sqrt, differential or all.")] = "kalman",
    observation: Annotated[str, typer.Option("--observation", help="Kalman observation: quadratic (EKF on the quadratic terms), sqrt or differential.")] = "quadratic",
    initial_omega: Annotated[Optional[str], typer.Option("--initial-omega", help="Angular velocity at the first sample WX,WY,WZ in rad/s (default 0,0,0).")] = None,
    truth: Annotated[Optional[Path], typer.Option("--truth", help="Truth CSV with t, wx, wy, wz (rad/s): adds error statistics.")] = None,
    attitude: Annotated[bool, typer.Option("--attitude", help="Integrate the angular velocity into a quaternion (qw qx qy qz).")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="Write t, w, alpha, f (and q) to this CSV.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Plot the rates (and errors with --truth) to a PNG.")] = None,
    lag: Annotated[int, typer.Option("--lag", help="Span of the differential method in samples (1 = the paper's).")] = 1,
    noise_std: Annotated[Optional[str], typer.Option("--noise-std", help="Channel white-noise std in m/s^2 (default: estimated).")] = None,
    bias_std: Annotated[Optional[str], typer.Option("--bias-std", help="Standard uncertainty of each channel's constant error (bias) in m/s^2 (default 0.1): the quadratic filter estimates the constant errors of alpha and W, and u(w) includes them.")] = None,
    plain: Annotated[bool, typer.Option("--plain", help="The paper's plain filter without constant-error states: u(w) is white noise only and does NOT cover biased channels (warning constant-errors-ignored).")] = False,
    rest: Annotated[Optional[str], typer.Option("--rest", help="START:END in s of a segment where the body is at rest (e.g. 0:2): the constant errors of alpha and W are measured there and start the filter.")] = None,
    differential_max_u: Annotated[Optional[str], typer.Option("--differential-max-u", help="Differential method: reject samples whose standard uncertainty exceeds this many rad/s (absolute; the 3x-median rule alone passes gross errors on axes that hardly turn).")] = None,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="Offline: the Kalman estimate from the fixed-interval (RTS) smoother over the whole record instead of the causal filter.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Angular velocity of a rigid body from an accelerometer array (no gyroscope)."""
    from senscal.io import write_recording
    from senscal.jobs.gfimu import gfimu

    result = gfimu(file, _options(**locals()))
    est = result.estimate
    doc = result.to_dict()
    if out is not None:
        doc["out"] = str(write_recording(result.output_recording(), out))
    if plot is not None:
        from senscal.gfimu.plots import plot_rates

        doc["plot"] = str(plot_rates(result.t, est.omega, plot, truth=result.truth_omega, title=str(file.name)))
    if json_out:
        print_json(doc)
        emit_warnings(result.warnings, strict)
        return
    console.print(f"{file}: {doc['n_samples']} samples at {doc['sample_rate_hz']:.6g} Hz, "
                  f"layout {doc['layout']['source']}, condition number {est.condition_number:.3g}")
    console.print(f"channel noise (estimated or given): median {np.median(est.noise_std):.3g} m/s^2")
    if est.filter is not None:
        f = doc["filter"]
        u = f["median_u_omega"]
        console.print(f"Kalman {'smoother (offline RTS)' if f['smoothed'] else 'filter'} "
                      f"({f['observation']} observation): {f['n_gated']} samples gated, "
                      f"{f['n_dropped']} observation components dropped; median u(w) = "
                      + ", ".join(f"{ax} {u[ax]:.3g} (U {2 * u[ax]:.3g}, k=2)" for ax in _AXES) + " rad/s")
        if "offsets" in f:
            rows = [[n, f"{o['value']:.4g}", f"{o['u']:.3g}", f"{2 * o['u']:.3g}"] for n, o in f["offsets"].items()]
            console.print(table("Constant errors estimated by the filter (alpha rad/s^2, W (rad/s)^2)",
                                ["term", "value", "u (k=1)", "U (k=2)"], rows))
    if "errors" in doc:
        rows = [[m] + [f"{e[ax][k]:.3g}" for ax in _AXES for k in ("max_abs_error", "std_error")]
                for m, e in doc["errors"].items()]
        tr = doc.get("errors_transient")
        since = f" from t = {doc['errors_from_s']:.4g} s, after the filter's start-up" if tr else ""
        console.print(table(f"Angular-velocity error vs truth (rad/s){since}",
                            ["method", "max |e| wx", "std wx", "max |e| wy", "std wy", "max |e| wz", "std wz"], rows))
        if tr:
            k = tr.get("kalman")
            worst = f"; the Kalman filter's max |e| there {max(k[ax]['max_abs_error'] for ax in _AXES):.3g} rad/s" \
                if k else ""
            console.print(f"start-up transient before t = {tr['until_s']:.4g} s (the filter learns the constant errors "
                          f"until its u(w) settles within 2x of its median){worst}; 'errors_transient' in --json")
    else:
        rows = [[m] + [f"{np.nanmin(w[i]):.4g} .. {np.nanmax(w[i]):.4g}" for i in range(3)] for m, w in est.omega.items()]
        console.print(table("Angular velocity range (rad/s)", ["method", "wx", "wy", "wz"], rows))
    if "attitude" in doc and "max_error_deg" in doc["attitude"]:
        a = doc["attitude"]
        console.print(f"attitude ({a['method']}): max error {a['max_error_deg']:.3g} deg, final {a['final_error_deg']:.3g} deg, "
                      f"growth {a['growth_deg_per_s']:.3g} deg/s; gravity alone then drifts position by "
                      f"{a['position_drift_m']:.3g} m")
    if "rest" in doc:
        r = doc["rest"]
        rows = [[n, f"{o['value']:.4g}", f"{o['u']:.3g}", f"{2 * o['u']:.3g}"] for n, o in r["offsets"].items()]
        console.print(table(f"Constant errors on the rest segment {r['span_s'][0]:g}:{r['span_s'][1]:g} s "
                            "(alpha rad/s^2, W (rad/s)^2)", ["term", "value", "u (k=1)", "U (k=2)"], rows))
    for key in ("out", "plot"):
        if key in doc:
            err_console.print(f"wrote {doc[key]}")
    emit_warnings(result.warnings, strict)


@simulate_app.command("gfimu")
@units(fs='Hz', duration='s', distance='m', bias_g='g', noise_g='g', position_error='m', direction_error='rad',
       rest='s', offset=ListOf('m'), amplitudes=ListOf('deg'), freqs=ListOf('Hz'), linear_amplitude='m/s^2')
def simulate_gfimu_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    paper: Annotated[bool, typer.Option("--paper", help="The paper's set-up: 10 kHz, 10 s, 30 deg / 2 Hz about z, 1e-4 g bias, 1e-3 g noise, L = 0.04 m.")] = False,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    fs: Annotated[Optional[str], typer.Option("--fs", help="Sample rate in Hz (default 10000 with --paper, else 1000).")] = None,
    duration: Annotated[Optional[str], typer.Option("--duration", help="Record length in s (default 10).")] = None,
    distance: Annotated[str, typer.Option("--distance", help="Mounting distance L, m.")] = "0.04",
    bias_g: Annotated[str, typer.Option("--bias-g", help="Per-channel constant error magnitude, g.")] = "1e-4",
    noise_g: Annotated[str, typer.Option("--noise-g", help="White-noise standard deviation, g.")] = "1e-3",
    position_error: Annotated[str, typer.Option("--position-error", help="Mounting position error std, m.")] = "0.0",
    direction_error: Annotated[str, typer.Option("--direction-error", help="Mounting direction error std, rad.")] = "0.0",
    direction_error_deg: Annotated[Optional[float], typer.Option("--direction-error-deg", help="Mounting direction error std, deg (instead of --direction-error).")] = None,
    rest: Annotated[str, typer.Option("--rest", help="Rest before the motion starts, s (mark it with 'senscal gfimu --rest 0:REST').")] = "0.0",
    scale_error: Annotated[str, typer.Option("--scale-error", help="Per-channel scale-factor error, random sign, as a fraction or percentage (0.05%); the layout assumes unit gains.")] = "0",
    offset: Annotated[Optional[str], typer.Option("--offset", help="Array origin relative to the rotation centre X,Y,Z in m (default 0.1,0,0 with --paper, else 0.05,-0.03,0.02).")] = None,
    amplitudes: Annotated[Optional[str], typer.Option("--amplitudes", help="Roll, pitch, yaw amplitudes R,P,Y in deg (default 0,0,30 with --paper, else 10,15,30).")] = None,
    freqs: Annotated[Optional[str], typer.Option("--freqs", help="Roll, pitch, yaw frequencies in Hz (default 1,1,2 with --paper, else 1.3,0.7,2).")] = None,
    linear_amplitude: Annotated[Optional[str], typer.Option("--linear-amplitude", help="Linear vibration of the rotation centre per axis, m/s^2 (default 0 with --paper, else 2).")] = None,
) -> None:
    """An accelerometer array on a moving rigid body: gfimu.csv, gfimu_truth.csv/.json, layout.csv."""
    from senscal.gfimu import paper_layout, write_layout
    from senscal.io import write_recording
    from senscal.simulate.common import write_truth
    from senscal.simulate.gfimu import simulate_gfimu

    def three(text, opt):
        if text is None:
            return None
        v = parse_floats(text, opt)
        if len(v) != 3:
            raise InputError(f"{opt} needs three numbers separated by commas, got {text!r}")
        return v

    if direction_error_deg is not None:
        if direction_error:
            raise InputError("give either --direction-error (rad) or --direction-error-deg, not both")
        direction_error = float(np.radians(direction_error_deg))
    rec, truth, info = simulate_gfimu(paper=paper, fs=fs, duration=duration, distance=distance, bias_g=bias_g,
                                      noise_g=noise_g, position_error_m=position_error,
                                      direction_error_rad=direction_error, seed=seed, rest_s=rest,
                                      scale_error=parse_relative(scale_error, "--scale-error"),
                                      offset_m=three(offset, "--offset"),
                                      amplitudes_deg=three(amplitudes, "--amplitudes"),
                                      freqs_hz=three(freqs, "--freqs"), linear_amplitude=linear_amplitude)
    paths = [write_recording(rec, out / "gfimu.csv"), write_recording(truth, out / "gfimu_truth.csv"),
             write_truth(info, out / "gfimu_truth.json"), write_layout(paper_layout(distance), out / "layout.csv")]
    console.print("wrote " + ", ".join(str(p) for p in paths))
