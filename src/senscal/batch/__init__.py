"""Scale-out: run any per-recording job over many files on Dask.

Each recording is one task on ``dask.distributed``.  A task runs the job's
own command in-process with ``--json`` and returns its JSON document, so a
job's batch result has exactly the fields of its JSON output, flattened.
"""

from senscal.batch.core import BatchRow, BatchSummary, expand_files, flatten, job_argv, run_batch, run_one

__all__ = ["BatchRow", "BatchSummary", "expand_files", "flatten", "job_argv", "run_batch", "run_one"]
