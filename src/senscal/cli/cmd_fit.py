"""``senscal fit``: sine fit of every (or the chosen) channel of a recording."""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli.app import app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings, load,
                                print_json, table)
from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt, quoted,
                                       save_if_requested)
from senscal.diagnostics import named, warning_name
from senscal.errors import DataError, InputError, SenscalError
from senscal.sinefit import SineFit, fit_sine

NOISE_MODELS = ("auto", "white", "coloured")


def fit_summary(fit: SineFit) -> dict:
    """The JSON fields of one channel's fit (CLI contract).

    ``phase_deg`` is the phase at t = 0 (the file's time origin);
    ``phase_centre_deg`` the phase at ``t_phase_centre_s``, the record's
    centre, which does not carry the frequency's lever arm.
    """
    d = {
        "frequency_hz": float(fit.frequency),
        "amplitude": float(fit.amplitude),
        "phase_deg": math.degrees(fit.phase),
        "offset": float(fit.offset),
        "u_frequency_hz": float(fit.u_frequency),
        "u_amplitude": float(fit.u_amplitude),
        "u_phase_deg": math.degrees(fit.u_phase),
        "u_offset": float(fit.u_offset),
        "residual_rms": float(fit.residual_rms),
        "snr_db": float(fit.snr_db),
        "n_samples": int(fit.n_samples),
        "phase_centre_deg": math.degrees(fit.phase_centre),
        "u_phase_centre_deg": math.degrees(fit.u_phase_centre),
        "t_phase_centre_s": float(fit.t_ref),
        "noise_model": str(fit.noise_model),
        "dof_effective": float(fit.dof_effective),
        "residual_lag1": float(fit.residual_lag1),
    }
    if fit.thd is not None:
        d["thd_percent"] = 100.0 * float(fit.thd)
        d["harmonic_amplitudes"] = np.asarray(fit.harmonic_amplitudes).tolist()
        d["harmonic_phases_deg"] = np.degrees(fit.harmonic_phases).tolist()
    return d


def not_a_signal(y: np.ndarray) -> str | None:
    """Why a column cannot hold a sine (None when it might).

    NaN/inf cannot be fitted; a constant column has nothing to fit; a column that changes by the same
    step every sample is a sample counter or a ramp (a scope's ``Sample``
    column), whose spectrum peaks at the lowest bin and whose fit fails
    with a misleading "record too short".
    """
    y = np.asarray(y, dtype=float)
    bad = np.flatnonzero(~np.isfinite(y))
    if bad.size:
        more = f" (and {bad.size - 1} more)" if bad.size > 1 else ""
        kind = "NaN" if np.isnan(y[bad[0]]) else "inf"
        return f"it has {kind} at sample {bad[0]}{more}; remove or interpolate the bad samples"
    finite = y
    if finite.size and np.ptp(finite) == 0.0:
        return f"it is constant ({finite[0]:g}): there is no signal to fit"
    if y.size > 2:
        d = np.diff(y)
        if d[0] != 0.0 and np.ptp(d) <= 1e-9 * abs(d[0]):
            return (f"it rises by the same step ({d[0]:g}) every sample: a sample counter or ramp, not a signal; "
                    f"leave it out with --channel")
    return None


def _fit_one(y, t, freq, harmonics, noise_model):
    return fit_sine(y, t, freq=freq, harmonics=harmonics, noise_model=noise_model)


def fit_recording(path: Path, *, channels: list[str] | None, freq: float | None, harmonics: int,
                  time_column: str, fs: float | None, names: str | None, noise_model: str = "auto") -> dict:
    """Fit a file's channels; returns the JSON document of ``senscal fit``.

    A channel that cannot be fitted (constant, a sample counter, NaN, no
    sinusoid ...) is left out with a ``channel-not-fitted`` warning naming it
    and the reason; the command fails only when no channel can be fitted.
    """
    if noise_model not in NOISE_MODELS:
        raise InputError(f"--noise-model must be one of {', '.join(NOISE_MODELS)}, got {noise_model!r}")
    # NaN in one channel should not stop the others: checked per channel below.
    rec = load(path, time_column=time_column, fs=fs, names=names, channels=channels, allow_nan=True)
    chans = list(rec.names)
    y = rec.data(chans)
    failed: dict[str, SenscalError] = {}
    reasons: dict[str, str] = {}
    for i, c in enumerate(chans):
        why = not_a_signal(y[i])
        if why is not None:
            reasons[c] = why
            failed[c] = DataError(f"channel {c!r} cannot be fitted: {why}")
    good = [i for i, c in enumerate(chans) if c not in failed]
    fits: dict[str, SineFit] = {}
    if freq is not None and good:
        try:
            res = fit_sine(y[good], rec.time, freq=freq, harmonics=harmonics, noise_model=noise_model)
            fits = {chans[i]: res.channel(j) for j, i in enumerate(good)}
        except SenscalError:
            fits = {}  # find out which channel: one by one below
    if not fits:
        for i in good:
            try:
                fits[chans[i]] = _fit_one(y[i], rec.time, freq, harmonics, noise_model)
            except InputError as exc:
                if "Nyquist" in str(exc) and freq is not None:
                    raise  # an argument error, the same for every channel
                failed[chans[i]] = exc
                reasons[chans[i]] = str(exc)
            except SenscalError as exc:
                failed[chans[i]] = exc
                reasons[chans[i]] = str(exc)
    if not fits:
        if len(failed) == 1:
            raise next(iter(failed.values()))
        detail = "; ".join(f"{c!r}: {r}" for c, r in reasons.items())
        raise DataError(f"no channel of {path} could be fitted ({detail})")
    warnings = []
    for c, f in fits.items():
        for w in f.warnings:
            nm = warning_name(w)
            warnings.append(named(nm, f"channel {c!r}: {w[len(nm) + 2:]}") if nm else f"channel {c!r}: {w}")
    for c, r in reasons.items():
        warnings.append(named("channel-not-fitted", f"channel {c!r} was not fitted: {r}"))
    doc = {"file": str(path), "channels": {c: fit_summary(fits[c]) for c in chans if c in fits}}
    if reasons:
        doc["not_fitted"] = dict(reasons)
    doc["warnings"] = warnings
    return doc


