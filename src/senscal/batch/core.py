"""Batch execution of per-recording jobs on a Dask cluster.

Each worker calls the job function (:func:`senscal.jobs.run`) with the
job's typed options; a row holds ``result.to_dict()``, the document
``senscal JOB --json`` prints.  Nothing here imports the command line.
"""

from __future__ import annotations

import glob
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from senscal._result import ResultMixin
from senscal.errors import InputError, SenscalError

__all__ = ["BatchRow", "BatchSummary", "batch_jobs", "check_job", "expand_files", "flatten", "run_one", "run_many",
           "run_batch", "rows_table", "write_rows"]


@dataclass(frozen=True)
class BatchRow(ResultMixin):
    """One recording's outcome: ``ok`` with the job's JSON document, or its one-line error."""

    file: str
    ok: bool
    error: str | None
    result: dict[str, Any] | None
    seconds: float


@dataclass(frozen=True)
class BatchSummary(ResultMixin):
    """What a batch did."""

    job: str
    n_files: int
    n_ok: int
    n_failed: int
    workers: int
    wall_seconds: float
    rows: tuple[BatchRow, ...] = field(repr=False, default=())


def expand_files(patterns: Iterable[str]) -> list[str]:
    """Expand globs (``**`` allowed); keep order, drop duplicates.

    Raises
    ------
    InputError
        When a pattern matches nothing.
    """
    out: list[str] = []
    seen = set()
    for pat in patterns:
        matches = sorted(glob.glob(pat, recursive=True)) if glob.has_magic(pat) else [pat]
        if not matches:
            raise InputError(f"no file matches '{pat}'; check the pattern (quote it so the shell does not expand it)")
        for m in matches:
            if m not in seen:
                seen.add(m)
                out.append(m)
    if not out:
        raise InputError("no recordings given; name files or glob patterns")
    return out


# Jobs that combine several recordings into one result: one task per recording cannot run them.
NOT_PER_RECORDING = {"linearity": "combines one recording per input level into one straight line"}


def batch_jobs() -> list[str]:
    """Names of the per-recording jobs ``senscal batch`` can run (the job table of :mod:`senscal.jobs`)."""
    from senscal import jobs

    return [j for j in jobs.names() if j not in NOT_PER_RECORDING]


def check_job(job: str) -> str:
    """``job`` if it names a job of :mod:`senscal.jobs`.

    Raises
    ------
    InputError
        For a name that is not a job, listing the jobs.
    """
    if job in NOT_PER_RECORDING:
        raise InputError(f"'{job}' {NOT_PER_RECORDING[job]}, so senscal batch (one task per recording) cannot "
                         f"run it; run 'senscal {job} FILES...' on each set")
    jobs = batch_jobs()
    if job not in jobs:
        raise InputError(f"unknown batch job '{job}'; jobs are: {', '.join(jobs)}")
    return job


def run_one(job: str, file: str, options: Any = None, *, strict: bool = False) -> BatchRow:
    """Run one job on one recording in this process; never raises for a job failure.

    Parameters
    ----------
    job : str
        Job name (``fit``, ``shaft-calibrate`` ...).
    file : str
        The recording.
    options : dataclass, optional
        The job's options (``FitOptions(freq=10.0)`` ...); None for its defaults.
    strict : bool
        A recording whose result carries named warnings fails (as ``--strict``
        makes the single command exit 3), its row naming the first warning.

    Returns
    -------
    BatchRow
        ``ok`` with ``result.to_dict()``, or the one-line error.
    """
    from senscal import jobs
    from senscal.errors import DiagnosticError
    from senscal.io.guard import note_input, protect_inputs

    t0 = time.perf_counter()
    try:
        # The recording is an input of the job: nothing the job writes may replace it.
        with protect_inputs():
            note_input(file)
            result = jobs.run(job, file, options)
        if strict and result.warnings:
            more = f" (and {len(result.warnings) - 1} more)" if len(result.warnings) > 1 else ""
            raise DiagnosticError(f"--strict: {result.warnings[0]}{more}")
        return BatchRow(file=file, ok=True, error=None, result=result.to_dict(), seconds=time.perf_counter() - t0)
    except SenscalError as exc:
        msg = str(exc)
    except OSError as exc:
        # An unreadable recording (permission, vanished file) is that recording's problem, not a bug.
        msg = f"{exc.filename}: {(exc.strerror or type(exc).__name__).lower()}" if exc.filename else str(exc)
    except Exception as exc:  # a bug in one job: one line in its row, the batch goes on
        msg = f"internal error ({type(exc).__name__}: {exc}); please report it"
    return BatchRow(file=file, ok=False, error=" ".join(msg.split()), result=None, seconds=time.perf_counter() - t0)


def run_many(job: str, files: Sequence[str], options: Any = None, strict: bool = False) -> list[BatchRow]:
    """:func:`run_one` over several files in one task (amortises per-task scheduling)."""
    return [run_one(job, f, options, strict=strict) for f in files]


