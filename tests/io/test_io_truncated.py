"""A CSV whose last line was cut off is refused, not read as a shorter valid recording (issue 20 item 5)."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.errors import DataError
from senscal.io import read_recording


def _write(path, text: str):
    path.write_bytes(text.encode())
    return path


BODY = "t,x,y\n" + "".join(f"{i / 100:.4f},{np.sin(i):.6f},{np.cos(i):.6f}\n" for i in range(200))


def test_number_cut_off_in_last_line_is_refused(tmp_path):
    cut = BODY.rstrip("\n")[:-4]          # the last value loses four digits, no line end
    with pytest.raises(DataError, match="truncated"):
        read_recording(_write(tmp_path / "a.csv", cut))


def test_missing_fields_in_last_line_is_refused(tmp_path):
    cut = BODY + "2.0000,0.5"             # header has three columns
    with pytest.raises(DataError, match="truncated"):
        read_recording(_write(tmp_path / "b.csv", cut))


def test_complete_files_with_or_without_final_line_break_are_read(tmp_path):
    rec = read_recording(_write(tmp_path / "c.csv", BODY))
    assert rec.n_samples == 200 if hasattr(rec, "n_samples") else rec.time.size == 200
    rec2 = read_recording(_write(tmp_path / "d.csv", BODY.rstrip("\n")))
    np.testing.assert_array_equal(rec.time, rec2.time)
    # variable-width numbers: a naturally short last line is not a truncation
    text = "t,x\n" + "".join(f"{i},{v}\n" for i, v in enumerate([10.25, -3.5, 7.125, 2.5])) + "4,1.5"
    assert read_recording(_write(tmp_path / "e.csv", text)).time.size == 5


def test_cli_says_so_in_one_line(cli, tmp_path):
    p = _write(tmp_path / "a.csv", BODY.rstrip("\n")[:-4])
    before = p.read_bytes()
    r = cli("fit", p, "--freq", "1")
    assert r.code == 2 and "truncated" in r.err and len(r.err.strip().splitlines()) == 1
    assert p.read_bytes() == before
