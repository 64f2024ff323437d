"""``senscal gfimu`` and ``senscal simulate gfimu``: angular velocity from an accelerometer array."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli.app import app, simulate_app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings,
                                err_console, load, parse_floats, print_json, table)
from senscal.cli.common import TimeUnitOpt, time_checked
from senscal.errors import InputError
from senscal.gfimu import (DEFAULT_BIAS_STD, METHODS, OBSERVATIONS, UNKNOWNS, angular_velocity, attitude_error, error_statistics,
                           integrate_attitude, paper_layout, read_layout)
from senscal.io import Recording, write_recording

_AXES = ("wx", "wy", "wz")


def _truth_on(rec_t: np.ndarray, path: Path, need_q: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """Truth ``w`` (3, T) and, if present, ``q`` (4, T) on the recording's time base."""
    tr = load(path)
    missing = [c for c in _AXES if c not in tr]
    if missing:
        raise InputError(f"truth file {path} lacks column(s) {', '.join(missing)}; it needs t, wx, wy, wz in rad/s")
    tt = tr.time
    if tt.size == rec_t.size and np.allclose(tt, rec_t, rtol=0, atol=1e-9 * max(1.0, float(np.abs(rec_t).max()))):
        w = tr.data(list(_AXES))
        q = tr.data(["qw", "qx", "qy", "qz"]) if need_q and all(c in tr for c in ("qw", "qx", "qy", "qz")) else None
        return w, q
    if tt[0] > rec_t[0] or tt[-1] < rec_t[-1]:
        raise InputError(f"truth file {path} spans t={tt[0]:g}..{tt[-1]:g} s but the recording "
                         f"{rec_t[0]:g}..{rec_t[-1]:g} s; give a truth that covers the recording")
    w = np.stack([np.interp(rec_t, tt, tr[c]) for c in _AXES])
    return w, None


def _rate_checked(est, y, layout):
    """``est`` plus a time-unit-suspect warning when its rates are physically impossible for the array."""
    from dataclasses import replace

    from senscal.io.plausibility import TIME_UNIT_WARNING, check_angular_rate

    if any(w.startswith(TIME_UNIT_WARNING) for w in est.warnings):
        return est
    pos = np.asarray(layout.positions, dtype=float)
    radius = float(np.max(np.linalg.norm(pos - pos.mean(axis=0), axis=1))) if pos.size else float("nan")
    # NaN rates (samples a method rejected) are skipped without numpy's all-NaN warnings.  The
    # differential method is left out: its gross errors where the increment is small (1e5 rad/s on an
    # axis that hardly turns) are the method's, not a sign of a wrong time unit.
    norms = [np.linalg.norm(np.asarray(w, dtype=float), axis=0) for m, w in est.omega.items() if m != "differential"]
    rates = [float(n[np.isfinite(n)].max()) for n in norms if np.isfinite(n).any()]
    ay = np.abs(np.asarray(y, dtype=float))
    found = check_angular_rate(max(rates, default=float("nan")),
                               float(ay[np.isfinite(ay)].max()) if np.isfinite(ay).any() else float("nan"), radius)
    return replace(est, warnings=tuple(est.warnings) + found) if found else est


