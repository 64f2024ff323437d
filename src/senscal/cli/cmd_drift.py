"""``senscal drift`` and ``senscal simulate drift``."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import app, simulate_app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings, load,
                                print_json, progress_bar, split_names, table)
from senscal.cli.common import StartOpt, StopOpt
from senscal.cli.common import TimeUnitOpt
from senscal.errors import InputError
from senscal.io import Recording, write_recording
from senscal.jobs._base import with_read_options

# The set-up rules live with the job; re-exported for the callers that import them from here.
from senscal.jobs.drift import BIAS_DYNAMICS, PRESETS, drift_setup_for  # noqa: E402,F401

#: Rows per chunk read from standard input ('-') by default.
DEFAULT_CHUNK = 1000


@with_read_options
def _drift_options(*, preset: str = "redundant", channels: str | None = None, trusted: str | None = None,
                   covariate: str | None = None, model: Path | str | None = None, window: int | None = None,
                   smooth: bool = False, false_alarm_rate: float = 1e-4, signal: str = "random_walk",
                   signal_tau: float | None = None, signal_mean: float = 0.0, signal_tau_known: bool = False,
                   covariate_reference: float | None = None, covariate_lag: float | None = None,
                   bias_dynamics: str = "random_walk", true_value: float = 0.0, compare: bool = True, state: Path | str | None = None,
                   fit_levels: bool = False, levels_from_allan: bool = False, flush: bool = False, **_):
    """``DriftOptions`` from the command's keyword parameters (output-only ones ignored)."""
    from senscal.jobs.drift import DriftOptions

    return DriftOptions(
        preset=preset, channels=tuple(split_names(channels) or ()) or None, trusted=tuple(split_names(trusted) or ()),
        covariate=covariate, model=None if model is None else str(model), window=window, smooth=smooth,
        false_alarm_rate=false_alarm_rate, signal=signal, signal_tau=signal_tau, signal_mean=signal_mean,
        signal_tau_known=signal_tau_known, covariate_reference=covariate_reference, covariate_lag=covariate_lag, bias_dynamics=bias_dynamics,
        true_value=true_value, compare=compare, state=None if state is None else str(state), fit_levels=fit_levels,
        levels_from_allan=levels_from_allan, flush=flush)


def _batch_options(**params):
    """The job's options for ``senscal batch``, which runs files in parallel: no state to carry between them."""
    if params.get("state") is not None:
        raise InputError("--state carries one sensor's filter from file to file in order; senscal batch runs files "
                         "in parallel: run senscal drift FILE --state STATE once per file, oldest first")
    return _drift_options(**params)


# senscal batch refuses an option its builder does not name; without this, every option passed unchecked.
_batch_options.__signature__ = inspect.signature(_drift_options)  # type: ignore[attr-defined]

# What `senscal batch` turns the job's option words into (see senscal.jobs).
JOB_OPTIONS = {"drift": _batch_options}


