"""Scale-out: run any per-recording job over many files on Dask.

Each recording is one task on ``dask.distributed``.  A task calls the job
function of :mod:`senscal.jobs` with the job's typed options and keeps
``result.to_dict()``, so a job's batch result has exactly the fields of its
``--json`` output, flattened.
"""

from senscal.batch.core import (BatchRow, BatchSummary, batch_jobs, check_job, expand_files, flatten, rows_table,
                                run_batch, run_one, write_rows)

__all__ = ["BatchRow", "BatchSummary", "batch_jobs", "check_job", "expand_files", "flatten", "rows_table",
           "run_batch", "run_one", "write_rows"]
