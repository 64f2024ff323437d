"""Registry speed against plain baselines measured in the same run.

    python benchmarks/bench_registry.py [N]

* record: ``Registry.record`` (one transaction per calibration, as the CLI
  does) vs the same rows written with the bare ``sqlite3`` module, one
  transaction each, same WAL/synchronous settings;
* history: ``Registry.history`` vs a bare ``sqlite3`` SELECT of the same rows;
* drift: ``fit_drift`` vs ``numpy.polyfit(..., w=1/u, cov=True)``;
* PostgreSQL record throughput too when ``SENSCAL_TEST_PG_URL`` is set.

Ratios > 1 mean the registry is slower than the bare baseline.
"""

from __future__ import annotations

import os
import sqlite3
import sys
import tempfile
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from senscal.registry import Quantity, fit_drift, open_registry  # noqa: E402


def best(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def bench_record(url: str, n: int) -> float:
    reg = open_registry(url)
    reg.add_sensor("B1", "accelerometer")
    t0 = datetime(2000, 1, 1, tzinfo=timezone.utc)
    t = time.perf_counter()
    for i in range(n):
        reg.record("B1", [Quantity("sensitivity", 0.01 + i * 1e-9, 1e-5, "V/(m/s^2)")],
                   performed_at=t0 + timedelta(days=i), operator="bench")
    dt = time.perf_counter() - t
    reg.close()
    return dt


def bench_raw_sqlite(path: str, n: int) -> float:
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA synchronous=NORMAL")
    con.execute("CREATE TABLE c (id INTEGER PRIMARY KEY, uid TEXT, performed_at TEXT, operator TEXT)")
    con.execute("CREATE TABLE q (id INTEGER PRIMARY KEY, cid INTEGER, name TEXT, value REAL, u REAL, unit TEXT)")
    t = time.perf_counter()
    for i in range(n):
        con.execute("BEGIN IMMEDIATE")
        cid = con.execute("INSERT INTO c (uid, performed_at, operator) VALUES (?, ?, ?)",
                          (f"{i:036d}", f"2000-01-01 {i}", "bench")).lastrowid
        con.execute("INSERT INTO q (cid, name, value, u, unit) VALUES (?, ?, ?, ?, ?)",
                    (cid, "sensitivity", 0.01 + i * 1e-9, 1e-5, "V/(m/s^2)"))
        con.execute("COMMIT")
    dt = time.perf_counter() - t
    con.close()
    return dt


def main(n: int = 300) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        reg_path, raw_path = Path(tmp) / "reg.sqlite", Path(tmp) / "raw.sqlite"
        t_reg = bench_record(f"sqlite:///{reg_path}", n)
        t_raw = bench_raw_sqlite(str(raw_path), n)
        print(f"record  {n} calibrations, SQLite : registry {1e3 * t_reg / n:.2f} ms/record, bare sqlite3 "
              f"{1e3 * t_raw / n:.2f} ms/record, ratio {t_reg / t_raw:.1f}")

        reg = open_registry(f"sqlite:///{reg_path}")
        t_hist = best(lambda: reg.history("B1", "sensitivity"))
        con = sqlite3.connect(raw_path)
        t_sel = best(lambda: con.execute("SELECT c.performed_at, q.value, q.u, q.unit FROM c JOIN q ON q.cid = c.id "
                                         "WHERE q.name = 'sensitivity' ORDER BY c.performed_at").fetchall())
        print(f"history {n} records              : registry {1e3 * t_hist:.1f} ms, bare SELECT {1e3 * t_sel:.2f} ms, "
              f"ratio {t_hist / t_sel:.0f}")
        t_due = best(lambda: reg.drift("B1", "sensitivity", tolerance=0.01))
        print(f"due     {n} records (read + fit) : {1e3 * t_due:.1f} ms")
        reg.close()

    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 10, 20))
    u = rng.uniform(1e-5, 2e-5, 20)
    y = 0.01 + 1e-5 * t + rng.normal(0, u)
    fit_drift(t, y, u)  # import scipy.stats outside the timing
    m = 2000
    t_fit = best(lambda: [fit_drift(t, y, u) for _ in range(m)]) / m
    t_poly = best(lambda: [np.polyfit(t, y, 1, w=1 / u, cov=True) for _ in range(m)]) / m
    print(f"drift   20-record fit            : fit_drift {1e6 * t_fit:.0f} us, numpy.polyfit {1e6 * t_poly:.0f} us, "
          f"ratio {t_fit / t_poly:.1f} (fit_drift also tests significance)")

    pg = os.environ.get("SENSCAL_TEST_PG_URL")
    if pg:
        import uuid

        import sqlalchemy as sa
        from sqlalchemy.engine import make_url

        schema = f"bench_{uuid.uuid4().hex[:8]}"
        admin = sa.create_engine(pg)
        with admin.begin() as c:
            c.execute(sa.text(f"CREATE SCHEMA {schema}"))
        try:
            url = make_url(pg).update_query_dict({"options": f"-csearch_path={schema}"})
            t_pg = bench_record(url.render_as_string(hide_password=False), n)
            print(f"record  {n} calibrations, PostgreSQL: registry {1e3 * t_pg / n:.2f} ms/record, "
                  f"ratio to bare sqlite3 {t_pg / t_raw:.1f}")
        finally:
            with admin.begin() as c:
                c.execute(sa.text(f"DROP SCHEMA {schema} CASCADE"))
            admin.dispose()


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 300)