def flatten(doc: Any, prefix: str = "") -> dict[str, Any]:
    """Flatten nested JSON into ``a.b.c`` keys (lists of scalars stay lists as JSON text)."""
    out: dict[str, Any] = {}
    if isinstance(doc, dict):
        for k, v in doc.items():
            out.update(flatten(v, f"{prefix}{k}."))
    elif isinstance(doc, list):
        if all(not isinstance(v, (dict, list)) for v in doc):
            out[prefix[:-1]] = json.dumps(doc)
        else:
            for i, v in enumerate(doc):
                out.update(flatten(v, f"{prefix}{i}."))
    else:
        out[prefix[:-1]] = doc
    return out


def run_batch(job: str, files: Sequence[str], options: Any = None, *, workers: int = 2,
              scheduler: str | None = None, client: Any = None, files_per_task: int = 1, strict: bool = False,
              on_done: Callable[[BatchRow], None] | None = None) -> BatchSummary:
    """Run ``job`` on every file, one Dask task per recording.

    Parameters
    ----------
    job : str
        Job name (``fit``, ``shaft-calibrate``, ``triaxial-calibrate``, ...).
    files : sequence of str
        Recordings (already expanded).
    options : dataclass, optional
        The job's options (``senscal.jobs.options("fit", freq=10.0)``); None
        for its defaults.  Every worker calls ``senscal.jobs.run(job, file,
        options)``.
    workers : int
        Worker processes of the local cluster (ignored with ``scheduler``).
    scheduler : str, optional
        Address of an existing cluster (``tcp://host:8786``).
    client : distributed.Client, optional
        Use this client (and leave it open) instead of starting a cluster.
    files_per_task : int
        Recordings per Dask task (default 1: one task per recording).  Dask
        costs a few milliseconds per task; for thousands of recordings that
        each take about as long, grouping them amortises that cost.
    strict : bool
        Fail the recordings whose results carry named warnings.
    on_done : callable, optional
        Called with each row as it completes (progress).

    Raises
    ------
    InputError
        Unknown job, bad ``workers`` / ``files_per_task``, unreachable scheduler.
    """
    from dask.distributed import Client, LocalCluster, as_completed

    from senscal import jobs

    check_job(job)
    if options is None:
        options = jobs.options(job)  # also: a job whose module is not there yet fails here, not in every worker
    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    if files_per_task < 1:
        raise InputError(f"--files-per-task must be at least 1, got {files_per_task}")
    t0 = time.perf_counter()
    cluster = None
    own_client = client is None
    try:
        if client is not None:
            pass
        elif scheduler:
            try:
                client = Client(scheduler, timeout="10s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise InputError(f"cannot reach the Dask scheduler at {scheduler} ({type(exc).__name__}); "
                                 "check the address or omit --scheduler for a local cluster") from None
        else:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=50)
            client = Client(cluster)
        try:
            n_workers = len(client.scheduler_info().get("workers", {})) or workers
            groups = [list(files[i:i + files_per_task]) for i in range(0, len(files), files_per_task)]
            futures = client.map(run_many, [job] * len(groups), groups, [options] * len(groups),
                                 [strict] * len(groups), pure=False)
            rows: dict[str, BatchRow] = {}
            # with_results gathers finished results in batches instead of one
            # round trip per task.
            for _, group_rows in as_completed(futures, with_results=True):
                for row in group_rows:
                    rows[row.file] = row
                    if on_done:
                        on_done(row)
        finally:
            if own_client:
                client.close()
    finally:
        if cluster is not None:
            cluster.close()
    ordered = tuple(rows[f] for f in files)
    n_ok = sum(r.ok for r in ordered)
    return BatchSummary(job=job, n_files=len(files), n_ok=n_ok, n_failed=len(files) - n_ok, workers=n_workers,
                        wall_seconds=time.perf_counter() - t0, rows=ordered)


def rows_table(summary: BatchSummary):
    """The results as a pandas DataFrame: one row per recording."""
    import pandas as pd

    recs = []
    for r in summary.rows:
        d = {"file": r.file, "ok": r.ok, "error": r.error, "seconds": r.seconds}
        if r.result is not None:
            d.update({k: v for k, v in flatten(r.result).items() if k != "file"})
        recs.append(d)
    return pd.DataFrame.from_records(recs)


def write_rows(summary: BatchSummary, path: str | Path) -> Path:
    """Write the results table as Parquet or CSV (by extension)."""
    from senscal.io.guard import atomic_output, check_output

    path = check_output(path)
    if path.suffix.lower() not in (".parquet", ".pq", ".csv"):
        raise InputError(f"--out must end in .parquet or .csv, got {path.name}")
    df = rows_table(summary)
    with atomic_output(path, what="results table") as tmp:
        if path.suffix.lower() in (".parquet", ".pq"):
            df.to_parquet(tmp, index=False)
        else:
            df.to_csv(tmp, index=False)
    return path
