"""``senscal drift`` and ``senscal simulate drift``."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli.app import app, simulate_app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings, load,
                                print_json, progress_bar, split_names, table)
from senscal.cli.common import TimeUnitOpt, time_checked
from senscal.errors import InputError
from senscal.io import Recording, write_recording

PRESETS = ("redundant", "covariate", "known", "model")
BIAS_DYNAMICS = ("random_walk", "ramp")


def drift_setup_for(rec: Recording, preset: str, *, channels: list[str] | None, trusted: list[str],
                    covariate: str | None, model: Path | None, signal: str, signal_tau: float | None,
                    signal_mean: float, covariate_reference: float | None, bias_dynamics: str = "random_walk",
                    true_value: float = 0.0):
    """Build the DriftSetup a preset and its options describe."""
    from senscal.drift import covariate_setup, known_setup, load_model_yaml, redundant_setup

    if bias_dynamics not in BIAS_DYNAMICS:
        raise InputError(f"--bias-dynamics must be one of {', '.join(BIAS_DYNAMICS)}, got {bias_dynamics!r}")

    if preset not in PRESETS:
        raise InputError(f"--preset must be one of {', '.join(PRESETS)}, got {preset!r}")
    if preset == "model":
        if model is None:
            raise InputError("--preset model needs --model FILE.yaml")
        return load_model_yaml(model)
    if model is not None:
        raise InputError("--model is only used with --preset model")
    if covariate is not None and covariate not in rec:
        raise InputError(f"covariate channel '{covariate}' is not in the file (channels: {', '.join(rec.names)})")
    chans = channels or [c for c in rec.names if c != covariate]
    if preset == "known":
        if trusted:
            raise InputError("--trusted is for the redundant preset; with --preset known every channel's true "
                             "value is --true-value")
        return known_setup(chans, true_value, bias_dynamics=bias_dynamics, covariate=covariate,
                           covariate_reference=covariate_reference)
    kw = dict(signal=signal, signal_tau=signal_tau, signal_mean=signal_mean, covariate_reference=covariate_reference)
    if preset == "covariate":
        if covariate is None:
            raise InputError("--preset covariate needs --covariate NAME (the channel the bias follows)")
        if trusted:
            raise InputError("--trusted is for the redundant preset; the covariate preset has one sensor")
        if bias_dynamics != "random_walk":
            raise InputError("--bias-dynamics is for the additive biases of the redundant and known presets; the "
                             "covariate preset has only a covariate-linked bias")
        if len(chans) != 1:
            raise InputError(f"--preset covariate corrects one sensor; choose it with --channels (got {', '.join(chans)})")
        return covariate_setup(chans[0], covariate, **kw)
    return redundant_setup(chans, trusted, covariate=covariate, bias_dynamics=bias_dynamics, **kw)


@app.command("drift")
def drift_cmd(
    file: Annotated[Path, typer.Argument(help="Recording file (CSV, Parquet, HDF5, TDMS, NPZ).")],
    preset: Annotated[str, typer.Option("--preset", help="redundant | covariate | known (true value known, e.g. a gyro at rest) | model.")],
    channels: Annotated[Optional[str], typer.Option("--channels", help="Measured channels, comma separated (default: all but the covariate).")] = None,
    trusted: Annotated[Optional[str], typer.Option("--trusted", help="Channels that do not drift (redundant preset), comma separated.")] = None,
    covariate: Annotated[Optional[str], typer.Option("--covariate", help="Covariate channel the bias is linear in (e.g. temperature).")] = None,
    model: Annotated[Optional[Path], typer.Option("--model", help="YAML model file (preset model).")] = None,
    window: Annotated[Optional[int], typer.Option("--window", help="Fixed-lag window L in samples (latency for accuracy).")] = None,
    smooth: Annotated[bool, typer.Option("--smooth", help="Offline: use all data (RTS smoother).")] = False,
    out: Annotated[Optional[Path], typer.Option("--out", help="CSV of t, NAME_corrected, NAME_bias, NAME_bias_std.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", help="PNG of raw, corrected and bias with its band.")] = None,
    false_alarm_rate: Annotated[float, typer.Option("--false-alarm-rate", help="Drift detector false alarms per hour per channel.")] = 1e-4,
    signal: Annotated[str, typer.Option("--signal", help="Model of the quantity: random_walk | gauss_markov.")] = "random_walk",
    signal_tau: Annotated[Optional[float], typer.Option("--signal-tau", help="Time constant of a gauss_markov quantity in s.")] = None,
    signal_mean: Annotated[float, typer.Option("--signal-mean", help="Known mean of a gauss_markov quantity.")] = 0.0,
    covariate_reference: Annotated[Optional[float], typer.Option("--covariate-reference", help="Covariate value of zero bias (default: its mean, with a warning when that fixes the offset).")] = None,
    bias_dynamics: Annotated[str, typer.Option("--bias-dynamics", help="random_walk | ramp (bias plus a wandering slope: a linear drift without lag).")] = "random_walk",
    true_value: Annotated[float, typer.Option("--true-value", help="Preset known: the true reading of every channel (0 for a gyro at rest).")] = 0.0,
    compare: Annotated[bool, typer.Option("--compare/--no-compare", help="Also fit the alternative signal/bias models and warn when one has a lower AIC.")] = True,
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Estimate and remove slowly drifting sensor biases (augmented Kalman filter)."""
    from senscal.drift import correct_drift

    if window is not None and smooth:
        raise InputError("choose either --window or --smooth, not both")
    rec = load(file, time_column=time_column, fs=fs, names=names, allow_nan=True, time_unit=time_unit)
    setup = drift_setup_for(rec, preset, channels=split_names(channels), trusted=split_names(trusted) or [],
                            covariate=covariate, model=model, signal=signal, signal_tau=signal_tau,
                            signal_mean=signal_mean, covariate_reference=covariate_reference,
                            bias_dynamics=bias_dynamics, true_value=true_value)
    for c in list(setup.channels) + setup.covariates:
        if c not in rec:
            raise InputError(f"channel '{c}' is not in {file} (channels: {', '.join(rec.names)})")
    cov = {c: rec[c] for c in setup.covariates}
    with progress_bar("estimating noise levels (likelihood evaluations)", None) as advance:
        res = time_checked(rec, "drift", correct_drift(
            setup, rec.data(list(setup.channels)), rec.time, cov, window=window, smooth=smooth,
            false_alarm_rate=false_alarm_rate, compare=compare, progress=advance))
    if out is not None:
        cols: dict[str, np.ndarray] = {}
        for i, c in enumerate(res.channels):
            cols[f"{c}_corrected"] = res.corrected[i]
            cols[f"{c}_bias"] = res.bias[i]
            cols[f"{c}_bias_std"] = res.bias_std[i]
        units = {}
        for c in res.channels:
            u = rec.unit(c)
            units.update({f"{c}_corrected": u, f"{c}_bias": u, f"{c}_bias_std": u})
        write_recording(Recording(cols, t=rec.time, units=units), out)
    if plot is not None:
        from senscal.drift.plot import plot_drift

        plot_drift(res, {c: rec[c] for c in res.channels}, plot, unit=rec.unit(res.channels[0]) if res.channels else "")
    doc = {"file": str(file), "preset": preset, **res.summary()}
    if json_out:
        print_json(doc)
        emit_warnings(res.warnings, strict)
        return
    rows = []
    for c, d in doc["channels"].items():
        rows.append([c, d["bias"], 2 * d["bias_std"], d["onset_t"], d["alarm_t"]])
    console.print(table(f"Drift of {file} ({res.method}; U = expanded uncertainty, k=2)",
                        ["channel", "final bias", "U bias", "onset t (s)", "alarm t (s)"], rows))
    for c, d in doc["channels"].items():
        terms = [[name, v["value"], 2 * v["std"]] for name, v in d["terms"].items()]
        if len(terms) > 1:
            console.print(table(f"{c}: bias terms (final)", ["term", "value", "U (k=2)"], terms))
    nrows = [[k, v["value"], None if v["std"] is None else 2 * v["std"],
              "estimated" + (" (at search bound)" if v["at_bound"] else "") if v["estimated"] else "given"]
             for k, v in doc["noise"].items()]
    console.print(table("Noise levels (std; random walks per sqrt(s))", ["parameter", "value", "U (k=2)", "source"], nrows))
    if res.check is not None:
        console.print(f"innovations: mean normalised square {res.check.nis:.3f} (1 under the model), whiteness "
                      f"p = {res.check.whiteness_p:.2g} ({res.check.lags} lags): "
                      + ("adequate" if res.check.adequate else "model rejected"))
    for c in res.comparison[1:]:
        console.print(f"alternative {c['model']}: AIC {c['aic'] - res.comparison[0]['aic']:+.1f} against the model used")
    for p in (out, plot):
        if p is not None:
            console.print(f"wrote {p}")
    emit_warnings(res.warnings, strict)