@app.command("drift")
@units(signal_tau='s', false_alarm_rate='1/h', covariate_lag='s')
def drift_cmd(
    file: Annotated[Path, typer.Argument(help="Recording file (CSV, Parquet, HDF5, TDMS, NPZ), or - for CSV on standard input (read whole; with --state in chunks as it arrives, corrected CSV on standard output).")],
    preset: Annotated[str, typer.Option("--preset", help="redundant | covariate | known (true value known, e.g. a gyro at rest) | model.")],
    channels: Annotated[Optional[str], typer.Option("--channels", help="Measured channels, comma separated (default: all but the covariate).")] = None,
    trusted: Annotated[Optional[str], typer.Option("--trusted", help="Channels that do not drift (redundant preset), comma separated.")] = None,
    covariate: Annotated[Optional[str], typer.Option("--covariate", help="Covariate channel the bias is linear in (e.g. temperature).")] = None,
    model: Annotated[Optional[Path], typer.Option("--model", help="YAML model file (preset model).")] = None,
    window: Annotated[Optional[int], typer.Option("--window", help="Fixed-lag window L in samples (latency for accuracy).")] = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="Offline: use all data (RTS smoother).")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="CSV of t, NAME_corrected, NAME_bias, NAME_bias_std.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="PNG of raw, corrected and bias with its band.")] = None,
    false_alarm_rate: Annotated[str, typer.Option("--false-alarm-rate", help="Drift detector false alarms per hour per channel.")] = "1e-4",
    signal: Annotated[str, typer.Option("--signal", help="Model of the quantity: random_walk | gauss_markov.")] = "random_walk",
    signal_tau: Annotated[Optional[str], typer.Option("--signal-tau", help="Time constant of a gauss_markov quantity in s.")] = None,
    signal_mean: Annotated[float, typer.Option("--signal-mean", help="Known mean of a gauss_markov quantity.")] = 0.0,
    signal_tau_known: Annotated[bool, typer.Option("--signal-tau-known", help="The --signal-tau of a gauss_markov quantity is known; without it the result is averaged over the time constants the record allows (wider u).")] = False,
    covariate_reference: Annotated[Optional[float], typer.Option("--covariate-reference", help="Covariate value of zero bias (default: its mean, with a warning when that fixes the offset).")] = None,
    covariate_lag: Annotated[Optional[str], typer.Option("--covariate-lag", help="Known first-order lag between the covariate and the bias, in s (0: none, e.g. a sensor reading its own temperature); without it the result is averaged over the lags the record holds (wider u).")] = None,
    bias_dynamics: Annotated[str, typer.Option("--bias-dynamics", help="random_walk | ramp (bias plus a wandering slope: a linear drift without lag).")] = "random_walk",
    true_value: Annotated[float, typer.Option("--true-value", help="Preset known: the true reading of every channel (0 for a gyro at rest).")] = 0.0,
    compare: Annotated[bool, typer.Option("--compare/--no-compare", help="Also fit the alternative signal/bias models and warn when one has a lower AIC.")] = True,
    state: Annotated[Optional[Path], typer.Option("--state", help="Tracker state (.json or .npz): continued when it exists, started otherwise, written back atomically.")] = None,
    fit_levels: Annotated[bool, typer.Option("--fit-levels", help="With --state: estimate the noise levels again on this file (default: keep the state's).")] = False,
    levels_from_allan: Annotated[bool, typer.Option("--levels-from-allan", help="Start the noise-level estimation from Allan-deviation levels (white noise, random walks).")] = False,
    flush: Annotated[bool, typer.Option("--flush", help="With --state and --window: end of data, output the samples the window still holds.")] = False,
    chunk_size: Annotated[int, typer.Option("--chunk-size", help="With FILE '-' and --state: rows per chunk (the first chunk starts a new state).")] = DEFAULT_CHUNK,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Estimate and remove slowly drifting sensor biases (augmented Kalman filter)."""
    from senscal.io.guard import check_output
    from senscal.jobs.drift import drift

    opts = _drift_options(**{k: v for k, v in locals().items() if k not in ("file", "check_output", "drift")})
    if state is not None:
        check_output(state, suffixes=(".json", ".npz"), what="drift state")
        if plot is not None:
            raise InputError("--plot draws a one-pass result; leave it out with --state (use --out for the values)")
        if out is not None and str(file) != "-":
            from senscal.io.readers import FORMATS

            # Checked before the run: a run that fails on its --out must not have moved the state on.
            check_output(out, suffixes=tuple(FORMATS), what="--out")
            if Path(out).resolve() == Path(state).resolve():
                raise InputError(f"--out and --state name the same file {out}; give two names")
    if str(file) == "-" and state is not None:
        if out is not None or plot is not None or json_out:
            raise InputError("with '-' the corrected values go to standard output as CSV; leave out --out, --plot "
                             "and --json")
        if not chunk_size >= 1:
            raise InputError(f"--chunk-size must be >= 1, got {chunk_size}")
        _stream_stdin(opts, chunk_size, strict)
        return
    with progress_bar("estimating noise levels (likelihood evaluations)", None) as advance:
        res = drift(file, opts, progress=advance)
    if out is not None:
        t, cols, units = res.columns()
        write_recording(Recording(cols, t=t, units=units), out)
    if res.state is not None:
        # After the corrected values are written: a failed run leaves the state where it was.
        res.state.save(state)
    if plot is not None:
        from senscal.drift.plot import plot_drift

        rec = load(file, time_column=time_column, fs=fs, names=names, allow_nan=True, time_unit=time_unit,
                   start=start, stop=stop)
        chans = res.result.channels
        plot_drift(res.result, {c: rec[c] for c in chans}, plot, unit=rec.unit(chans[0]) if chans else "")
    doc = res.to_dict()
    if json_out:
        print_json(doc)
        emit_warnings(res.warnings, strict)
        return
    _print_tables(file, res, doc)
    for p in (out, plot, state):
        if p is not None:
            console.print(f"wrote {p}")
    emit_warnings(res.warnings, strict)


def _print_tables(file: Path, res, doc: dict) -> None:
    streamed = res.result is None
    rows = []
    for c, d in doc["channels"].items():
        if streamed:
            rows.append([c, d["bias"], 2 * d["bias_std"], d["t_s"]])
        else:
            rows.append([c, d["bias"], 2 * d["bias_std"], d["onset_t"], d["alarm_t"]])
    cols = ["channel", "final bias", "U bias"] + (["at t (s)"] if streamed else ["onset t (s)", "alarm t (s)"])
    console.print(table(f"Drift of {file} ({doc['method']}; U = expanded uncertainty, k=2)", cols, rows))
    for c, d in doc["channels"].items():
        terms = [[name, v["value"], 2 * v["std"]] for name, v in d["terms"].items()]
        if len(terms) > 1:
            console.print(table(f"{c}: bias terms (final)", ["term", "value", "U (k=2)"], terms))
    source = {True: "estimated", False: "from the state" if streamed else "given"}
    nrows = [[k, v["value"], None if v["std"] is None else 2 * v["std"],
              source[bool(v["estimated"])] + (" (at search bound)" if v["at_bound"] else "")]
             for k, v in doc["noise"].items()]
    console.print(table("Noise levels (std; random walks per sqrt(s))", ["parameter", "value", "U (k=2)", "source"], nrows))
    if streamed:
        st = doc["state"]
        console.print(f"state {st['how']}: {doc['n_samples']} samples in, {doc['n_output']} out, {st['pending']} "
                      f"held in the window; {st['n_samples_total']} samples since the state started "
                      f"(last t = {st['t_last_s']:g} s)")
        return
    check, comparison = res.result.check, res.result.comparison
    if check is not None:
        console.print(f"innovations: mean normalised square {check.nis:.3f} (1 under the model), whiteness "
                      f"p = {check.whiteness_p:.2g} ({check.lags} lags): "
                      + ("adequate" if check.adequate else "model rejected"))
    ta = res.result.tau_average
    if ta is not None:
        held = [tau for tau, w in zip(ta["taus"], ta["weights"]) if w > 0.01]
        console.print(f"signal tau: asked {ta['asked']:.4g} s, most likely {ta['most_likely']:.4g} s; "
                      + (f"averaged over {min(held):.3g}-{max(held):.3g} s by likelihood (in U; "
                         "--signal-tau-known to use the one given)" if ta["applied"] else
                         "not averaged (another model used)"))
    for c in comparison[1:]:
        console.print(f"alternative {c['model']}: AIC {c['aic'] - comparison[0]['aic']:+.1f} against the model "
                      + ("used (signal tau the most likely)" if ta is not None else "asked for"))
    if res.result.selected:
        console.print(f"model used: {res.result.selected} (lowest AIC"
                      + ("" if res.result.selected == "--noise ar1" else
                         "; the innovations rejected the model asked for") + ")")


def _stdin_chunks(chunk_size: int, opts):
    """Recordings of ``chunk_size`` rows each from CSV on standard input, as the rows arrive.

    Each chunk is parsed by the ordinary CSV reader (units in the header,
    separators, NaN) with the header line in front; a line is read as soon
    as it arrives, so a ``tail -f`` pipe is followed.
    """
    import sys
    import tempfile

    from senscal.errors import SenscalError
    from senscal.io import read_recording

    stream = sys.stdin
    if stream is None or stream.isatty():
        raise InputError("'-' means standard input, but nothing is piped in; use 'tail -f FILE.csv | senscal drift - "
                         "...' or give the file name")

    def readline() -> str:
        try:
            line = stream.readline()
            line.encode("utf-8")  # stdin decodes bad bytes to surrogates (surrogateescape): not UTF-8 text either
            return line
        except UnicodeEncodeError as exc:
            raise InputError(f"standard input is not UTF-8 text (bad bytes "
                             f"{exc.object[exc.start:exc.end].encode('utf-8', 'surrogateescape')!r}); "
                             "pipe CSV text, or give a binary recording as a file name") from None
        except UnicodeDecodeError as exc:
            raise InputError(f"standard input is not UTF-8 text (bad byte {exc.object[exc.start:exc.start + 1]!r}); "
                             "pipe CSV text, or give a binary recording as a file name") from None

    head = []
    while True:
        line = readline()
        if not line:
            raise InputError("standard input ended before a CSV header row")
        head.append(line)
        if line.strip() and not line.lstrip().startswith("#"):
            break
    n_seen = 0
    with tempfile.TemporaryDirectory(prefix="senscal-drift-") as folder:
        tmp = Path(folder) / "chunk.csv"
        while True:
            lines = []
            while len(lines) < chunk_size:
                line = readline()
                if not line:
                    break
                if line.strip():
                    lines.append(line if line.endswith("\n") else line + "\n")
            if not lines:
                return
            tmp.write_text("".join(head) + "".join(lines), encoding="utf-8")
            try:
                rec = read_recording(tmp, format="csv", time_column=opts.time_column, fs=opts.fs,
                                     names=split_names(opts.names), allow_nan=True, time_unit=opts.time_unit)
            except SenscalError as exc:
                raise type(exc)(str(exc).replace(str(tmp), f"standard input (rows {n_seen + 1}-{n_seen + len(lines)})")
                                ) from None
            # Without a time column every chunk starts at 0: its samples continue the count instead.
            offset = n_seen / opts.fs if opts.fs and opts.time_column not in rec.names else 0.0
            n_seen += len(lines)
            yield rec, rec.time + offset
            if len(lines) < chunk_size:
                return


def _stream_stdin(opts, chunk_size: int, strict: bool) -> None:
    """``senscal drift - --state S``: corrected CSV on stdout, flushed per chunk; the state saved after each chunk."""
    import sys

    from senscal.drift.stream import TrackerState
    from senscal.errors import TooFewSamplesError
    from senscal.jobs.drift import _arrays, drift_setup_for, start_tracker

    state_path = Path(opts.state)
    setup = tracker = None
    warnings: list[str] = []
    write = sys.stdout.write
    for rec, t in _stdin_chunks(chunk_size, opts):
        if setup is None:
            setup = drift_setup_for(rec, opts)
        y, _, cov = _arrays(rec, setup, "on standard input")
        if tracker is None:
            old = TrackerState.load(state_path) if state_path.exists() else None
            try:
                tracker, _, _, warnings = start_tracker(setup, y, t, cov, opts, old)
            except TooFewSamplesError as exc:
                if old is not None or rec.n_samples < chunk_size:
                    raise
                raise TooFewSamplesError(f"{exc} in the first chunk, which starts the state; give a larger "
                                         f"--chunk-size than {chunk_size}") from None
            write("t," + ",".join(f"{c}_corrected,{c}_bias,{c}_bias_std" for c in tracker.channels) + "\n")
        _write_rows(write, tracker.update(y, t, cov))
        sys.stdout.flush()
        tracker.state.save(state_path)
    if tracker is None:
        raise InputError("standard input has a header but no data rows")
    if opts.flush:
        _write_rows(write, tracker.flush())
        sys.stdout.flush()
        tracker.state.save(state_path)
    emit_warnings(warnings, strict)


def _write_rows(write, out) -> None:
    for k in range(out.n):
        vals = [out.t[k]] + [v for i in range(len(out.channels))
                             for v in (out.corrected[i, k], out.bias[i, k], out.u_bias[i, k])]
        write(",".join(repr(float(v)) for v in vals) + "\n")


@simulate_app.command("drift")
@units(days='day', dt='s', ramp_start_day='day', signal_tau='s', ramp_start_s='s', noise='kPa', ramp_rate='kPa/day')
def simulate_drift_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    days: Annotated[str, typer.Option("--days", help="Record length in days.")] = "10.0",
    dt: Annotated[str, typer.Option("--dt", help="Sample interval in s.")] = "300.0",
    noise: Annotated[str, typer.Option("--noise", help="Sensor noise standard deviation (kPa).")] = "0.05",
    ramp_start_day: Annotated[str, typer.Option("--ramp-start-day", help="Drift onset of channel 'drift' (day).")] = "4.0",
    ramp_rate: Annotated[str, typer.Option("--ramp-rate", help="Ramp slope of channel 'drift' (kPa/day).")] = "0.3",
    temperature_coefficient: Annotated[float, typer.Option("--temperature-coefficient", help="Thermal bias coefficient of channel 'thermal' (kPa/degC).")] = 0.04,
    layout: Annotated[str, typer.Option("--layout", help="three (ref/drift/thermal over days) | pair (s1 trusted, s2 biased) | known (one sensor g whose true value is 0) | covariate (one sensor x with a temperature-linked bias).")] = "three",
    samples: Annotated[int, typer.Option("--samples", help="Samples of the pair/known/covariate layouts.")] = 600,
    signal_tau: Annotated[Optional[str], typer.Option("--signal-tau", help="pair/covariate: the quantity is Gauss-Markov with this time constant in s (std 1) instead of a random walk (0.1/sqrt(s)).")] = None,
    bias: Annotated[str, typer.Option("--bias", help="pair/known: random_walk (0.01/sqrt(s)) | ramp | none.")] = "random_walk",
    ramp_start_s: Annotated[Optional[str], typer.Option("--ramp-start-s", help="pair/known with --bias ramp: onset in s (default: mid-record).")] = None,
    ramp_slope: Annotated[float, typer.Option("--ramp-slope", help="pair/known with --bias ramp: slope per s.")] = 4e-3,
    covariate_offset: Annotated[float, typer.Option("--covariate-offset", help="covariate layout: the sensor's offset at 20 degC.")] = 0.0,
) -> None:
    """Drifting sensors of a slowly varying quantity (drift.csv) and the truth (drift_truth.json)."""
    from senscal.simulate.common import write_truth
    from senscal.simulate.drift import simulate_drift, simulate_drift_batch

    if not (0 < days < float("inf") and 0 < dt < float("inf") and 0 < noise < float("inf")):
        raise InputError("--days, --dt and --noise must be > 0")
    layouts = ("three", "pair", "known", "covariate")
    if layout not in layouts:
        raise InputError(f"--layout must be one of {', '.join(layouts)}, got {layout!r}")
    if layout != "three":
        if bias not in ("random_walk", "ramp", "none"):
            raise InputError(f"--bias must be random_walk, ramp or none, got {bias!r}")
        if not 20 <= samples <= 10_000_000:
            raise InputError(f"--samples must be between 20 and 1e7, got {samples}")
        if signal_tau is not None and not 0 < signal_tau < float("inf"):
            raise InputError("--signal-tau must be > 0 (seconds)")
        for name, v in (("--ramp-slope", ramp_slope), ("--covariate-offset", covariate_offset),
                        ("--ramp-start-s", 0.0 if ramp_start_s is None else ramp_start_s)):
            if not abs(v) < float("inf"):
                raise InputError(f"{name} must be a finite number")
        kw: dict = dict(n=samples, dt=dt, noise=noise, bias=bias, ramp_start=ramp_start_s, ramp_slope=ramp_slope)
        if signal_tau is not None:
            kw.update(signal="gauss_markov", signal_level=1.0, signal_tau=signal_tau)
        if layout == "known":
            kw.update(channels=("g",), trusted=(), signal="known", signal_mean=0.0)
        elif layout == "covariate":
            kw.update(channels=("x",), trusted=(), bias="none", covariate_coefficient=temperature_coefficient,
                      covariate_offset=covariate_offset)
        d = simulate_drift_batch(1, seed=seed, **kw)
        ch = {c: d["y"][0, i] for i, c in enumerate(d["channels"])}
        if d["covariate"] is not None:
            ch["temperature"] = d["covariate"][0]
        rec = Recording(ch, t=d["t"], metadata={"simulator": f"drift/{layout}", "seed": seed})
        truth = {k: v for k, v in d.items() if k not in ("y", "signal", "bias", "covariate", "t")}
        truth.update({"signal": d["signal"][0], **{f"bias_{c}": d["bias"][0, i] for i, c in enumerate(d["channels"])}})
        p = write_recording(rec, out / "drift.csv")
        q = write_truth(truth, out / "drift_truth.json")
        console.print(f"wrote {p} and {q}")
        return
    if dt * 20 > days * 86400:
        raise InputError("--dt is too long for --days: fewer than 20 samples")
    rec, truth = simulate_drift(days=days, dt=dt, noise=noise, ramp_start_day=ramp_start_day,
                                ramp_rate_per_day=ramp_rate, temperature_coefficient=temperature_coefficient, seed=seed)
    p = write_recording(rec, out / "drift.csv")
    q = write_truth(truth, out / "drift_truth.json")
    console.print(f"wrote {p} and {q}")