def run_gfimu(file: Path, *, layout_file: Path | None, distance: float | None, method: str, observation: str,
              initial_omega: str | None, truth: Path | None, attitude: bool, lag: int, noise_std: float | None,
              time_column: str, fs: float | None, names: str | None, bias_std: float | None = None,
              smooth: bool = False, plain: bool = False, rest: str | None = None,
              differential_max_u: float | None = None, time_unit: str | None = None):
    """Run the job; returns (document, recording time, estimate, truth w, quaternion)."""
    if layout_file is not None and distance is not None:
        raise InputError("give either --layout or --distance, not both")
    layout = read_layout(layout_file) if layout_file is not None else paper_layout(0.04 if distance is None else distance)
    methods = METHODS if method == "all" else (method,)
    if method not in METHODS + ("all",):
        raise InputError(f"--method must be one of {', '.join(METHODS)}, all; got {method!r}")
    if observation not in OBSERVATIONS:
        raise InputError(f"--observation must be one of {', '.join(OBSERVATIONS)}; got {observation!r}")
    w0 = (0.0, 0.0, 0.0)
    if initial_omega is not None:
        w0 = parse_floats(initial_omega, "--initial-omega")
        if len(w0) != 3:
            raise InputError(f"--initial-omega needs three numbers WX,WY,WZ in rad/s, got {initial_omega!r}")
    span = None
    if rest is not None:
        span = parse_floats(rest.replace(":", ","), "--rest")
        if len(span) != 2:
            raise InputError(f"--rest needs START:END in s (e.g. 0:2), got {rest!r}")
    rec = load(file, time_column=time_column, fs=fs, names=names, time_unit=time_unit)
    y = rec.data(list(layout.names))
    est = time_checked(rec, "gfimu", angular_velocity(
        y, rec.time, layout, methods=methods, observation=observation, initial=w0, noise_std=noise_std, lag=lag,
        bias_std=bias_std, smooth=smooth, plain=plain, rest=span, differential_max_u=differential_max_u))
    est = _rate_checked(est, y, layout)
    doc: dict = {
        "file": str(file), "n_samples": int(rec.n_samples), "sample_rate_hz": rec.sample_rate,
        "layout": {"channels": list(layout.names), "condition_number": est.condition_number,
                   "source": str(layout_file) if layout_file else f"paper, L = {0.04 if distance is None else distance} m"},
        "methods": list(est.omega), "observation": observation if "kalman" in est.omega else None,
        "initial_omega": list(w0),
        "noise_std_m_s2": dict(zip(layout.names, est.noise_std.tolist())),
        "differential_rejected": est.differential_rejected if "differential" in est.omega else None,
        "differential_max_u_rad_s": differential_max_u if "differential" in est.omega else None,
        "noise_scale": est.noise_scale,
    }
    if est.rest is not None:
        r = est.rest
        doc["rest"] = {"span_s": list(r.span), "n_samples": r.n, "spread_ratio": r.spread_ratio,
                       "offsets": {n: {"value": float(v), "u": float(u)}
                                   for n, v, u in zip(UNKNOWNS[3:], r.offsets, r.u_offsets)}}
    if est.filter is not None:
        f = est.filter
        doc["filter"] = {"observation": f.observation, "n_observed": f.n_observed, "n_dropped": f.n_dropped,
                         "n_gated": f.n_gated, "passes": f.passes, "smoothed": f.smoothed,
                         "constant_error_states": f.offsets is not None,
                         "median_u_omega": dict(zip(_AXES, np.median(f.u_omega, axis=1).tolist()))}
        if f.offsets is not None:
            doc["filter"]["bias_std_m_s2"] = (None if rest is not None else
                                              DEFAULT_BIAS_STD if bias_std is None else bias_std)
            doc["filter"]["offsets"] = {n: {"value": float(v), "u": float(u)}
                                        for n, v, u in zip(UNKNOWNS[3:], f.offsets, f.u_offsets)}
    w_true = q_true = None
    if truth is not None:
        w_true, q_true = _truth_on(rec.time, truth, attitude)
        stats = error_statistics(est.omega, w_true)
        doc["errors"] = {m: {ax: s.axis(i) for i, ax in enumerate(_AXES)} for m, s in stats.items()}
    q = None
    if attitude:
        src = "kalman" if "kalman" in est.omega else next(iter(est.omega))
        q0 = q_true[:, 0] if q_true is not None else (1.0, 0.0, 0.0, 0.0)
        q = integrate_attitude(est.omega[src], rec.time, q0)
        doc["attitude"] = {"method": src, "initial_quaternion": list(map(float, q0))}
        if q_true is not None:
            ae = attitude_error(q, q_true, rec.time)
            doc["attitude"].update(max_error_deg=ae.max_deg, final_error_deg=ae.final_deg,
                                   growth_deg_per_s=ae.growth_deg_per_s, position_drift_m=ae.position_drift_m)
    doc["warnings"] = list(est.warnings)
    return doc, rec, est, w_true, q


