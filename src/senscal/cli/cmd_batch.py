"""``senscal batch JOB FILES... [job options]``: one Dask task per recording."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app
from senscal.cli.common import console, err_console, print_json, progress_bar, table


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
    with progress_bar(f"{job} on {len(files)} recordings", len(files)) as advance:
        summary = run_batch(job, files, extra, workers=workers, scheduler=scheduler, on_done=lambda r: advance())
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
