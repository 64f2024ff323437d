"""Several processes writing to one registry at once lose nothing and corrupt nothing."""

from __future__ import annotations

import multiprocessing as mp

import pytest

# Imported here so that forked writers start at once instead of each importing the stack.
from senscal.registry import Quantity, open_registry

N_PROC = 4
N_REC = 12


def _writer(url: str, proc: int, barrier) -> None:
    barrier.wait()  # everybody opens the (fresh) registry and creates the sensor at the same moment
    with open_registry(url) as reg:
        for i in range(N_REC):
            # The value encodes writer and index so each record's content can be checked afterwards.
            reg.record("SHARED", [Quantity("sensitivity", 1.0 + proc + i * 1e-3, 1e-4, "V/g"),
                                  Quantity("phase", float(proc * 100 + i), 0.1, "deg")],
                       performed_at=f"2024-01-{1 + i:02d}T00:00:00+00:00", job="parallel",
                       note=f"{proc}:{i}", create_kind="accelerometer", operator=f"p{proc}")


def test_parallel_writers(db_url):
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    barrier = ctx.Barrier(N_PROC)
    procs = [ctx.Process(target=_writer, args=(db_url, p, barrier)) for p in range(N_PROC)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=300)
    assert [p.exitcode for p in procs] == [0] * N_PROC

    with open_registry(db_url) as reg:
        assert [s.serial for s in reg.sensors()] == ["SHARED"]
        recs = reg.calibrations("SHARED")
    assert len(recs) == N_PROC * N_REC
    assert len({r.uid for r in recs}) == N_PROC * N_REC
    seen = set()
    for r in recs:
        proc, i = map(int, r.note.split(":"))
        seen.add((proc, i))
        q = {x.name: x.value for x in r.quantities}
        assert q == {"sensitivity": pytest.approx(1.0 + proc + i * 1e-3, abs=0), "phase": float(proc * 100 + i)}
        assert r.operator == f"p{proc}" and r.performed_at.day == 1 + i
    assert seen == {(p, i) for p in range(N_PROC) for i in range(N_REC)}
