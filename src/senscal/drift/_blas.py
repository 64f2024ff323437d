"""One BLAS thread for the small linear algebra of the noise-level search.

SciPy's L-BFGS-B (1.15 on, rewritten in C) calls BLAS on vectors of a few
entries at every iteration.  A threaded OpenBLAS then wakes its worker
threads for each call; on a loaded two-core machine that cost 10 ms per
iteration against 1 ms with one thread (measured with scipy 1.17, load
13): more than the Kalman pass itself.  ``openblas_set_num_threads_local``
(OpenBLAS >= 0.3.27) limits only the calling thread and returns the old
value, so the setting is restored afterwards and other threads are not
touched.  Other BLAS libraries, or a platform without ``/proc/self/maps``,
are left alone (the search is then as before, only slower under load).
"""

from __future__ import annotations

import contextlib
import ctypes
from typing import Iterator

_SETTERS: list | None = None


def _setters() -> list:
    global _SETTERS
    if _SETTERS is None:
        out = []
        try:
            with open("/proc/self/maps") as fh:
                paths = {ln.split()[-1] for ln in fh if "openblas" in ln.lower() and ln.rstrip().endswith(".so")
                         or ("openblas" in ln.lower() and ".so" in ln.split()[-1])}
        except OSError:
            paths = set()
        for p in sorted(paths):
            try:
                fn = getattr(ctypes.CDLL(p), "openblas_set_num_threads_local", None)
            except OSError:
                fn = None
            if fn is not None:
                fn.restype = ctypes.c_int
                fn.argtypes = [ctypes.c_int]
                out.append(fn)
        _SETTERS = out
    return _SETTERS


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block with one OpenBLAS thread in this thread (a no-op where that cannot be set)."""
    done = []
    try:
        for fn in _setters():
            done.append((fn, fn(1)))
    except Exception:  # a foreign library: leave it as it is
        pass
    try:
        yield
    finally:
        for fn, old in done:
            try:
                fn(max(int(old), 1))
            except Exception:
                pass
