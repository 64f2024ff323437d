"""Upper bounds on the counts a user gives (workers, channels, samples), from this machine's cores and memory.

A count is a typo long before it is a request: ``--workers 2147483648``
started a local cluster that grew past 20 GB in a minute, and ``simulate sine
--channels 2147483648`` ran until killed.  The bounds are generous (a few
times what the machine can use) and refuse with one line naming the machine.
"""

from __future__ import annotations

import functools
import os

__all__ = ["cores", "memory_bytes", "max_workers", "max_values", "WORKER_BYTES", "VALUE_BYTES"]

#: Memory one Dask worker process needs at least (interpreter, numpy, scipy, dask): ~250 MB.
WORKER_BYTES = 256 * 2**20
#: Bytes a simulated or processed value costs: float64 plus the copies a job makes (noise, text formatting).
VALUE_BYTES = 8 * 4
#: Worker processes per core that still make sense (I/O-bound tasks overlap; beyond, they only queue).
WORKERS_PER_CORE = 4


@functools.lru_cache(maxsize=1)
def cores() -> int:
    """CPU cores this process may run on (affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


@functools.lru_cache(maxsize=1)
def memory_bytes() -> int:
    """Physical memory in bytes: psutil if installed, else /proc/meminfo, else a conservative 4 GiB."""
    try:
        import psutil

        return int(psutil.virtual_memory().total)
    except Exception:  # not installed, or no answer in a sandbox
        pass
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return 4 * 2**30


def max_workers() -> int:
    """Most worker processes a local cluster may start: a few per core, and as many as memory holds."""
    return max(1, min(WORKERS_PER_CORE * cores(), memory_bytes() // WORKER_BYTES))


def max_values() -> int:
    """Most float64 values one command may hold (with the copies it makes) in this machine's memory."""
    return max(1, memory_bytes() // VALUE_BYTES)


def describe() -> str:
    """``"2 cores, 23.4 GB memory"`` for error messages."""
    return f"{cores()} core{'s' if cores() != 1 else ''}, {memory_bytes() / 1e9:.1f} GB memory"
