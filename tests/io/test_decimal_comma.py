"""Excel CSV with ';' and decimal commas (issue 31 item 5): read, or refused with a message that says so;
row numbers in messages count from 1, as the user counts the data rows below the header."""

from __future__ import annotations

import json

import numpy as np
import pytest

from senscal.errors import DataError, FileFormatError
from senscal.io import read_recording


def _excel(path, header="t;x", sep=";", preamble=""):
    t = np.arange(200) / 1000.0
    x = np.sin(2 * np.pi * 12.5 * t)
    rows = "".join(f"{a:.6f}{sep}{b:.6f}\n".replace(".", ",") for a, b in zip(t, x))
    path.write_text(preamble + header + "\n" + rows, encoding="utf-8")
    return t, x


@pytest.mark.parametrize("header,sep,preamble", [
    ("t;x", ";", ""), ("t [s];x [mV]", ";", ""), ("t\tx", "\t", ""), ("t;x", ";", "# exported by Excel\nFs;1000\n"),
])
def test_semicolon_and_tab_files_with_decimal_commas_are_read(tmp_path, header, sep, preamble):
    f = tmp_path / "excel.csv"
    t, x = _excel(f, header, sep, preamble)
    rec = read_recording(f)
    np.testing.assert_allclose(rec.time, np.round(t, 6))
    np.testing.assert_allclose(rec["x"], np.round(x, 6))
    if "mV" in header:
        assert rec.unit("x") == "mV"


def test_fit_reads_an_excel_file(cli, tmp_path):
    f = tmp_path / "excel.csv"
    _excel(f)
    r = cli("fit", f, "--json")
    assert r.code == 0, r.err
    ch = json.loads(r.out)["channels"]["x"]
    assert ch["frequency_hz"] == pytest.approx(12.5, abs=1e-3) and ch["amplitude"] == pytest.approx(1.0, abs=1e-3)


def test_decimal_commas_in_a_comma_separated_file_are_explained(cli, tmp_path):
    f = tmp_path / "commas.csv"
    f.write_text("t,x\n0,0,1,5\n0,1,2,5\n0,2,3,5\n", encoding="utf-8")
    with pytest.raises(FileFormatError, match="decimal commas"):
        read_recording(f)
    r = cli("fit", f)
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "decimal comma" in r.err


def test_mixed_decimal_marks_are_refused_naming_both(tmp_path):
    f = tmp_path / "mixed.csv"
    f.write_text("t;x\n0;1,5\n1;2.5\n2;3,5\n3;1,0\n", encoding="utf-8")
    with pytest.raises(DataError, match=r"mixes decimal commas \('1,5' in data row 1\) with decimal points "
                                        r"\('2.5' in data row 2\)"):
        read_recording(f)


def test_a_decimal_comma_cell_among_numbers_is_named_as_such(tmp_path):
    f = tmp_path / "odd.csv"
    f.write_text("t;x\n0;1\n1;2\n2;3 V\n", encoding="utf-8")
    with pytest.raises(DataError, match=r"'3 V' in data row 3 \(the 3rd row below the header\); keep only numbers"):
        read_recording(f)


def test_rows_count_from_one(tmp_path):
    f = tmp_path / "nan.csv"
    f.write_text("t,x\n0,1\n1,2\n2,nan\n", encoding="utf-8")
    with pytest.raises(DataError, match="NaN in data row 3"):
        read_recording(f)
    f.write_text("t,x\n0,1\n1,2\n1,3\n", encoding="utf-8")
    with pytest.raises(DataError, match=r"duplicate in data row 3 \(t=1.0 then 1.0\)"):
        read_recording(f)
