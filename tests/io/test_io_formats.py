"""Readers/writers: the same data in every format gives the same results."""

from __future__ import annotations

import math
import os
import stat

import numpy as np
import pytest

from senscal import fit_sine
from senscal.errors import DataError, FileFormatError, InputError, SenscalError
from senscal.io import Recording, read_recording, write_recording


@pytest.fixture
def rec():
    rng = np.random.default_rng(0)
    fs = 200.0
    t = 10.0 + np.arange(600) / fs
    chans = {
        "a": 2.0 * np.sin(2 * math.pi * 5.0 * t + 0.3) + 0.1 + rng.normal(0, 0.01, t.size),
        "b": 0.5 * np.sin(2 * math.pi * 5.0 * t - 1.0) + rng.normal(0, 0.01, t.size),
    }
    return Recording(channels=chans, t=t, units={"a": "V", "b": "m/s^2"})


@pytest.mark.parametrize("ext", [".csv", ".parquet", ".h5", ".tdms", ".npz"])
def test_round_trip_same_fit(rec, tmp_path, ext):
    path = write_recording(rec, tmp_path / f"rec{ext}", units_in_header=True)
    back = read_recording(path)
    assert back.names == ["a", "b"]
    np.testing.assert_array_equal(back.time, rec.time)
    np.testing.assert_array_equal(back.data(), rec.data())
    assert back.unit("b") == "m/s^2"
    f1 = fit_sine(rec.data(), rec.time, freq=5.0)
    f2 = fit_sine(back.data(), back.time, freq=5.0)
    np.testing.assert_array_equal(f1.amplitude, f2.amplitude)


@pytest.mark.parametrize("ext", [".parquet", ".h5", ".tdms", ".npz"])
def test_sample_rate_recordings_keep_fs(tmp_path, ext):
    rec = Recording(channels={"x": np.arange(10.0)}, fs=50.0, t0=2.0)
    back = read_recording(write_recording(rec, tmp_path / f"r{ext}"))
    assert back.fs == pytest.approx(50.0)
    np.testing.assert_allclose(back.time, rec.time)


def test_tdms_waveform_increment_written_by_nptdms(tmp_path):
    from nptdms import ChannelObject, TdmsWriter

    path = tmp_path / "wf.tdms"
    with TdmsWriter(path) as w:
        w.write_segment([ChannelObject("g", "acc", np.ones(8), properties={"wf_increment": 0.01, "unit_string": "g"})])
    rec = read_recording(path)
    assert rec.sample_rate == pytest.approx(100.0)
    assert rec.unit("acc") == "g"


def test_csv_header_names_bare_by_default(rec, tmp_path):
    p = write_recording(rec, tmp_path / "plain.csv")
    assert p.read_text().splitlines()[0] == "t,a,b"


def test_csv_from_another_program(tmp_path):
    # Semicolon separated, units in brackets, comment line, spaces.
    p = tmp_path / "x.csv"
    p.write_text("# exported by a DAQ\nt; accel [m/s^2]; v [V]\n0.0; 1.0; 2.0\n0.1; 1.5; 2.5\n0.2; 1.2; 2.2\n")
    rec = read_recording(p)
    assert rec.names == ["accel", "v"]
    assert rec.unit("accel") == "m/s^2"
    np.testing.assert_allclose(rec["v"], [2.0, 2.5, 2.2])


def test_headerless_text_needs_names(tmp_path):
    p = tmp_path / "raw.txt"
    p.write_text("0.00 1 2 3\n0.01 1 2 3\n0.02 1 2 4\n")
    with pytest.raises(FileFormatError, match="no header row"):
        read_recording(p)
    rec = read_recording(p, names=["t", "x", "y", "z"])
    assert rec.names == ["x", "y", "z"] and rec.n_samples == 3


def test_fs_instead_of_time_column(tmp_path):
    p = tmp_path / "nots.csv"
    p.write_text("x,y\n1,2\n3,4\n5,6\n")
    with pytest.raises(FileFormatError, match="--fs"):
        read_recording(p)
    rec = read_recording(p, fs=10.0)
    np.testing.assert_allclose(rec.time, [0.0, 0.1, 0.2])


@pytest.mark.parametrize(
    "text, error, pattern",
    [
        ("t,x\n0,1\n1,abc\n2,3\n", DataError, r"non-numeric value 'abc' in data row 2 \(the 2nd row below the header\)"),
        ("t,x\n0,1\n1,nan\n2,3\n", DataError, r"channel 'x'.*NaN in data row 2"),
        ("t,x\n0,1\n1,inf\n2,3\n", DataError, r"inf in data row 2"),
        ("t,x\n0,1\n2,1\n1,3\n", DataError, r"non-monotonic .* in data row 3"),
        ("t,x\n0,1\n0,1\n1,3\n", DataError, r"duplicate in data row 2"),
        ("t,x\n", FileFormatError, r"no data rows"),
    ],
)
def test_bad_csv(tmp_path, text, error, pattern):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    before = p.read_bytes()
    with pytest.raises(error, match=pattern) as exc:
        read_recording(p)
    assert "\n" not in str(exc.value)
    assert p.read_bytes() == before  # input never modified


def test_missing_empty_and_unknown(tmp_path):
    with pytest.raises(FileFormatError, match="file not found"):
        read_recording(tmp_path / "nope.csv")
    e = tmp_path / "empty.csv"
    e.write_text("")
    with pytest.raises(FileFormatError, match="empty"):
        read_recording(e)
    g = tmp_path / "good.csv"
    g.write_text("t,x,y\n0,1,2\n1,2,3\n")
    with pytest.raises(InputError, match="no channel 'z'.*channels are: x, y"):
        read_recording(g, channels=["z"])
    with pytest.raises(SenscalError, match="no channel 'q'.*x, y"):
        read_recording(g)["q"]
    with pytest.raises(FileFormatError, match="extension"):
        read_recording(write_bytes(tmp_path / "f.xyz"))


def write_bytes(p):
    p.write_bytes(b"1,2\n")
    return p


def test_allow_nan_keeps_missing(tmp_path):
    p = tmp_path / "gaps.csv"
    p.write_text("t,x\n0,1\n1,\n2,3\n")
    rec = read_recording(p, allow_nan=True)
    assert np.isnan(rec["x"][1])


def test_recording_is_immutable(rec):
    with pytest.raises(ValueError):
        rec["a"][0] = 5.0
    sl = rec.slice(100, 200)
    assert sl.n_samples == 100 and sl.time[0] == rec.time[100]


def test_input_file_not_modified_by_reading(rec, tmp_path):
    p = write_recording(rec, tmp_path / "r.parquet")
    os.chmod(p, stat.S_IRUSR)
    mtime = p.stat().st_mtime_ns
    read_recording(p)
    assert p.stat().st_mtime_ns == mtime
