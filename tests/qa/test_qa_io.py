"""QA: --fs against a file that has its own time stamps."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.io import Recording, read_recording, write_recording


@pytest.fixture
def timed(tmp_path):
    t = np.arange(500) / 1000.0
    return write_recording(Recording({"x": np.sin(2 * np.pi * 12.5 * t)}, t=t), tmp_path / "s.csv")


def test_contradicting_fs_is_refused(timed):
    # Silently using --fs 500 halved every fitted frequency.
    with pytest.raises(InputError, match="contradicts the time column"):
        read_recording(timed, fs=500.0)


def test_agreeing_fs_is_accepted(timed):
    rec = read_recording(timed, fs=1000.0)
    assert rec.sample_rate == pytest.approx(1000.0)


def test_cli_fit_with_contradicting_fs(cli, timed):
    r = cli("fit", timed, "--fs", "500")
    assert r.code == 2 and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err


def _ms_file(path, unit):
    t = np.arange(1000) / 1000.0
    path.write_text(f"t [{unit}],x\n" + "".join(f"{float(1000 * a)!r},{float(np.sin(2 * np.pi * 10 * a))!r}\n" for a in t))
    return path


def test_time_column_in_milliseconds_is_converted(tmp_path):
    # It was read as seconds: a 10 Hz sine came out at 0.01 Hz.
    rec = read_recording(_ms_file(tmp_path / "ms.csv", "ms"))
    assert rec.sample_rate == pytest.approx(1000.0)


def test_unknown_time_unit_is_refused(cli, tmp_path):
    r = cli("fit", _ms_file(tmp_path / "f.csv", "fortnight"))
    assert r.code == 2 and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err
