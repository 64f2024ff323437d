"""``senscal batch JOB FILES... [job options]``: one Dask task per recording."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

import typer
from typing_extensions import Annotated

from senscal.cli._quantities import units
from senscal.cli.app import app
from senscal.cli.common import console, err_console, print_json, progress_bar, table
from senscal.errors import InputError
from senscal.io.guard import atomic_output, check_output, note_input


# Parameters of a job's command that only make sense for one interactive run: files it writes next to its
# result, and the registry (a batch row keeps each recording's result; the rows go to batch's own --out).
_SINGLE_RUN = {"plot", "report", "out", "save_response", "pdf", "dcc", "certificate", "save", "sensor", "db",
               "create_sensor", "date", "operator", "standard"}
# Accepted and handled by batch itself: --json (rows are JSON already), --strict (fails the rows with warnings).
_BATCH_HANDLED = {"json_out", "strict"}


def _job_command(job: str) -> tuple[list[str], str]:
    """Command words and ``cmd_*`` module of a job: ``shaft-calibrate`` -> (["shaft", "calibrate"], "cmd_shaft")."""
    from senscal.cli._manifest_data import COMMANDS

    if job in COMMANDS:
        return [job], COMMANDS[job][0]
    for name, (module, _) in COMMANDS.items():
        if job.startswith(name + "-"):
            return [name, job[len(name) + 1:]], module
    raise InputError(f"job '{job}' has no command of its own in this version of senscal")


def job_options(job: str, first_file: str, words: list[str]) -> tuple[Any, bool]:
    """The job's Options from its option words, parsed by the job command's own parser.

    Parameters
    ----------
    job : str
        Job name (``fit``, ``shaft-calibrate`` ...).
    first_file : str
        A recording of the batch: the command's file argument while parsing.
    words : list of str
        The job's options as on its command line (``["--freq", "10"]``).

    Returns
    -------
    (options, strict)
        ``JOB_OPTIONS[job](**params)`` of the command's module, and whether
        ``--strict`` was given.

    Raises
    ------
    InputError
        Unknown job, a job whose command does not yet hand its options to the
        job layer, or an option that only makes sense for a single run.
    click.UsageError
        An option the job's command does not know (one line via ``senscal.cli.main``).
    """
    import importlib
    import inspect

    from senscal.batch import check_job

    check_job(job)
    cmd_words, module = _job_command(job)
    spelled = "senscal " + " ".join(cmd_words)
    mod = importlib.import_module(f"senscal.cli.{module}")
    builder = getattr(mod, "JOB_OPTIONS", {}).get(job)
    if builder is None:
        raise InputError(f"senscal batch cannot run '{job}' yet: its command does not hand its options to the job "
                         f"layer (no JOB_OPTIONS in senscal.cli.{module}); run '{spelled}' on each file")
    cmd = typer.main.get_command(app)
    for w in cmd_words:
        cmd = cmd.commands[w]  # type: ignore[attr-defined]
    for param in cmd.params:
        if param.required and param.name in _SINGLE_RUN:
            opt = param.opts[0]
            raise InputError(f"'{spelled}' writes each recording's result to its own {opt} file, which a batch "
                             f"cannot name; run '{spelled} FILE {opt} OUT ...' per recording (a shell loop)")
    ctx = cmd.make_context(spelled, [first_file, *words], resilient_parsing=False)
    sig = inspect.signature(builder).parameters.values()
    explicit = {p.name for p in sig if p.kind is not p.VAR_KEYWORD}
    for param in cmd.params:
        # Typer may vendor its own Click: classes and enums are compared by name.
        if param.param_type_name == "argument" or param.name in _BATCH_HANDLED:
            continue
        source = ctx.get_parameter_source(param.name)
        if getattr(source, "name", None) not in ("COMMANDLINE", "ENVIRONMENT"):
            continue
        opt = param.opts[0]
        if param.name in _SINGLE_RUN:
            raise InputError(f"{opt} applies to a single run of '{spelled}', not to a batch (each recording's "
                             f"result is a row of batch's --out table); run '{spelled} FILE {opt} ...' for it")
        if explicit and param.name not in explicit:
            # Silently dropping it would run the job differently from what was asked.
            raise InputError(f"{opt} of '{spelled}' is not an option of the '{job}' job that senscal batch runs "
                             f"on each recording; leave it out, or run '{spelled}' per file")
    from senscal.cli._quantities import convert_options

    # Quantity options ('80 mm') as the command itself converts them (senscal.cli._quantities).
    return builder(**convert_options(cmd.callback, ctx.params)), bool(ctx.params.get("strict"))


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
    everything from the first option on is the job's options (as its own
    command takes them; plots, reports and --save are for single runs).
    Exit code 0 when every recording succeeded, 4 when some failed.
    """
    from senscal.batch import expand_files, run_batch, write_rows

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
    # Parsed here, once: a typo fails before a cluster starts, and workers get typed options, not words.
    options, strict = job_options(job, files[0], extra)
    from senscal.cli.common import set_window

    # The job's --start/--stop window is the batch's: its --json summary says which part of each record was used.
    set_window(getattr(options, "start", None), getattr(options, "stop", None))
    with progress_bar(f"{job} on {len(files)} recordings", len(files)) as advance:
        summary = run_batch(job, files, options, workers=workers, scheduler=scheduler, files_per_task=files_per_task,
                            strict=strict, on_done=lambda r: advance())
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
@units(fs='Hz', freq='Hz')
def fit_array_cmd(
    file: Annotated[Path, typer.Argument(help="HDF5 file or Zarr store holding a 2-D dataset (channels x samples).")],
    dataset: Annotated[str, typer.Option("--dataset", help="Name of the 2-D dataset.")],
    out: Annotated[Path, typer.Option("--out", help="Per-channel results: .parquet or .csv.")],
    fs: Annotated[Optional[str], typer.Option("--fs", help="Sample rate in Hz (default: the dataset's 'fs' attribute).")] = None,
    time_dataset: Annotated[Optional[str], typer.Option("--time-dataset", help="1-D dataset of time stamps (s).")] = None,
    freq: Annotated[Optional[str], typer.Option("--freq", help="Known frequency in Hz; estimated per channel when omitted.")] = None,
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

    from senscal.batch.arrays import SUMMARY_FIELDS, check_stored_array, fit_stored_array

    if out.suffix.lower() not in (".parquet", ".pq", ".csv"):
        raise InputError(f"--out must end in .parquet or .csv, got {out.name}")
    if workers < 0:
        raise InputError(f"--workers must be 0 (threads in this process) or more, got {workers}")
    note_input(file)
    out = check_output(out)
    # Everything about the input is checked before a cluster starts (seconds, and workers that would all fail).
    shape = check_stored_array(file, dataset, fs=fs, time_dataset=time_dataset, freq=freq, harmonics=harmonics,
                               chunk_channels=chunk)[0]
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
        total = shape[0]
        with progress_bar(f"fitting {dataset}", total) as advance:
            res = fit_stored_array(file, dataset, fs=fs, time_dataset=time_dataset, freq=freq,
                                   harmonics=harmonics, chunk_channels=chunk, progress=advance)
    df = pd.DataFrame({"channel": np.arange(res.n_channels),
                       **{f: getattr(res, f) for f in SUMMARY_FIELDS}})
    df["phase_deg"] = np.degrees(df["phase"])
    df["u_phase_deg"] = np.degrees(df["u_phase"])
    with atomic_output(out, what="results table") as tmp:
        df.to_parquet(tmp, index=False) if out.suffix.lower() in (".parquet", ".pq") else df.to_csv(tmp, index=False)
    under = int(np.sum(res.under_dithered > 0))
    clipped = int(np.sum(res.n_clipped > 0))
    unhandled = int(np.sum((res.n_clipped > 0) & ~(res.clip_handled > 0)))
    summary = {"file": str(file), "dataset": dataset, "n_channels": res.n_channels, "n_samples": res.n_samples,
               "out": str(out), "amplitude_median": float(np.median(res.amplitude)),
               "u_amplitude_median": float(np.median(res.u_amplitude)),
               "n_clipped_channels": clipped, "n_clipped_unhandled": unhandled, "n_under_dithered": under}
    if json_out:
        print_json(summary)
    else:
        console.print(f"fitted {res.n_channels} channels x {res.n_samples} samples; results in {out}")
    # Per-channel flags are in the table (n_clipped, clip_handled, lsb, under_dithered); the count is said here.
    if clipped:
        err_console.print(f"[yellow]warning:[/yellow] clipped: {clipped} channel(s) clipped ({unhandled} not "
                          "handled: their amplitude and offset are biased); see n_clipped and clip_handled")
    if under:
        err_console.print(f"[yellow]warning:[/yellow] under-dithered: {under} channel(s) quantised with analogue "
                          "noise too small to dither the ADC; their u does not cover (see under_dithered)")