@simulate_app.command("drift")
def simulate_drift_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    days: Annotated[float, typer.Option("--days", help="Record length in days.")] = 10.0,
    dt: Annotated[float, typer.Option("--dt", help="Sample interval in s.")] = 300.0,
    noise: Annotated[float, typer.Option("--noise", help="Sensor noise standard deviation (kPa).")] = 0.05,
    ramp_start_day: Annotated[float, typer.Option("--ramp-start-day", help="Drift onset of channel 'drift' (day).")] = 4.0,
    ramp_rate: Annotated[float, typer.Option("--ramp-rate", help="Ramp slope of channel 'drift' (kPa/day).")] = 0.3,
    temperature_coefficient: Annotated[float, typer.Option("--temperature-coefficient", help="Thermal bias coefficient of channel 'thermal' (kPa/degC).")] = 0.04,
    layout: Annotated[str, typer.Option("--layout", help="three (ref/drift/thermal over days) | pair (s1 trusted, s2 biased) | known (one sensor g whose true value is 0) | covariate (one sensor x with a temperature-linked bias).")] = "three",
    samples: Annotated[int, typer.Option("--samples", help="Samples of the pair/known/covariate layouts.")] = 600,
    signal_tau: Annotated[Optional[float], typer.Option("--signal-tau", help="pair/covariate: the quantity is Gauss-Markov with this time constant in s (std 1) instead of a random walk (0.1/sqrt(s)).")] = None,
    bias: Annotated[str, typer.Option("--bias", help="pair/known: random_walk (0.01/sqrt(s)) | ramp | none.")] = "random_walk",
    ramp_start_s: Annotated[Optional[float], typer.Option("--ramp-start-s", help="pair/known with --bias ramp: onset in s (default: mid-record).")] = None,
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
