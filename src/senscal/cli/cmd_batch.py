"""``senscal batch JOB FILES... [job options]``: one Dask task per recording."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app
from senscal.cli.common import console, err_console, print_json, progress_bar, table
from senscal.io.guard import atomic_output, check_output, note_input


# Job options that name a file the job writes (--out always belongs to batch itself).
_JOB_OUTPUTS = ("--plot", "--report", "--save-response")


def _check_job_outputs(options: list[str], n_files: int) -> None:
    """Refuse a job output file that every recording would overwrite, or that is a recording."""
    from senscal.errors import InputError

    for i, opt in enumerate(options):
        name, eq, value = opt.partition("=")
        if name not in _JOB_OUTPUTS:
            continue
        if not eq:
            value = options[i + 1] if i + 1 < len(options) else ""
        if n_files > 1:
            raise InputError(f"{name} {value} would be written by each of the {n_files} recordings in turn; "
                             f"run the job per file for its {name}")
        check_output(value)


@app.command(
    "batch",
    context_settings={"allow_extra_args": True, "ignore_unknown_options": True},
)
def batch_cmd(
    ctx: typer.Context,
    job: Annotated[str, typer.Argument(help="Per-recording job: fit, shaft-calibrate, triaxial-calibrate, drift, gfimu, ...")],
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="Address of an existing Dask scheduler.")] = None,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes of the local cluster.")] = 2,
    out: Annotated[Optional[Path], typer.Option("--out", help="Results table: RESULTS.parquet or .csv.")] = None,
    files_per_task: Annotated[int, typer.Option(
        "--files-per-task", help="Recordings per Dask task (1: one task each; more amortises the few ms Dask costs per task).")] = 1,
    json_out: Annotated[bool, typer.Option("--json", help="Print the summary and rows as JSON.")] = False,
) -> None:
    """Run a job over many recordings on Dask; failed recordings get their error in their row.

    Arguments after JOB that do not start with '-' are files or glob patterns;
    everything from the first option on is passed to the job. Exit code 0
    when every recording succeeded, 4 when some failed.
    """
    from senscal.batch import expand_files, run_batch
    from senscal.batch.core import write_rows
    from senscal.errors import InputError

    extra = list(ctx.args)
    files_part: list[str] = []
    while extra and not extra[0].startswith("-"):
        files_part.append(extra.pop(0))
    if not files_part:
        raise InputError("name at least one recording file or glob after the job")
    files = expand_files(files_part)
    # The recordings are read in worker processes: note them here so --out cannot overwrite one.
    for f in files:
        note_input(f)
    if out is not None:
        check_output(out)
    _check_job_outputs(extra, len(files))
    with progress_bar(f"{job} on {len(files)} recordings", len(files)) as advance:
        summary = run_batch(job, files, extra, workers=workers, scheduler=scheduler, files_per_task=files_per_task,
                            on_done=lambda r: advance())
    if out is not None:
        write_rows(summary, out)
    if json_out:
        print_json({"job": summary.job, "n_files": summary.n_files, "n_ok": summary.n_ok,
                    "n_failed": summary.n_failed, "workers": summary.workers,
                    "wall_seconds": summary.wall_seconds, "out": str(out) if out else None,
                    "rows": [r.to_dict() for r in summary.rows]})
    else:
        failed = [r for r in summary.rows if not r.ok]
        if failed:
            console.print(table("failed recordings", ["file", "error"], [[r.file, r.error] for r in failed[:50]]))
        console.print(f"{summary.n_ok} of {summary.n_files} recordings succeeded ({summary.n_failed} failed) "
                      f"on {summary.workers} workers in {summary.wall_seconds:.1f} s"
                      + (f"; results in {out}" if out else ""))
    if summary.n_failed:
        err_console.print(f"senscal: {summary.n_failed} of {summary.n_files} recordings failed")
        raise typer.Exit(4)


@app.command("fit-array")
def fit_array_cmd(
    file: Annotated[Path, typer.Argument(help="HDF5 file or Zarr store holding a 2-D dataset (channels x samples).")],
    dataset: Annotated[str, typer.Option("--dataset", help="Name of the 2-D dataset.")],
    out: Annotated[Path, typer.Option("--out", help="Per-channel results: .parquet or .csv.")],
    fs: Annotated[Optional[float], typer.Option("--fs", help="Sample rate in Hz (default: the dataset's 'fs' attribute).")] = None,
    time_dataset: Annotated[Optional[str], typer.Option("--time-dataset", help="1-D dataset of time stamps (s).")] = None,
    freq: Annotated[Optional[float], typer.Option("--freq", help="Known frequency in Hz; estimated per channel when omitted.")] = None,
    harmonics: Annotated[int, typer.Option("--harmonics", help="Number of harmonics.")] = 1,
    chunk: Annotated[int, typer.Option("--chunk", help="Channels per task.")] = 256,
    workers: Annotated[int, typer.Option("--workers", help="Worker processes of a local cluster (0: threads in this process).")] = 0,
    scheduler: Annotated[Optional[str], typer.Option("--scheduler", help="Address of an existing Dask scheduler.")] = None,
    json_out: Annotated[bool, typer.Option("--json", help="Print a JSON summary.")] = False,
) -> None:
    """Sine fit of every channel of an HDF5/Zarr array larger than memory, chunk by chunk on Dask."""
    import contextlib

    import numpy as np
    import pandas as pd

    from senscal.batch.arrays import SUMMARY_FIELDS, _store_info, fit_stored_array
    from senscal.errors import InputError

    if chunk < 1:
        raise InputError(f"--chunk must be at least 1, got {chunk}")
    if out.suffix.lower() not in (".parquet", ".pq", ".csv"):
        raise InputError(f"--out must end in .parquet or .csv, got {out.name}")
    stack = contextlib.ExitStack()
    with stack:
        if scheduler or workers > 0:
            from dask.distributed import Client, LocalCluster

            if scheduler:
                try:
                    stack.enter_context(Client(scheduler, timeout="10s"))
                except (OSError, ValueError, TypeError) as exc:  # TimeoutError is an OSError
                    raise InputError(f"cannot connect to the Dask scheduler {scheduler!r} "
                                     f"({type(exc).__name__}: {' '.join(str(exc).split())[:150]}); give an "
                                     "address like tcp://host:8786") from None
            else:
                cluster = stack.enter_context(LocalCluster(n_workers=workers, threads_per_worker=1,
                                                           dashboard_address=None, silence_logs=50))
                stack.enter_context(Client(cluster))
        total = _store_info(str(file), dataset, None)[0][0] if file.exists() else None
        with progress_bar(f"fitting {dataset}", total) as advance:
            res = fit_stored_array(file, dataset, fs=fs, time_dataset=time_dataset, freq=freq,
                                   harmonics=harmonics, chunk_channels=chunk, progress=advance)
    df = pd.DataFrame({"channel": np.arange(res.n_channels),
                       **{f: getattr(res, f) for f in SUMMARY_FIELDS}})
    df["phase_deg"] = np.degrees(df["phase"])
    df["u_phase_deg"] = np.degrees(df["u_phase"])
    note_input(file)
    out = check_output(out)
    with atomic_output(out, what="results table") as tmp:
        df.to_parquet(tmp, index=False) if out.suffix.lower() in (".parquet", ".pq") else df.to_csv(tmp, index=False)
    summary = {"file": str(file), "dataset": dataset, "n_channels": res.n_channels, "n_samples": res.n_samples,
               "out": str(out), "amplitude_median": float(np.median(res.amplitude)),
               "u_amplitude_median": float(np.median(res.u_amplitude))}
    if json_out:
        print_json(summary)
    else:
        console.print(f"fitted {res.n_channels} channels x {res.n_samples} samples; results in {out}")
