"""``senscal fit``: sine fit of every (or the chosen) channel of a recording (the job: :mod:`senscal.jobs.fit`)."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import app
from senscal.cli.common import (FsOpt, JsonOpt, NamesOpt, StrictOpt, TimeColumnOpt, console, emit_warnings,
                                print_json, table)
from senscal.cli.common import StartOpt, StopOpt, TimeUnitOpt
from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt, SensorOpt,
                                       StandardOpt, note_standards, save_if_requested, use_standards)
from senscal.jobs._base import with_read_options
from senscal.jobs.fit import FitOptions, fit


@with_read_options
def fit_options(*, channel=None, freq=None, harmonics=1, noise_model="auto", **_) -> FitOptions:
    """The fit job's options from ``senscal fit``'s parameters (output-only ones ignored)."""
    return FitOptions(channels=tuple(channel) if channel else None, freq=freq, harmonics=harmonics,
                      noise_model=noise_model)


JOB_OPTIONS = {"fit": fit_options}


@app.command("fit")
@units(freq='Hz')
def fit_cmd(
    file: Annotated[Path, typer.Argument(help="Recording file (CSV, Parquet, HDF5, TDMS, NPZ).")],
    channel: Annotated[Optional[List[str]], typer.Option("--channel", "-c", help="Channel to fit (repeatable); default: all.")] = None,
    freq: Annotated[Optional[str], typer.Option("--freq", help="Known frequency in Hz; estimated when omitted.")] = None,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Number of harmonics K (1 = fundamental).")] = 1,
    noise_model: Annotated[str, typer.Option(
        "--noise-model", help="auto: test the residual for whiteness and use the noise spectrum at the fitted "
        "frequency when it is coloured; white: residual variance only; coloured: always the spectrum.")] = "auto",
    strict: StrictOpt = False,
    time_column: TimeColumnOpt = "t",
    fs: FsOpt = None,
    names: NamesOpt = None,
    time_unit: TimeUnitOpt = None,
    start: StartOpt = None,
    stop: StopOpt = None,
    json_out: JsonOpt = False,
    save: SaveOpt = False,
    sensor: SensorOpt = None,
    db: DbOpt = None,
    create_sensor: CreateSensorOpt = None,
    date: DateOpt = None,
    operator: OperatorOpt = None,
    standard: StandardOpt = None,
) -> None:
    """Least-squares sine fit: amplitude, phase, offset, frequency with uncertainties."""
    opts = fit_options(channel=channel, freq=freq, harmonics=harmonics, noise_model=noise_model,
                       time_column=time_column, fs=fs, names=names, time_unit=time_unit, start=start, stop=stop)
    used_standards = use_standards(standard, db=db, date=date)
    result = fit(file, opts)
    save_if_requested(result, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date,
                      operator=operator, method=opts.method, input_files=[file], standards=used_standards)
    doc = result.to_dict()
    note_standards(doc, used_standards)  # doc["warnings"] (emitted below) gets standard-overdue
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
        for name, d in doc["channels"].items():
            for what in (d.get("instrument") or {}).get("handled", ()):
                console.print(f"{name}: {what}")
    emit_warnings(doc["warnings"], strict)
