"""Batch runs on a real LocalCluster with two worker processes."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pandas as pd
import pytest

from senscal.batch import check_job, expand_files, flatten, run_batch, run_one
from senscal.batch.arrays import fit_hdf5_dataset, fit_sine_dask
from senscal.errors import InputError
from senscal.io import Recording, write_recording
from senscal.jobs.fit import FitOptions


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
    assert check_job("fit") == "fit"
    with pytest.raises(InputError, match="unknown batch job 'nope'"):
        check_job("nope")
    with pytest.raises(InputError, match="'linearity' combines"):
        check_job("linearity")


def test_expand_files(recordings):
    d, truth, bad = recordings
    files = expand_files([str(d / "r*.csv")])
    assert len(files) == 6
    with pytest.raises(InputError, match="no file matches"):
        expand_files([str(d / "zz*.csv")])


def test_run_one_failure_is_a_row(recordings):
    _, _, bad = recordings
    row = run_one("fit", bad, FitOptions(freq=10.0))
    assert not row.ok and "NaN in data row 2" in row.error and "\n" not in row.error


def test_run_one_strict_fails_a_recording_with_warnings(tmp_path):
    # A constant column is skipped with a channel-not-fitted warning: fine alone, a failure under --strict.
    t = np.arange(500) / 500.0
    noise = np.random.default_rng(4).normal(0, 0.01, t.size)
    rec = Recording(channels={"x": np.sin(2 * math.pi * 10 * t) + noise, "c": np.ones(t.size)}, t=t)
    p = str(write_recording(rec, tmp_path / "w.csv"))
    ok = run_one("fit", p, FitOptions(freq=10.0))
    assert ok.ok and [w.split(":")[0] for w in ok.result["warnings"]] == ["channel-not-fitted"]
    row = run_one("fit", p, FitOptions(freq=10.0), strict=True)
    assert not row.ok and row.error.startswith("--strict: channel-not-fitted")


def test_local_cluster_two_workers(recordings):
    d, truth, bad = recordings
    files = sorted(truth) + [bad]
    done = []
    summary = run_batch("fit", files, FitOptions(freq=10.0), workers=2, on_done=done.append)
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


def _no_cluster(monkeypatch):
    """Make starting a cluster fail loudly: the checks below must refuse before that."""
    import dask.distributed
    import distributed

    def boom(*a, **k):
        raise AssertionError("a cluster was started for input that should have been refused")

    for mod in (distributed, dask.distributed):
        monkeypatch.setattr(mod, "LocalCluster", boom)
        monkeypatch.setattr(mod, "Client", boom)


@pytest.mark.parametrize("words, pattern", [
    (["--save", "--sensor", "SN-1"], "--save applies to a single run of 'senscal fit'"),
    (["--db", "reg.db"], "--db applies to a single run"),
    (["--bogus"], "No such option: --bogus"),
])
def test_cli_batch_refuses_single_run_and_unknown_options(cli, recordings, monkeypatch, words, pattern):
    _no_cluster(monkeypatch)
    d, truth, _ = recordings
    r = cli("batch", "fit", *sorted(truth), "--freq", "10", *words)
    assert r.code == 2 and pattern in r.err and len(r.err.strip().splitlines()) == 1, r.err


def test_cli_batch_job_without_options_builder_is_one_line(cli, recordings, monkeypatch):
    import senscal.cli.cmd_fit as cmd_fit

    _no_cluster(monkeypatch)
    monkeypatch.setattr(cmd_fit, "JOB_OPTIONS", {})
    d, truth, _ = recordings
    r = cli("batch", "fit", *sorted(truth), "--freq", "10")
    assert r.code == 2 and "cannot run 'fit' yet" in r.err and len(r.err.strip().splitlines()) == 1


def test_cli_batch_options_equal_the_commands_own(recordings):
    # The batch parses a job's words with the command's own parser and builder: same Options as the command.
    from senscal.cli.cmd_batch import job_options

    d, truth, _ = recordings
    f = sorted(truth)[0]
    opts, strict = job_options("fit", f, ["--freq", "10", "-c", "x", "--harmonics", "2", "--strict"])
    assert opts == FitOptions(channels=("x",), freq=10.0, harmonics=2) and strict
    assert job_options("fit", f, [])[0] == FitOptions()


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


@pytest.mark.parametrize("args, pattern", [
    (["--dataset", "nope", "--fs", "200"], "no dataset 'nope'"),
    (["--dataset", "d", "--fs", "200", "--freq", "150"], "Nyquist"),
    (["--dataset", "d"], "sample rate"),
    (["--dataset", "d", "--fs", "200", "--chunk", "0"], "--chunk"),
])
def test_cli_fit_array_checks_input_before_a_cluster(cli, tmp_path, monkeypatch, args, pattern):
    _no_cluster(monkeypatch)
    path = tmp_path / "a.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("d", data=np.zeros((3, 100)))
    r = cli("fit-array", path, *args, "--workers", "2", "--out", tmp_path / "o.csv")
    assert r.code == 2 and pattern in r.err and len(r.err.strip().splitlines()) == 1, r.err
    r = cli("fit-array", tmp_path / "missing.h5", "--dataset", "d", "--workers", "2", "--out", tmp_path / "o.csv")
    assert r.code == 2 and "not found" in r.err


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
