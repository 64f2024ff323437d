"""fit-array on odd stores: one line naming the file or option, never a traceback (issue 19)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest


@pytest.fixture
def store(tmp_path):
    p = tmp_path / "a.h5"
    t = np.arange(200) / 200.0
    with h5py.File(p, "w") as fh:
        fh.create_dataset("y", data=np.stack([np.sin(2 * np.pi * 5 * t)] * 2)).attrs["fs"] = 200.0
        fh.create_dataset("t", data=t)
        fh.create_dataset("empty", data=np.zeros((0, 5)))
        fh.create_dataset("s", data=np.array([[b"a", b"b"], [b"c", b"d"]]))
        fh.create_dataset("t_short", data=t[:10])
        fh.create_group("grp")
    return p


@pytest.mark.parametrize("extra, match", [
    (("--dataset", "grp"), "is a group, not a dataset"),
    (("--dataset", "empty"), "is empty"),
    (("--dataset", "s"), "not real numbers"),
    (("--dataset", "y", "--time-dataset", ""), "--time-dataset is empty"),
    (("--dataset", "y", "--time-dataset", "t_short"), "has 10 samples"),
    (("--dataset", "y", "--time-dataset", "nope"), "no time dataset 'nope'"),
    (("--dataset", "y", "--fs", "0"), "--fs must be a positive"),
    (("--dataset", "y", "--scheduler", "tcp://nohost"), "cannot connect to the Dask scheduler"),
])
def test_odd_stores_and_options(cli, store, tmp_path, extra, match):
    r = cli("fit-array", store, *extra, "--out", tmp_path / "r.csv")
    assert r.code == 2, r.err
    assert len(r.err.splitlines()) == 1 and match in r.err, r.err
    assert not (tmp_path / "r.csv").exists()


def test_corrupt_store_names_the_file(cli, store, tmp_path):
    data = bytearray(store.read_bytes())
    data[100:400] = bytes(300)
    bad = tmp_path / "bad.h5"
    bad.write_bytes(bytes(data))
    r = cli("fit-array", bad, "--dataset", "y", "--out", tmp_path / "r.csv")
    assert r.code == 2 and len(r.err.splitlines()) == 1 and str(bad) in r.err, r.err
