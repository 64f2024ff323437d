"""Batch runs on a real LocalCluster with two worker processes."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pandas as pd
import pytest

from senscal.batch import expand_files, flatten, job_argv, run_batch, run_one
from senscal.batch.arrays import fit_hdf5_dataset, fit_sine_dask
from senscal.errors import InputError
from senscal.io import Recording, write_recording


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch")
    rng = np.random.default_rng(0)
    t = np.arange(1000) / 500.0
    truth = {}
    for i in range(5):
        a = 1.0 + i
        rec = Recording(channels={"x": a * np.sin(2 * math.pi * 10 * t) + rng.normal(0, 0.01, t.size)}, t=t)
        p = write_recording(rec, d / f"r{i}.csv")
        truth[str(p)] = a
    bad = d / "r9.csv"
    bad.write_text("t,x\n0,1\n1,nan\n2,0\n")
    return d, truth, str(bad)


def test_job_names():
    assert job_argv("fit") == ["fit"]
    with pytest.raises(InputError, match="unknown batch job 'nope'"):
        job_argv("nope")


def test_expand_files(recordings):
    d, truth, bad = recordings
    files = expand_files([str(d / "r*.csv")])
    assert len(files) == 6
    with pytest.raises(InputError, match="no file matches"):
        expand_files([str(d / "zz*.csv")])


def test_run_one_failure_is_a_row(recordings):
    _, _, bad = recordings
    row = run_one(["fit"], bad, ["--freq", "10"])
    assert not row.ok and "NaN at sample 1" in row.error and "\n" not in row.error


def test_local_cluster_two_workers(recordings):
    d, truth, bad = recordings
    files = sorted(truth) + [bad]
    done = []
    summary = run_batch("fit", files, ["--freq", "10"], workers=2, on_done=done.append)
    assert summary.workers == 2
    assert summary.n_ok == 5 and summary.n_failed == 1
    assert len(done) == 6
    for row in summary.rows:
        if row.file == bad:
            assert not row.ok
            continue
        ch = row.result["channels"]["x"]
        assert abs(ch["amplitude"] - truth[row.file]) < 4 * ch["u_amplitude"]


def test_cli_batch_exit_codes_and_table(cli, recordings, tmp_path):
    d, truth, bad = recordings
    out = tmp_path / "res.parquet"
    r = cli("batch", "fit", *sorted(truth), "--freq", "10", "--workers", "1", "--out", out, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["n_ok"] == 5
    df = pd.read_parquet(out)
    assert len(df) == 5 and "channels.x.amplitude" in df.columns
    r = cli("batch", "fit", str(d / "r*.csv"), "--freq", "10", "--workers", "1", "--files-per-task", "4")
    assert r.code == 4
    assert "1 of 6 recordings failed" in r.err


def test_flatten():
    assert flatten({"a": {"b": 1, "c": [1, 2]}, "d": [{"e": 3}]}) == {"a.b": 1, "a.c": "[1, 2]", "d.0.e": 3}


def test_array_fit_chunks_equal_in_memory(tmp_path):
    rng = np.random.default_rng(1)
    fs, n, c = 1000.0, 2000, 300
    t = np.arange(n) / fs
    amp = rng.uniform(0.5, 2.0, c)
    y = amp[:, None] * np.sin(2 * math.pi * 7 * t + 0.3) + rng.normal(0, 0.05, (c, n))
    path = tmp_path / "big.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("data", data=y).attrs["fs"] = fs
    from senscal import fit_sine

    ref = fit_sine(y, fs=fs, freq=7.0)
    a = fit_sine_dask(y, fs=fs, freq=7.0, chunk_channels=64)
    b = fit_hdf5_dataset(path, "data", freq=7.0, chunk_channels=70)
    for r in (a, b):
        np.testing.assert_allclose(r.amplitude, ref.amplitude, rtol=1e-12)
        np.testing.assert_allclose(r.u_phase, ref.u_phase, rtol=1e-9)
    # Within the reported uncertainty of the truth (4 sigma, 300 channels).
    assert np.max(np.abs(b.amplitude - amp) / b.u_amplitude) < 4.5
    with pytest.raises(InputError, match="no dataset 'nope'"):
        fit_hdf5_dataset(path, "nope", freq=7.0)


def test_cli_fit_array(cli, tmp_path):
    rng = np.random.default_rng(2)
    y = np.sin(2 * math.pi * 5 * np.arange(1000) / 200.0) + rng.normal(0, 0.01, (20, 1000))
    path = tmp_path / "a.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("d", data=y)
    r = cli("fit-array", path, "--dataset", "d", "--fs", "200", "--freq", "5", "--out", tmp_path / "o.csv", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["n_channels"] == 20
    assert len(pd.read_csv(tmp_path / "o.csv")) == 20
    r = cli("fit-array", path, "--dataset", "d", "--out", tmp_path / "o.csv")
    assert r.code == 2 and "sample rate" in r.err


def test_zarr_store_equals_hdf5(tmp_path):
    import zarr

    from senscal.batch.arrays import fit_stored_array

    rng = np.random.default_rng(3)
    fs, n, c = 500.0, 1500, 40
    y = np.sin(2 * math.pi * 11 * np.arange(n) / fs) * rng.uniform(0.5, 2, c)[:, None] + rng.normal(0, 0.02, (c, n))
    store = tmp_path / "big.zarr"
    grp = zarr.open_group(str(store), mode="w")
    arr = grp.create_array("data", shape=y.shape, chunks=(8, n), dtype="f8")
    arr[:] = y
    arr.attrs["fs"] = fs
    h5 = tmp_path / "big.h5"
    with h5py.File(h5, "w") as fh:
        fh.create_dataset("data", data=y).attrs["fs"] = fs
    a = fit_stored_array(store, "data", freq=11.0, chunk_channels=16)
    b = fit_stored_array(h5, "data", freq=11.0, chunk_channels=16)
    np.testing.assert_array_equal(a.amplitude, b.amplitude)
    with pytest.raises(InputError, match="no dataset 'x'"):
        fit_stored_array(store, "x", freq=11.0)
