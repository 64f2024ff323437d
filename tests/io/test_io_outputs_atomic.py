"""Outputs are written atomically: a failed write leaves the old file (or nothing), never half a file."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.io import Recording, write_recording
from senscal.io.guard import atomic_output, write_text

DEV_FULL = Path("/dev/full")


@pytest.fixture
def rec():
    return Recording(channels={"x": np.arange(1000.0)}, fs=100.0)


@pytest.mark.parametrize("ext", [".csv", ".parquet", ".h5", ".tdms", ".npz"])
def test_failed_write_keeps_the_old_file_and_leaves_no_temp(rec, tmp_path, ext, monkeypatch):
    path = tmp_path / f"r{ext}"
    path.write_bytes(b"old content")

    def broken_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(InputError, match="no space left on device"):
        write_recording(rec, path)
    assert path.read_bytes() == b"old content"
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]


def test_exception_inside_the_block_removes_the_temp_file(tmp_path):
    path = tmp_path / "a.json"
    with pytest.raises(RuntimeError):
        with atomic_output(path) as tmp:
            tmp.write_text("{half")
            raise RuntimeError("writer crashed")
    assert list(tmp_path.iterdir()) == []


def test_read_only_output_is_refused_and_untouched(rec, tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("keep me\n")
    path.chmod(stat.S_IRUSR | stat.S_IRGRP)
    try:
        with pytest.raises(InputError, match="read-only") as info:
            write_recording(rec, path)
        assert "\n" not in str(info.value) and str(path) in str(info.value)
        assert path.read_text() == "keep me\n"
    finally:
        path.chmod(stat.S_IRUSR | stat.S_IWUSR)


def test_new_file_gets_ordinary_permissions(tmp_path):
    path = write_text(tmp_path / "a.txt", "x")
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask


@pytest.mark.skipif(not DEV_FULL.exists(), reason="needs Linux /dev/full")
def test_full_device_is_one_line_and_the_device_is_not_replaced(tmp_path):
    with pytest.raises(InputError, match="no space left on device") as info:
        write_text(DEV_FULL, "x" * 100000)
    assert "\n" not in str(info.value)
    assert stat.S_ISCHR(DEV_FULL.stat().st_mode)


@pytest.mark.skipif(not DEV_FULL.exists(), reason="needs Linux /dev/full")
def test_cli_output_to_dev_full_exits_2(cli, tmp_path):
    t = np.linspace(0, 1, 200)
    mag = np.stack([np.cos(2 * np.pi * t) * np.cos(t), np.sin(2 * np.pi * t) * np.cos(t), np.sin(t)])
    f = write_recording(Recording(channels=dict(zip("xyz", 50.0 * mag)), t=t), tmp_path / "m.csv")
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--out", DEV_FULL)
    assert r.code == 2, r.err
    last = r.err.strip().splitlines()[-1]
    assert last.startswith("senscal: error: cannot write ") and last.endswith(" /dev/full: no space left on device")
