"""``senscal fit``: sine fit of every (or the chosen) channel of a recording."""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer
from typing_extensions import Annotated

from senscal.cli.app import app
from senscal.cli.common import FsOpt, JsonOpt, NamesOpt, TimeColumnOpt, console, load, print_json, table
from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt, quoted,
                                       save_if_requested)
from senscal.sinefit import SineFit, fit_sine


def fit_summary(fit: SineFit) -> dict:
    """The JSON fields of one channel's fit (CLI contract)."""
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
    }
    if fit.thd is not None:
        d["thd_percent"] = 100.0 * float(fit.thd)
        d["harmonic_amplitudes"] = np.asarray(fit.harmonic_amplitudes).tolist()
        d["harmonic_phases_deg"] = np.degrees(fit.harmonic_phases).tolist()
    return d


def fit_recording(path: Path, *, channels: list[str] | None, freq: float | None, harmonics: int,
                  time_column: str, fs: float | None, names: str | None) -> dict:
    """Fit a file's channels; returns the JSON document of ``senscal fit``."""
    rec = load(path, time_column=time_column, fs=fs, names=names, channels=channels)
    chans = rec.names
    y = rec.data(chans)
    if freq is not None:
        res = fit_sine(y, rec.time, freq=freq, harmonics=harmonics)
        fits = [res.channel(i) for i in range(len(chans))]
    else:
        # Each channel gets its own frequency estimate.
        fits = [fit_sine(y[i], rec.time, harmonics=harmonics) for i in range(len(chans))]
    return {"file": str(path), "channels": {c: fit_summary(f) for c, f in zip(chans, fits)}}


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
                        time_column=time_column, fs=fs, names=names)
    save_if_requested(doc, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date, operator=operator,
                      job="fit", method=f"sine-fit, {harmonics} harmonic(s), frequency {'known' if freq else 'estimated'}",
                      quantities=lambda: fit_quantities(doc), input_files=[file])
    if json_out:
        print_json(doc)
        return
    rows = []
    for name, d in doc["channels"].items():
        rows.append([name, d["frequency_hz"], 2 * d["u_frequency_hz"], d["amplitude"], 2 * d["u_amplitude"],
                     d["phase_deg"], 2 * d["u_phase_deg"], d["offset"], 2 * d["u_offset"], d["residual_rms"],
                     f"{d['snr_db']:.1f}"] + ([f"{d['thd_percent']:.3g}"] if "thd_percent" in d else []))
    cols = ["channel", "f (Hz)", "U f", "amplitude", "U amp", "phase (deg)", "U phase", "offset", "U offset",
            "resid RMS", "SNR dB"] + (["THD %"] if harmonics > 1 else [])
    console.print(table(f"Sine fit of {file}  (U = expanded uncertainty, k=2)", cols, rows))
