"""Reading a CSV recording without pandas (the fast path) against the pandas path, as ratios in one run.

For 3-column recordings (``t`` and two channels, ``%.9g`` as ``numpy.savetxt``
writes them, like ``small_csv()`` in ``bench_cli.py``) of 10^3 ... 10^6 rows,
each row of the table is the best wall time of ``read_recording`` over
``--repeat`` interleaved rounds:

- ``fast``: the reader as shipped (plain numeric bodies go through
  ``senscal.io._textfast``, no pandas);
- ``pandas``: the same reader with the fast path switched off (``pd.read_csv``
  of text fields, converted with ``float()``), pandas already imported;
- ``pd C float``: for reference, pandas' C parser asked for float64 (pandas 3
  parses floats correctly rounded by default: 0 of 500 000 hard cases differ
  from ``float()``), without the reader's checks: how fast pandas could be.

``import pandas`` (what the fast path saves a fresh ``senscal`` process) is
timed in a subprocess, best of ``--repeat``.

Run: ``python benchmarks/bench_read.py [--repeat 3] [--max-rows 1000000]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from unittest import mock

import numpy as np


def write_csv(path: Path, rows: int) -> Path:
    rng = np.random.default_rng(0)
    t = np.arange(rows) / 1000.0
    data = np.column_stack([t, 2.0 * np.sin(2 * np.pi * 12.5 * t) + rng.normal(0, 0.05, rows),
                            0.5 * np.sin(2 * np.pi * 12.5 * t) + rng.normal(0, 0.05, rows)])
    np.savetxt(path, data, delimiter=",", header="t,ch1,ch2", comments="", fmt="%.9g")
    return path


def import_pandas_time(repeat: int) -> float:
    """Best wall time (s) of ``import pandas`` minus ``import numpy`` in fresh interpreters."""
    def best(code: str) -> float:
        out = float("inf")
        for _ in range(repeat):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], check=True)
            out = min(out, time.perf_counter() - t0)
        return out
    return best("import numpy, pandas") - best("import numpy")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--max-rows", type=int, default=1_000_000)
    args = ap.parse_args()

    import pandas as pd

    from senscal.io import read_recording, readers
    from senscal.io._textfast import FAST_MAX_BYTES

    def fast(path: Path):
        return read_recording(path)

    def slow(path: Path):
        with mock.patch.object(readers, "read_plain_columns", lambda *a, **k: None):
            return read_recording(path)

    def pandas_float(path: Path):
        return pd.read_csv(path, dtype=np.float64)

    cases = {"fast": fast, "pandas": slow, "pd C float": pandas_float}
    sizes = [n for n in (1_000, 10_000, 100_000, 1_000_000) if n <= args.max_rows]
    print(f"import pandas (fresh process, beyond numpy): {import_pandas_time(args.repeat) * 1e3:.0f} ms; "
          f"fast-path bound FAST_MAX_BYTES = {FAST_MAX_BYTES / 2**20:.0f} MiB")
    print(f"{'rows':>9} {'MB':>6} {'fast ms':>9} {'pandas ms':>10} {'pandas/fast':>12} {'pd C float ms':>14} "
          f"{'pdC/fast':>9}")
    with tempfile.TemporaryDirectory() as folder:
        for n in sizes:
            path = write_csv(Path(folder) / f"r{n}.csv", n)
            a, b = fast(path), slow(path)
            assert all(a.channels[k].tobytes() == b.channels[k].tobytes() for k in a.names)
            best = {name: float("inf") for name in cases}
            for _ in range(args.repeat):
                for name, fn in cases.items():
                    t0 = time.perf_counter()
                    fn(path)
                    best[name] = min(best[name], time.perf_counter() - t0)
            print(f"{n:>9} {path.stat().st_size / 1e6:>6.1f} {best['fast'] * 1e3:>9.1f} {best['pandas'] * 1e3:>10.1f} "
                  f"{best['pandas'] / best['fast']:>12.2f} {best['pd C float'] * 1e3:>14.1f} "
                  f"{best['pd C float'] / best['fast']:>9.2f}")


if __name__ == "__main__":
    main()