def fit_quantities(doc: dict) -> list:
    """The registry quantities of a fit: amplitude, phase, offset, frequency per channel."""
    return [quoted(doc, f"{ch}.{name}", f"channels.{ch}.{key}", f"channels.{ch}.u_{key}", unit)
            for ch in doc["channels"]
            for name, key, unit in (("amplitude", "amplitude", ""), ("phase", "phase_deg", "deg"),
                                    ("offset", "offset", ""), ("frequency", "frequency_hz", "Hz"))]


@app.command("fit")
def fit_cmd(
    file: Annotated[Path, typer.Argument(help="Recording file (CSV, Parquet, HDF5, TDMS, NPZ).")],
    channel: Annotated[Optional[List[str]], typer.Option("--channel", "-c", help="Channel to fit (repeatable); default: all.")] = None,
    freq: Annotated[Optional[float], typer.Option("--freq", help="Known frequency in Hz; estimated when omitted.")] = None,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Number of harmonics K (1 = fundamental).")] = 1,
    noise_model: Annotated[str, typer.Option(
        "--noise-model", help="auto: test the residual for whiteness and use the noise spectrum at the fitted "
        "frequency when it is coloured; white: residual variance only; coloured: always the spectrum.")] = "auto",
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    json_out: JsonOpt = False,
    save: SaveOpt = False,
    sensor: SensorOpt = None,
    db: DbOpt = None,
    create_sensor: CreateSensorOpt = None,
    date: DateOpt = None,
    operator: OperatorOpt = None,
) -> None:
    """Least-squares sine fit: amplitude, phase, offset, frequency with uncertainties."""
    doc = fit_recording(file, channels=channel, freq=freq, harmonics=harmonics,
                        time_column=time_column, fs=fs, names=names, noise_model=noise_model)
    save_if_requested(doc, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date, operator=operator,
                      job="fit", method=f"sine-fit, {harmonics} harmonic(s), frequency {'known' if freq else 'estimated'}",
                      quantities=lambda: fit_quantities(doc), input_files=[file])
    if json_out:
        print_json(doc)
    else:
        # With a given frequency the centre phase adds nothing (same u): shown only when f is estimated.
        centre = freq is None
        rows = []
        for name, d in doc["channels"].items():
            rows.append([name, d["frequency_hz"], 2 * d["u_frequency_hz"], d["amplitude"], 2 * d["u_amplitude"],
                         d["phase_deg"], 2 * d["u_phase_deg"]]
                        + ([d["phase_centre_deg"], 2 * d["u_phase_centre_deg"]] if centre else [])
                        + [d["offset"], 2 * d["u_offset"], d["residual_rms"], f"{d['snr_db']:.1f}"]
                        + ([f"{d['thd_percent']:.3g}"] if "thd_percent" in d else []))
        cols = (["channel", "f (Hz)", "U f", "amplitude", "U amp", "phase t=0 (deg)", "U phase"]
                + (["phase centre (deg)", "U phase c"] if centre else [])
                + ["offset", "U offset", "resid RMS", "SNR dB"] + (["THD %"] if harmonics > 1 else []))
        console.print(table(f"Sine fit of {file}  (U = expanded uncertainty, k=2)", cols, rows))
        if centre:
            t_c = next(iter(doc["channels"].values()))["t_phase_centre_s"]
            console.print(f"phase t=0: at the file's time origin; phase centre: at the record centre t = {t_c:.9g} s")
        coloured = [c for c, d in doc["channels"].items() if d["noise_model"] == "coloured"]
        if coloured:
            console.print(f"coloured noise (u from the noise spectrum at the fitted frequency): {', '.join(coloured)}")
    emit_warnings(doc["warnings"], strict)
