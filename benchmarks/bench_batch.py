"""Batch overhead: N small recordings with a plain loop, 1 worker and 2 workers.

Run: ``python benchmarks/bench_batch.py [--n 1000]``.  Prints the speed-up of
two workers over one, the per-task overhead of the Dask batch against the
plain in-process loop, and the cluster start-up time separately.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from senscal.batch import run_batch, run_one
from senscal.io import Recording, write_recording


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1000)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    t = np.arange(2000) / 1000.0
    with tempfile.TemporaryDirectory() as d:
        files = []
        for i in range(args.n):
            rec = Recording(channels={"x": np.sin(2 * math.pi * 10 * t) + rng.normal(0, 0.01, t.size)}, t=t)
            files.append(str(write_recording(rec, Path(d) / f"r{i:05d}.npz")))
        run_one(["fit"], files[0], ["--freq", "10"])  # warm imports and compilation
        t0 = time.perf_counter()
        for f in files:
            run_one(["fit"], f, ["--freq", "10"])
        t_loop = time.perf_counter() - t0
        res = {}
        for w in (1, 2):
            t0 = time.perf_counter()
            s = run_batch("fit", files[:2], ["--freq", "10"], workers=w)  # start-up + warm-up
            t_start = time.perf_counter() - t0
            t0 = time.perf_counter()
            s = run_batch("fit", files, ["--freq", "10"], workers=w)
            res[w] = (time.perf_counter() - t0, t_start, s)
    print(f"{args.n} recordings x 2000 samples, job 'fit --freq 10'")
    print(f"plain loop in one process        {t_loop:7.2f} s   ({t_loop / args.n * 1e3:.2f} ms/recording)")
    for w, (tw, ts, s) in res.items():
        over = (tw - t_loop / w) / args.n * 1e3
        print(f"dask batch, {w} worker(s)          {tw:7.2f} s   (cluster start-up of a small batch {ts:.1f} s; "
              f"overhead {over:+.2f} ms/task vs loop/{w}; {s.n_ok} ok)")
    print(f"speed-up 2 workers vs 1: {res[1][0] / res[2][0]:.2f}x; 1-worker batch / plain loop: {res[1][0] / t_loop:.2f}x")


if __name__ == "__main__":
    main()