def _write_out(path: Path, rec: Recording, est, q) -> Path:
    chans: dict[str, np.ndarray] = {}
    single = len(est.omega) == 1
    for m, w in est.omega.items():
        for i, ax in enumerate(_AXES):
            chans[ax if single else f"{m}_{ax}"] = w[i]
    kin = est.kinematics
    for i, ax in enumerate("xyz"):
        chans[f"alpha_{ax}"] = kin.angular_acceleration[i]
    for i, ax in enumerate("xyz"):
        chans[f"f_{ax}"] = kin.specific_force[i]
    if q is not None:
        chans.update(zip(("qw", "qx", "qy", "qz"), q))
    out = Recording(channels=chans, t=rec.time, allow_nan=True)
    return write_recording(out, path)


@app.command("gfimu")
def gfimu_cmd(
    file: Annotated[Path, typer.Argument(help="Recording of the array's channels (m/s^2).")],
    layout_file: Annotated[Optional[Path], typer.Option("--layout", help="Layout table CSV: name,x,y,z,nx,ny,nz (m).")] = None,
    distance: Annotated[Optional[float], typer.Option("--distance", help="Mounting distance L of the paper's layout, m (default 0.04).")] = None,
    method: Annotated[str, typer.Option("--method", help="kalman, integration, sqrt, differential or all.")] = "kalman",
    observation: Annotated[str, typer.Option("--observation", help="Kalman observation: quadratic (EKF on the quadratic terms), sqrt or differential.")] = "quadratic",
    initial_omega: Annotated[Optional[str], typer.Option("--initial-omega", help="Angular velocity at the first sample WX,WY,WZ in rad/s (default 0,0,0).")] = None,
    truth: Annotated[Optional[Path], typer.Option("--truth", help="Truth CSV with t, wx, wy, wz (rad/s): adds error statistics.")] = None,
    attitude: Annotated[bool, typer.Option("--attitude", help="Integrate the angular velocity into a quaternion (qw qx qy qz).")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="Write t, w, alpha, f (and q) to this CSV.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="Plot the rates (and errors with --truth) to a PNG.")] = None,
    lag: Annotated[int, typer.Option("--lag", help="Span of the differential method in samples (1 = the paper's).")] = 1,
    noise_std: Annotated[Optional[float], typer.Option("--noise-std", help="Channel white-noise std in m/s^2 (default: estimated).")] = None,
    bias_std: Annotated[Optional[float], typer.Option("--bias-std", help="Standard uncertainty of each channel's constant error (bias) in m/s^2 (default 0.1): the quadratic filter estimates the constant errors of alpha and W, and u(w) includes them.")] = None,
    plain: Annotated[bool, typer.Option("--plain", help="The paper's plain filter without constant-error states: u(w) is white noise only and does NOT cover biased channels (warning constant-errors-ignored).")] = False,
    rest: Annotated[Optional[str], typer.Option("--rest", help="START:END in s of a segment where the body is at rest (e.g. 0:2): the constant errors of alpha and W are measured there and start the filter.")] = None,
    differential_max_u: Annotated[Optional[float], typer.Option("--differential-max-u", help="Differential method: reject samples whose standard uncertainty exceeds this many rad/s (absolute; the 3x-median rule alone passes gross errors on axes that hardly turn).")] = None,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="Offline: the Kalman estimate from the fixed-interval (RTS) smoother over the whole record instead of the causal filter.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Angular velocity of a rigid body from an accelerometer array (no gyroscope)."""
    if lag < 1:
        raise InputError(f"--lag must be at least 1 sample, got {lag}")
    # The filter works with variances; beyond 1e100 their products overflow to NaN rates.
    if noise_std is not None and not 0 < noise_std < 1e100:
        raise InputError(f"--noise-std must be a positive number in m/s^2 (below 1e100), got {noise_std:g}")
    if bias_std is not None and not 0 < bias_std < 1e100:
        raise InputError("--bias-std must be a positive number in m/s^2 (the channels' constant-error uncertainty)")
    if (bias_std is not None or rest is not None) and observation != "quadratic":
        raise InputError("--bias-std and --rest need --observation quadratic (the constant errors are states of that "
                         "filter)")
    if bias_std is not None and rest is not None:
        raise InputError("--rest measures the constant errors that --bias-std would only bound: give one of them")
    if plain and (bias_std is not None or rest is not None):
        raise InputError("--plain is the filter without constant-error states: drop --bias-std / --rest, or --plain")
    if differential_max_u is not None and not 0 < differential_max_u < float("inf"):
        raise InputError(f"--differential-max-u must be a positive rate in rad/s, got {differential_max_u:g}")
    doc, rec, est, w_true, q = run_gfimu(file, layout_file=layout_file, distance=distance, method=method,
                                         observation=observation, initial_omega=initial_omega, truth=truth,
                                         attitude=attitude, lag=lag, noise_std=noise_std,
                                         time_column=time_column, fs=fs, names=names, bias_std=bias_std,
                                         smooth=smooth, plain=plain, rest=rest,
                                         differential_max_u=differential_max_u, time_unit=time_unit)
    if out is not None:
        doc["out"] = str(_write_out(out, rec, est, q))
    if plot is not None:
        from senscal.gfimu.plots import plot_rates

        doc["plot"] = str(plot_rates(rec.time, est.omega, plot, truth=w_true, title=str(file.name)))
    if json_out:
        print_json(doc)
        emit_warnings(est.warnings, strict)
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
        console.print(table("Angular-velocity error vs truth (rad/s)",
                            ["method", "max |e| wx", "std wx", "max |e| wy", "std wy", "max |e| wz", "std wz"], rows))
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
    emit_warnings(est.warnings, strict)


@simulate_app.command("gfimu")
def simulate_gfimu_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    paper: Annotated[bool, typer.Option("--paper", help="The paper's set-up: 10 kHz, 10 s, 30 deg / 2 Hz about z, 1e-4 g bias, 1e-3 g noise, L = 0.04 m.")] = False,
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    fs: Annotated[Optional[float], typer.Option("--fs", help="Sample rate in Hz (default 10000 with --paper, else 1000).")] = None,
    duration: Annotated[Optional[float], typer.Option("--duration", help="Record length in s (default 10).")] = None,
    distance: Annotated[float, typer.Option("--distance", help="Mounting distance L, m.")] = 0.04,
    bias_g: Annotated[float, typer.Option("--bias-g", help="Per-channel constant error magnitude, g.")] = 1e-4,
    noise_g: Annotated[float, typer.Option("--noise-g", help="White-noise standard deviation, g.")] = 1e-3,
    position_error: Annotated[float, typer.Option("--position-error", help="Mounting position error std, m.")] = 0.0,
    direction_error: Annotated[float, typer.Option("--direction-error", help="Mounting direction error std, rad.")] = 0.0,
    direction_error_deg: Annotated[Optional[float], typer.Option("--direction-error-deg", help="Mounting direction error std, deg (instead of --direction-error).")] = None,
    rest: Annotated[float, typer.Option("--rest", help="Rest before the motion starts, s (mark it with 'senscal gfimu --rest 0:REST').")] = 0.0,
    offset: Annotated[Optional[str], typer.Option("--offset", help="Array origin relative to the rotation centre X,Y,Z in m (default 0.1,0,0 with --paper, else 0.05,-0.03,0.02).")] = None,
    amplitudes: Annotated[Optional[str], typer.Option("--amplitudes", help="Roll, pitch, yaw amplitudes R,P,Y in deg (default 0,0,30 with --paper, else 10,15,30).")] = None,
    freqs: Annotated[Optional[str], typer.Option("--freqs", help="Roll, pitch, yaw frequencies in Hz (default 1,1,2 with --paper, else 1.3,0.7,2).")] = None,
    linear_amplitude: Annotated[Optional[float], typer.Option("--linear-amplitude", help="Linear vibration of the rotation centre per axis, m/s^2 (default 0 with --paper, else 2).")] = None,
) -> None:
    """An accelerometer array on a moving rigid body: gfimu.csv, gfimu_truth.csv/.json, layout.csv."""
    from senscal.gfimu import write_layout
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
                                      offset_m=three(offset, "--offset"),
                                      amplitudes_deg=three(amplitudes, "--amplitudes"),
                                      freqs_hz=three(freqs, "--freqs"), linear_amplitude=linear_amplitude)
    paths = [write_recording(rec, out / "gfimu.csv"), write_recording(truth, out / "gfimu_truth.csv"),
             write_truth(info, out / "gfimu_truth.json"), write_layout(paper_layout(distance), out / "layout.csv")]
    console.print("wrote " + ", ".join(str(p) for p in paths))
