"""Readers on damaged and odd files: one FileFormatError/DataError line naming the file, never anything else.

Regression tests for issue 19 (corrupt or odd input files) and issue 20 item 1
(duplicate column names in every format), and issue 15 item 6 (CSV preambles).
"""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from senscal.errors import DataError, FileFormatError, InputError, SenscalError
from senscal.io import Recording, read_recording, write_recording


@pytest.fixture
def rec():
    t = np.arange(50) / 100.0
    return Recording(channels={"x": np.sin(t), "y": np.cos(t)}, t=t, units={"x": "V"})


def _one_line_naming(exc: SenscalError, path) -> str:
    msg = str(exc)
    assert "\n" not in msg
    assert str(path) in msg
    return msg


def _refused(path, exc_type=FileFormatError, match=None, **kw) -> str:
    with pytest.raises(exc_type) as info:
        read_recording(path, **kw)
    msg = _one_line_naming(info.value, path)
    if match:
        assert match in msg, msg
    return msg


# -- NPZ ---------------------------------------------------------------------------------------------------

def test_npz_flipped_bytes_and_truncation(rec, tmp_path):
    good = write_recording(rec, tmp_path / "r.npz").read_bytes()
    rng = np.random.default_rng(0)
    for i in range(30):
        data = bytearray(good)
        for j in rng.integers(0, len(data), 4):
            data[int(j)] ^= 0xFF
        p = tmp_path / f"bad{i}.npz"
        p.write_bytes(bytes(data[: int(rng.integers(10, len(data)))]) if i % 2 else bytes(data))
        try:
            read_recording(p)
        except SenscalError as exc:
            _one_line_naming(exc, p)


def test_npz_object_array_is_refused_not_unpickled(tmp_path):
    p = tmp_path / "obj.npz"
    np.savez(p, t=np.arange(3.0), x=np.array([1, "a", None], dtype=object))
    _refused(p, match="Python objects")


def test_npz_metadata_of_the_wrong_type(tmp_path):
    p = tmp_path / "m.npz"
    np.savez(p, t=np.arange(3.0), x=np.ones(3), __senscal__=np.array(json.dumps([1, 2])))
    _refused(p, match="not a mapping")
    np.savez(p, t=np.arange(3.0), x=np.ones(3), __senscal__=np.array(json.dumps({"units": ["V"]})))
    _refused(p, match="units")
    np.savez(p, t=np.arange(3.0), x=np.ones(3), __senscal__=np.array("{not json"))
    _refused(p, match="not valid JSON")


def test_npz_complex_and_bad_fs(tmp_path):
    p = tmp_path / "c.npz"
    np.savez(p, t=np.arange(3.0), x=np.ones(3, dtype=complex))
    _refused(p, DataError, match="complex")
    np.savez(p, x=np.ones(3), fs=np.float64(0.0))
    _refused(p, match="sample rate")
    np.savez(p, x=np.ones(3), fs=np.float64(np.inf))
    _refused(p, match="finite")


def test_npz_duplicate_member_names(tmp_path):
    p = tmp_path / "dup.npz"
    buf = tmp_path / "x.npy"
    np.save(buf, np.ones(3))
    with zipfile.ZipFile(p, "w") as z, pytest.warns(UserWarning):
        z.write(buf, "x.npy")
        z.write(buf, "x.npy")
        np.save(buf, np.arange(3.0))
        z.write(buf, "t.npy")
    _refused(p, match="twice")


# -- Parquet -------------------------------------------------------------------------------------------------

