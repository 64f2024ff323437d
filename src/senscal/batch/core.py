"""Batch execution of per-recording jobs on a Dask cluster."""

from __future__ import annotations

import contextlib
import functools
import glob
import io
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from senscal._result import ResultMixin
from senscal.errors import InputError, SenscalError

__all__ = ["BatchRow", "BatchSummary", "expand_files", "flatten", "job_argv", "run_one", "run_batch"]


@dataclass(frozen=True)
class BatchRow(ResultMixin):
    """One recording's outcome: ``ok`` with the job's JSON, or its one-line error."""

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


def job_argv(job: str) -> list[str]:
    """Command words of a job name: ``shaft-calibrate`` -> ``["shaft", "calibrate"]``.

    Raises
    ------
    InputError
        For a name that is not a per-recording command of ``senscal``.
    """
    root = _root_command()
    words = job.split("-")
    # Longest prefix that names a group, then the command inside it.
    cmd = root
    path: list[str] = []
    i = 0
    while i < len(words):
        if not _is_group(cmd):
            break
        found = None
        for j in range(len(words), i, -1):
            name = "-".join(words[i:j])
            if name in cmd.commands:  # type: ignore[attr-defined]
                found = (name, j)
                break
        if found is None:
            break
        path.append(found[0])
        cmd = cmd.commands[found[0]]  # type: ignore[attr-defined]
        i = found[1]
    jobs = batch_jobs()
    if i != len(words) or _is_group(cmd) or "-".join(path) not in jobs:
        raise InputError(f"unknown batch job '{job}'; jobs are: {', '.join(jobs)}")
    return path


def _is_group(cmd) -> bool:
    # Typer's groups are not click.Group subclasses in every version.
    return hasattr(cmd, "commands")


_NOT_PER_RECORDING = {"demo", "batch", "simulate", "registry"}


def batch_jobs() -> list[str]:
    """Names of the per-recording jobs ``senscal batch`` can run."""
    root = _root_command()
    names = []
    for name, cmd in sorted(root.commands.items()):  # type: ignore[attr-defined]
        if name in _NOT_PER_RECORDING:
            continue
        if _is_group(cmd):
            names += [f"{name}-{sub}" for sub in sorted(cmd.commands)
                      if any(p.name == "json_out" or "--json" in getattr(p, "opts", ()) for p in cmd.commands[sub].params)]
        elif any("--json" in getattr(p, "opts", ()) for p in cmd.params):
            names.append(name)
    return names


@functools.lru_cache(maxsize=1)
def _root_command():
    import typer

    from senscal.cli import load_commands

    return typer.main.get_command(load_commands())


def run_one(command: Sequence[str], file: str, options: Sequence[str]) -> BatchRow:
    """Run one job on one file in this process; never raises for a job failure.

    Parameters
    ----------
    command : sequence of str
        Command words, e.g. ``["shaft", "calibrate"]``.
    file : str
        The recording.
    options : sequence of str
        The job's own options (as on its command line), ``--json`` added here.
    """
    t0 = time.perf_counter()
    root = _root_command()
    args = [*command, file, *options, "--json"]
    out = io.StringIO()
    err = io.StringIO()
    try:
        from senscal.io.guard import protect_inputs

        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), protect_inputs():
            rv = root.main(args=args, prog_name="senscal", standalone_mode=False)
        if isinstance(rv, int) and rv != 0:
            raise SenscalError(f"job exited with code {rv}")
        text = out.getvalue()
        start = text.find("{")
        if start < 0:
            raise SenscalError("job printed no JSON result")
        doc = json.loads(text[start:])
        return BatchRow(file=file, ok=True, error=None, result=doc, seconds=time.perf_counter() - t0)
    except SenscalError as exc:
        msg = str(exc)
    except Exception as exc:  # click usage errors and bugs: one line in the row, the batch goes on
        from senscal.cli import _clickcompat as cx

        if isinstance(exc, cx.ClickException):
            msg = exc.format_message()
        else:
            msg = f"internal error ({type(exc).__name__}: {exc}); please report it"
    return BatchRow(file=file, ok=False, error=" ".join(msg.split()), result=None, seconds=time.perf_counter() - t0)


def run_many(command: Sequence[str], files: Sequence[str], options: Sequence[str]) -> list[BatchRow]:
    """:func:`run_one` over several files in one task (amortises per-task scheduling)."""
    return [run_one(command, f, options) for f in files]


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


def run_batch(job: str, files: Sequence[str], options: Sequence[str] = (), *, workers: int = 2,
              scheduler: str | None = None, client: Any = None, files_per_task: int = 1,
              on_done: Callable[[BatchRow], None] | None = None) -> BatchSummary:
    """Run ``job`` on every file, one Dask task per recording.

    Parameters
    ----------
    job : str
        Job name (``fit``, ``shaft-calibrate``, ``triaxial-calibrate``, ...).
    files : sequence of str
        Recordings (already expanded).
    options : sequence of str
        The job's options, as on its command line.
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
    on_done : callable, optional
        Called with each row as it completes (progress).
    """
    from dask.distributed import Client, LocalCluster, as_completed

    command = job_argv(job)
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
            futures = client.map(run_many, [command] * len(groups), groups, [list(options)] * len(groups),
                                 pure=False)
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
