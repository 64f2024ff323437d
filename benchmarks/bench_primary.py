"""``senscal primary``'s processing time against reading the record, as ratios in one run (issue 28).

Issue 28's criterion: a 1-second record at 1 MS/s per frequency is processed in about the time of reading
it. For one simulated 1 kHz point, 1 s at 1 MS/s (three channels: ``I, Q, out`` for the homodyne
quadrature interferometer; ``H, ref, out`` for the heterodyne carrier at 250 kHz), written once as
``.npz`` and, with ``--csv``, as ``.csv``, each row gives the best wall time over ``--repeat`` rounds
(after one warm-up, which compiles the engines' kernels) of:

- ``read``: ``senscal.io.read_recording`` of the file (the reader every command uses, with its checks);
- ``stream``: a plain streaming read of the same record that decodes every sample, chunk by chunk, with no
  checks -- for ``.npz`` each stored array read 8 MiB at a time into float64 values (``np.frombuffer``) and
  summed, for ``.csv`` pandas' C parser in chunks of 65,536 rows as float64 and summed: the floor a reader of
  that format has;
- ``bytes``: the file's bytes only, 8 MiB at a time (from the page cache: no decoding at all);
- ``process``: the calibration of the point from the arrays (``senscal.primary.calibrate_point``, or
  ``senscal.primary.heterodyne.calibrate_heterodyne`` with the reference carrier), without reading;

and the ratios ``process / read`` and ``process / stream``, of wall times and of CPU times (the CPU
times are the steadier measure on a shared machine, where the wall time follows the load; they count every
thread, so a threaded step costs its CPU time, not its wall time).

Run: ``PYTHONPATH=src python3 benchmarks/bench_primary.py [--repeat 3] [--csv] [--profile]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np


def _best(fn, repeat: int) -> tuple[float, float]:
    """Best wall time and best CPU time (this process, all threads) over ``repeat`` rounds, s."""
    wall = cpu = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def _bytes(path: Path) -> int:
    n = 0
    with open(path, "rb") as fh:
        while True:
            b = fh.read(8 << 20)
            if not b:
                return n
            n += len(b)


def _stream(path: Path) -> float:
    """Every sample of the record decoded chunk by chunk (no checks), summed; see the module docstring."""
    total = 0.0
    if path.suffix == ".npz":
        import zipfile

        from numpy.lib import format as npformat

        with zipfile.ZipFile(path) as zf:
            for name in zf.namelist():
                with zf.open(name) as fh:
                    version = npformat.read_magic(fh)
                    header = npformat.read_array_header_1_0 if version == (1, 0) else npformat.read_array_header_2_0
                    shape, _, dtype = header(fh)
                    if dtype.kind != "f":
                        continue
                    step = (8 << 20) // dtype.itemsize * dtype.itemsize
                    while True:
                        b = fh.read(step)
                        if not b:
                            break
                        total += float(np.frombuffer(b, dtype=dtype).sum())
        return total
    import pandas as pd

    for chunk in pd.read_csv(path, chunksize=1 << 16, dtype="float64", engine="c"):
        total += float(chunk.to_numpy().sum())
    return total


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fs", type=float, default=1_000_000.0, help="sample rate, Hz (default 1 MS/s)")
    ap.add_argument("--duration", type=float, default=1.0, help="record length, s")
    ap.add_argument("--freq", type=float, default=1000.0, help="vibration frequency, Hz")
    ap.add_argument("--csv", action="store_true", help="also write and read the record as CSV (slow to write)")
    ap.add_argument("--profile", action="store_true", help="print cProfile's 15 costliest calls of each processing")
    args = ap.parse_args(argv)

    from senscal.io import read_recording, write_recording
    from senscal.primary import calibrate_point
    from senscal.primary.heterodyne import calibrate_heterodyne
    from senscal.simulate.interferometer import simulate_interferometer

    fs, f = args.fs, args.freq
    cases = []
    rq, _ = simulate_interferometer(freq=f, fs=fs, duration=args.duration, seed=1)
    cq = rq.channels
    cases.append(("quadrature", rq, lambda: calibrate_point(cq["I"], cq["Q"], cq["out"], fs, freq=f)))
    rh, _ = simulate_interferometer(freq=f, fs=fs, duration=args.duration, seed=1, heterodyne=True,
                                    carrier_hz=fs / 4)
    ch = rh.channels
    cases.append(("heterodyne", rh, lambda: calibrate_heterodyne(ch["H"], ch["out"], fs, carrier_hz=fs / 4,
                                                                 reference=ch["ref"], freq=f)))
    exts = ["npz"] + (["csv"] if args.csv else [])
    print(f"# {args.duration:g} s at {fs / 1e6:g} MS/s, {f:g} Hz, best of {args.repeat} (os.cpu_count() = "
          f"{os.cpu_count()}, load {os.getloadavg()[0]:.1f})")
    print("| input | file | MB | read / s | stream / s | bytes / s | process / s | process / read | process / stream "
          "| CPU: read / s | stream / s | process / s | process / read | process / stream |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, rec, proc in cases:
            proc()  # warm-up: compiles the kernels
            t_proc = _best(proc, args.repeat)
            if args.profile:
                import cProfile
                import pstats

                pr = cProfile.Profile()
                pr.runcall(proc)
                pstats.Stats(pr).sort_stats("cumulative").print_stats(15)
            for ext in exts:
                path = write_recording(rec, Path(tmp) / f"{name}.{ext}")
                read_recording(path)
                t_read = _best(lambda: read_recording(path), args.repeat)
                _stream(path)
                t_stream = _best(lambda: _stream(path), args.repeat)
                t_bytes = _best(lambda: _bytes(path), args.repeat)
                mb = path.stat().st_size / 1e6
                print(f"| {name} | {ext} | {mb:.1f} | {t_read[0]:.3f} | {t_stream[0]:.3f} | {t_bytes[0]:.4f} | "
                      f"{t_proc[0]:.3f} | {t_proc[0] / t_read[0]:.2f} | {t_proc[0] / t_stream[0]:.2f} | "
                      f"{t_read[1]:.3f} | {t_stream[1]:.3f} | {t_proc[1]:.3f} | {t_proc[1] / t_read[1]:.2f} | "
                      f"{t_proc[1] / t_stream[1]:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
