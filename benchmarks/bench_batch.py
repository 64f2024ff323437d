"""Batch overhead: N small recordings with a plain loop, 1 worker and 2 workers.

Run: ``python benchmarks/bench_batch.py [--n 1000]``.  In one run it times
the plain in-process loop over the recordings and the Dask batch on a warmed
``LocalCluster`` with 1 and 2 worker processes, and prints the speed-up of
two workers over one, the per-task overhead against the loop, and the
cluster start-up separately (it is paid once per batch).

The loop is timed before and after the Dask runs and the ratios use the mean
of the two: on a shared machine the load changes within a run, and one loop
timing can sit in a quiet or a busy stretch. The load average at the start
and the end is printed with the figures, which mean little without it.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np


def main() -> None:
    from dask.distributed import Client, LocalCluster

    from senscal.batch import run_batch, run_one
    from senscal.io import Recording, write_recording
    from senscal.jobs.fit import FitOptions

    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1000)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    t = np.arange(2000) / 1000.0
    opts = FitOptions(freq=10.0)
    with tempfile.TemporaryDirectory() as d:
        files = []
        for i in range(args.n):
            rec = Recording(channels={"x": np.sin(2 * math.pi * 10 * t) + rng.normal(0, 0.01, t.size)}, t=t)
            files.append(str(write_recording(rec, Path(d) / f"r{i:05d}.npz")))
        run_one("fit", files[0], opts)  # warm imports and compilation
        load0 = os.getloadavg()[0]

        def loop() -> float:
            t0 = time.perf_counter()
            for f in files:
                run_one("fit", f, opts)
            return time.perf_counter() - t0

        t_loop_before = loop()
        res = {}
        for w in (1, 2):
            t0 = time.perf_counter()
            with LocalCluster(n_workers=w, threads_per_worker=1, dashboard_address=None, silence_logs=50) as cl, \
                    Client(cl) as client:
                run_batch("fit", files[:4 * w], opts, client=client)  # workers import and compile once
                t_start = time.perf_counter() - t0
                t0 = time.perf_counter()
                s = run_batch("fit", files, opts, client=client)
                res[w] = (time.perf_counter() - t0, t_start, s.n_ok)
                t0 = time.perf_counter()
                s = run_batch("fit", files, opts, client=client, files_per_task=25)
                res[(w, 25)] = (time.perf_counter() - t0, t_start, s.n_ok)
        t_loop_after = loop()
    t_loop = 0.5 * (t_loop_before + t_loop_after)
    print(f"{args.n} recordings x 2000 samples (NPZ), job 'fit --freq 10'; {os.cpu_count()} cores, load average "
          f"(1 min) {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end")
    print(f"plain loop in one process   {t_loop:7.2f} s   ({t_loop / args.n * 1e3:.2f} ms/recording; "
          f"{t_loop_before:.2f} s before the Dask runs, {t_loop_after:.2f} s after)")
    for key, (tw, ts, ok) in res.items():
        w, per = (key, 1) if isinstance(key, int) else key
        over = (tw - t_loop / w) / args.n * 1e3
        print(f"dask batch, {w} worker(s), {per:2d} file(s)/task  {tw:7.2f} s   ({ok} ok; overhead {over:+.2f} ms per "
              f"recording vs loop/{w}; cluster start-up + warm-up {ts:.1f} s, paid once)")
    print(f"one task per recording: speed-up 2 workers vs 1 {res[1][0] / res[2][0]:.2f}x, "
          f"1-worker batch / plain loop {res[1][0] / t_loop:.2f}x")
    print(f"25 recordings per task: speed-up 2 workers vs 1 {res[(1, 25)][0] / res[(2, 25)][0]:.2f}x, "
          f"1-worker batch / plain loop {res[(1, 25)][0] / t_loop:.2f}x")


if __name__ == "__main__":
    main()
