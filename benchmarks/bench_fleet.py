"""Fleet drift correction throughput: 10,000 channels x 1 day at 1 Hz on 1 and 2 Dask workers.

Run: ``python benchmarks/bench_fleet.py [--small] [--channels N] [--seconds S] [--dir DIR]``.

It writes the fleet dataset once (``senscal.simulate.fleet``: Parquet files of
500 channels, row groups of one hour, float32 samples as a historian export
stores them) into a temporary folder, then on fresh ``LocalCluster``s of 1
and 2 worker processes (one thread each) times

* the **plain pass**: the same blocks, the same row groups and columns read,
  stacked into float64 and one vectorised operation per chunk (removing
  each channel's mean) -- the floor of any per-chunk work on this data;
* the **fleet run**: :func:`senscal.drift.fleet.run_fleet` with a state
  store (reading, filtering every channel, saving every block's state after
  every row group).

It prints throughput [samples/s], the CPU seconds the workers used (what a
pass costs per core whatever else runs on the machine), the peak resident
memory of each worker (``ru_maxrss``; a fresh cluster per measurement), the
ratio of the fleet time to the plain time, and the speed-up of 2 workers
over 1.  ``--small``:
1,000 channels x 3 h (1.08e7 samples) for a quick look.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def plain_block(file: str, channels: tuple) -> int:
    """Read every row group of a block and remove each channel's mean: the plain NumPy pass."""
    import pyarrow.parquet as pq

    pf = pq.ParquetFile(file)
    n = 0
    for rg in range(pf.metadata.num_row_groups):
        tbl = pf.read_row_group(rg, columns=["t", *channels])
        y = np.empty((len(channels), tbl.num_rows))
        for i in range(len(channels)):
            y[i] = tbl.column(1 + i).to_numpy()
        y -= y.mean(axis=1, keepdims=True)
        n += y.size
    return n


def _usage() -> tuple[float, float]:
    """(peak resident memory [MB], CPU seconds used) of this worker process."""
    import resource

    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_maxrss / 1024.0, ru.ru_utime + ru.ru_stime


def _warm() -> None:
    """Import and load the compiled kernels in a worker (not part of the timing)."""
    from senscal.drift import known_setup
    from senscal.drift.fleet import ROLE, FleetGroup, filter_block

    g = FleetGroup("w", known_setup([ROLE]), {"y_noise_std": 1.0, "y_bias_rate_std": 1.0}, prior_scale=1.0)
    y = np.zeros((2, 4))
    filter_block(g, y, np.arange(4.0), [None, None])
    filter_block(FleetGroup("w", known_setup([ROLE]), {"y_noise_std": 1.0, "y_bias_rate_std": 1.0}), y + 1,
                 np.arange(4.0), [None, None])


def _cluster(workers: int):
    from dask.distributed import Client, LocalCluster

    cl = LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=":0", silence_logs=50,
                      memory_limit=0)
    client = Client(cl)
    client.run(_warm)
    return cl, client


def measure(dataset: Path, groups, workers: int, what: str, store: Path) -> tuple[float, int, list[float], float]:
    """(seconds, samples, peak RSS per worker [MB], worker CPU seconds) of one pass on a fresh cluster."""
    from dask.distributed import wait

    from senscal.drift.fleet import plan_blocks, run_fleet

    cl, client = _cluster(workers)
    try:
        blocks, _ = plan_blocks(dataset, groups)
        cpu0 = sum(u[1] for u in client.run(_usage).values())
        t0 = time.perf_counter()
        if what == "plain":
            futs = [client.submit(plain_block, b.file, b.channels, pure=False) for b in blocks]
            wait(futs)
            n = sum(f.result() for f in futs)
        else:
            if store.exists():
                shutil.rmtree(store)
            n = run_fleet(dataset, groups, state=store, client=client).n_samples
        sec = time.perf_counter() - t0
        use = client.run(_usage).values()
        rss = sorted(u[0] for u in use)
        cpu = sum(u[1] for u in use) - cpu0
    finally:
        client.close()
        cl.close()
    return sec, n, rss, cpu


def main() -> None:
    from senscal.drift.fleet import load_fleet_config
    from senscal.simulate.fleet import simulate_fleet

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--small", action="store_true", help="1,000 channels x 3 h")
    ap.add_argument("--channels", type=int, default=None)
    ap.add_argument("--seconds", type=int, default=None, help="record length at 1 Hz [s]")
    ap.add_argument("--dir", type=Path, default=None, help="where to write the dataset (default: a temp folder)")
    ap.add_argument("--keep", action="store_true", help="keep the dataset (reuse it with --dir)")
    args = ap.parse_args()
    C = args.channels or (1000 if args.small else 10_000)
    T = args.seconds or (3 * 3600 if args.small else 86_400)
    root = Path(args.dir or tempfile.mkdtemp(prefix="bench_fleet_"))
    data = root / "data"
    try:
        t0 = time.perf_counter()
        if not (data / "fleet.json").exists():
            simulate_fleet(data, n_channels=C, n_samples=T, channels_per_file=500, rows_per_group=3600,
                           kind="known", dtype="float32", seed=0)
        t_gen = time.perf_counter() - t0
        size = sum(p.stat().st_size for p in data.glob("*.parquet"))
        groups = load_fleet_config(data / "fleet.json")
        rows = {}
        for w in (1, 2):
            for what in ("plain", "fleet"):
                rows[(what, w)] = measure(data, groups, w, what, root / f"state-{w}")
        print(f"fleet: {C} channels x {T} s at 1 Hz = {C * T:.3g} samples, {size / 1e9:.2f} GB Parquet "
              f"(float32, 500 channels/file, 1 h row groups); written in {t_gen:.0f} s")
        print("set-up: known value, random-walk bias (shared-covariance kernel), state saved every row group")
        print(f"{'pass':<8}{'workers':>8}{'seconds':>10}{'samples/s':>12}{'per worker':>12}{'worker CPU s':>14}"
              f"{'samples/CPU-s':>15}{'peak RSS/worker MB':>22}")
        for (what, w), (sec, n, rss, cpu) in rows.items():
            print(f"{what:<8}{w:>8}{sec:>10.1f}{n / sec:>12.3g}{n / sec / w:>12.3g}{cpu:>14.1f}{n / cpu:>15.3g}"
                  f"{'  ' + ', '.join(f'{r:.0f}' for r in rss):>22}")
        for w in (1, 2):
            f, p = rows[("fleet", w)], rows[("plain", w)]
            print(f"fleet / plain on {w} worker{'s' if w > 1 else ''}: wall time {f[0] / p[0]:.2f}, "
                  f"worker CPU time {f[3] / p[3]:.2f} (target <= 10)")
        for what in ("plain", "fleet"):
            print(f"{what}: 2 workers / 1 worker throughput {rows[(what, 1)][0] / rows[(what, 2)][0]:.2f} "
                  f"(2.0 = linear; needs 2 idle cores), CPU per sample {rows[(what, 2)][3] / rows[(what, 1)][3]:.2f}"
                  " (1.0 = no cost of parallelism)")
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