def test_parquet_metadata_not_json_or_not_a_mapping(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = tmp_path / "m.parquet"
    tab = pa.table({"t": np.arange(3.0), "x": np.ones(3)})
    pq.write_table(tab.replace_schema_metadata({b"senscal": b"{oops"}), p)
    _refused(p, match="not valid JSON")
    pq.write_table(tab.replace_schema_metadata({b"senscal": b"[1, 2]"}), p)
    _refused(p, match="not a mapping")
    pq.write_table(tab.replace_schema_metadata({b"senscal": json.dumps({"fs": "fast"}).encode()}), p)
    _refused(p, match="sample rate")


def test_parquet_duplicate_and_string_columns(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = tmp_path / "d.parquet"
    pq.write_table(pa.Table.from_arrays([pa.array(np.arange(3.0)), pa.array(np.ones(3)), pa.array(np.zeros(3))],
                                        names=["t", "x", "x"]), p)
    _refused(p, match="duplicate")
    pq.write_table(pa.table({"t": np.arange(3.0), "x": ["1", "two", "3"]}), p)
    _refused(p, DataError, match="'two'")


def test_parquet_garbage(tmp_path):
    p = tmp_path / "g.parquet"
    p.write_bytes(b"PAR1" + bytes(range(256)) * 4 + b"PAR1")
    _refused(p, match="not a readable Parquet file")


# -- HDF5 ----------------------------------------------------------------------------------------------------

def test_hdf5_odd_datasets(tmp_path):
    import h5py

    p = tmp_path / "h.h5"
    with h5py.File(p, "w") as fh:
        fh["t"] = np.arange(3.0)
        fh["x"] = np.array([b"1", b"x", b"3"])
    _refused(p, DataError, match="non-numeric")
    with h5py.File(p, "w") as fh:
        fh["t"] = np.arange(3.0)
        fh["x"] = np.zeros(3, dtype=[("a", "f8"), ("b", "i4")])
    _refused(p, DataError, match="compound")
    with h5py.File(p, "w") as fh:
        fh["t"] = np.arange(3.0)
        fh["x"] = np.ones(3, dtype=np.float16)
        fh["g/y"] = np.ones(3)
    assert read_recording(p).names == ["x"]  # exotic float widths are fine
    _refused(p, match="is a dataset, not a group", group="x")
    with h5py.File(p, "w") as fh:
        fh["x"] = np.ones(3)
        fh.attrs["fs"] = np.array([1.0, 2.0])
    _refused(p, match="sample rate")
    with h5py.File(p, "w") as fh:
        fh["t"] = np.arange(3.0)
        fh["x"] = np.ones(3)
        fh.attrs["metadata"] = "{bad"
    _refused(p, match="metadata")


def test_hdf5_damaged_bytes(rec, tmp_path):
    good = write_recording(rec, tmp_path / "r.h5").read_bytes()
    rng = np.random.default_rng(1)
    for i in range(40):
        data = bytearray(good)
        for j in rng.integers(0, len(data), 8):
            data[int(j)] = int(rng.integers(0, 256))
        p = tmp_path / f"bad{i}.h5"
        p.write_bytes(bytes(data))
        try:
            read_recording(p)
        except SenscalError as exc:
            _one_line_naming(exc, p)


# -- TDMS ----------------------------------------------------------------------------------------------------

def test_tdms_zero_increment(tmp_path):
    from nptdms import ChannelObject, TdmsWriter

    p = tmp_path / "z.tdms"
    with TdmsWriter(p) as w:
        w.write_segment([ChannelObject("g", "acc", np.ones(8), properties={"wf_increment": 0.0})])
    # An increment of zero is "no sample rate", not a division by zero.
    _refused(p, match="no time column")
    with TdmsWriter(p) as w:
        w.write_segment([ChannelObject("g", "acc", np.ones(8), properties={"wf_increment": -0.01})])
    _refused(p, match="positive")


# -- CSV -----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("header, match", [("t,ch1 [V],ch1 [mV]", "both read as 'ch1'"),
                                           ("t,ch1,ch1", "'ch1' twice"),
                                           ("t [ms],t,x", "both read as 't'")])
def test_csv_duplicate_column_names(tmp_path, header, match):
    p = tmp_path / "d.csv"
    p.write_text(header + "\n0,1,2\n1,2,3\n")
    _refused(p, match=match)


def test_duplicates_refused_in_every_binary_format(tmp_path):
    # HDF5 and TDMS cannot hold two channels of one name in a group; Parquet and NPZ can (tested above).
    import h5py

    p = tmp_path / "u.h5"
    with h5py.File(p, "w") as fh:
        fh["t"] = np.arange(3.0)
        fh["x"] = np.ones(3)
    assert read_recording(p).names == ["x"]


def test_csv_preamble_key_value_lines_and_fs(tmp_path):
    p = tmp_path / "qmc.csv"
    p.write_text("Fs,50.00\nInitialization time,60\nmx,my,mz\n6202,682,4812\n6177,682,4827\n6190,680,4830\n")
    r = read_recording(p)
    assert r.names == ["mx", "my", "mz"] and r.fs == 50.0 and r.n_samples == 3
    assert r.metadata["Initialization time"] == "60"


def test_csv_oscilloscope_comment_preamble(tmp_path):
    p = tmp_path / "scope.csv"
    p.write_text(";Scopy version,48fb6a9\n;Device,M2K\n;Sample rate,1e+06\n;Additional Information,\n"
                 "Sample,Time(S),CH1(V)\n0,-0.004,0.1\n1,-0.003999,0.2\n2,-0.003998,0.3\n")
    r = read_recording(p, time_column="Time(S)")
    assert r.names == ["Sample", "CH1(V)"]
    np.testing.assert_allclose(r.time, [-0.004, -0.003999, -0.003998])
    assert r.metadata["Device"] == "M2K"
    r2 = read_recording(p, time_column="none")  # no time column: the preamble's rate is used
    assert r2.fs == 1e6


def test_csv_skip_rows_and_headerless_without_time(tmp_path):
    p = tmp_path / "odd.csv"
    p.write_text("produced by a logger\nserial 12\nx,y,z\n1,2,3\n4,5,6\n")
    r = read_recording(p, skip_rows=2, time_required=False)
    assert r.names == ["x", "y", "z"] and r.metadata["time_basis"].startswith("sample index")
    with pytest.raises(InputError, match="skip-rows"):
        read_recording(p, skip_rows=-1)
    h = tmp_path / "xyz.csv"
    h.write_text("1,2,3\n4,5,6\n7,8,9\n")
    _refused(h, match="--names x,y,z".replace("x,y,z", "t,x,y"))
    r = read_recording(h, names=["x", "y", "z"], time_required=False)
    assert r.n_samples == 3 and r.fs == 1.0
    _refused(h, match="no time column", names=["x", "y", "z"])


def test_csv_binary_and_non_utf8(tmp_path):
    p = tmp_path / "b.csv"
    p.write_bytes(b"t,x\n0,1\n\x00\x01\x02\n")
    _refused(p, match="NUL")
    p.write_bytes(b"t,x\n0,1\n1,\xff\xfe\n")
    _refused(p, match="UTF-8")


def test_fs_argument_must_be_positive_and_finite(rec, tmp_path):
    p = write_recording(Recording(channels={"x": np.ones(4)}, fs=10.0), tmp_path / "f.npz")
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(InputError, match="--fs"):
            read_recording(p, fs=bad)
