"""Text recordings read without pandas give the same Recording as the pandas path, or are declined.

The fast path (``senscal.io._textfast``) exists for start-up time only: for every
file it must either decline (return ``None``, so pandas reads it) or give the
Recording, the warning-free result and the error that the pandas path gives,
value for value and bit for bit.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from senscal.errors import SenscalError
from senscal.io import read_recording, readers
from senscal.io._textfast import read_plain_columns

# -- what a text recording may hold ------------------------------------------

_MISSING = ["", "", "", "nan", "NaN", "+nan", "-nan"]
_SPECIAL = [" 1.5", "1.5 ", "+1", ".5", "5.", "1E+05", "-0", "0.1000000000000000055511151231257827",
            "2.2250738585072011e-308", "4.9e-324", "007", "1e-400"]
_INF = ["inf", "-inf", "1e400", "Infinity"]
_JUNK = ["abc", "1,5", '"2.5"', "NA", "1_000", "#3", "\u00b5", " ", "\t", "0x10", "1.5.2", "1;2", "--1", "e5"]
_FORMATS = ["{!r}", "{:.9g}", "{:.17g}", "{:.3e}", "{:g}", "{:.6f}"]


@st.composite
def _cell(draw, junk: bool, infs: bool) -> str:
    """One field: mostly numbers as programs write them; missing values, odd spellings; junk and inf when asked."""
    kind = draw(st.integers(0, 99))
    if kind < 55:
        x = draw(st.floats(allow_nan=False, allow_infinity=False, width=64))
        return draw(st.sampled_from(_FORMATS)).format(x)
    if kind < 70:
        return str(draw(st.integers(-10**6, 10**20)))
    if kind < 76:
        return draw(st.sampled_from(_MISSING))
    if kind < 92 or not (junk or infs):
        return draw(st.sampled_from(_SPECIAL))
    return draw(st.sampled_from(_JUNK if junk and (kind % 2 or not infs) else _INF))


_NAMES = ["x", "ch1", "acc_z", "y", "ch2"]
_NAMES_UNITS = ["x [m/s^2]", "ch1 (m/s^2)", "acc_z [g]", "y[V]", "ch2 [ m ]"]
_PREAMBLE = ["# comment text", "; Instrument: shaker", "Fs{sep}100", "% note", "// exported by DAQ",
             "Sample rate{sep}200", "#", "", "Operator{sep}Jo{sep}", "# quoted \"x\""]


@st.composite
def text_recordings(draw) -> tuple[bytes, dict]:
    """A text recording (bytes) and the read_recording options it is read with."""
    sep = draw(st.sampled_from([",", ";", "\t", " "]))
    width = draw(st.integers(1, 4))
    nrows = draw(st.integers(1, 30))
    junk = draw(st.integers(0, 9)) < 3
    infs = draw(st.integers(0, 9)) < 2
    header = draw(st.booleans())
    units = draw(st.booleans())
    time_name = draw(st.sampled_from(["t", "t [s]", "t [ms]", "t[s]", "time"] if units else ["t", "t", "time"]))
    names = [time_name] + draw(st.permutations(_NAMES_UNITS if units else _NAMES))[: width - 1]
    if sep == " ":
        names = [n.replace(" ", "") for n in names]
    rows = []
    dt = draw(st.sampled_from([1e-3, 0.01, 1.0, 1 / 3]))
    t_ok = draw(st.integers(0, 9)) > 0
    for i in range(nrows):
        t = draw(st.sampled_from(["{:.9g}", "{!r}", "{:g}"])).format(i * dt) if t_ok else draw(_cell(junk, infs))
        rows.append([t] + [draw(_cell(junk, infs)) for _ in range(width - 1)])
    if width > 1 and draw(st.booleans()):
        rows[0][1:] = [""] * (width - 1)  # a first data row with empty fields
    if draw(st.integers(0, 9)) == 0:
        rows[-1] = [""] * width  # a row of separators only
    if sep == " ":
        join = lambda fields: draw(st.sampled_from([" ", "  ", "\t", " \t "])).join(fields)  # noqa: E731
        lead = draw(st.sampled_from(["", " ", "  "]))
    else:
        join, lead = sep.join, ""
    lines = [draw(st.sampled_from(_PREAMBLE)).format(sep=sep if sep != " " else ",")
             for _ in range(draw(st.integers(0, 3)))]
    if header:
        lines.append((sep if sep != " " else " ").join(names))
    if draw(st.booleans()):
        lines.append("")
    lines += [lead + join(r) for r in rows]
    lines += [""] * draw(st.integers(0, 2))
    eol = draw(st.sampled_from(["\n", "\r\n", "\n", "\r\n", "\r"]))
    text = eol.join(lines) + (eol if draw(st.integers(0, 9)) > 0 else "")
    data = (b"\xef\xbb\xbf" if draw(st.booleans()) else b"") + text.encode("utf-8")
    options: dict = {"allow_nan": draw(st.integers(0, 3)) > 0}
    if not header:
        options["names"] = [n.split("[")[0].split("(")[0].strip() for n in names]
    if time_name == "time":
        options["fs"] = 100.0
    if draw(st.integers(0, 4)) == 0:
        options["skip_rows"] = draw(st.integers(0, len(lines) - len(rows)))
    if draw(st.integers(0, 9)) == 0:
        options["time_unit"] = "ms"
    return data, options


# -- reading both ways ---------------------------------------------------------

def _read(path: Path, options: dict, *, fast: bool):
    """("ok", Recording, fast path used) or ("error", type, message, fast path used)."""
    used = []

    def spy(*args, **kw):
        out = read_plain_columns(*args, **kw) if fast else None
        used.append(out is not None)
        return out

    with mock.patch.object(readers, "read_plain_columns", spy):
        try:
            rec = read_recording(path, **options)
        except SenscalError as exc:
            return ("error", type(exc).__name__, str(exc)), any(used)
    return ("ok", rec), any(used)


def _same_recording(a, b) -> None:
    assert list(a.names) == list(b.names)
    for name in a.names:
        x, y = a.channels[name], b.channels[name]
        assert x.dtype == y.dtype == np.float64
        assert np.array_equal(x, y, equal_nan=True), name
        assert x.tobytes() == y.tobytes(), f"{name}: not bit for bit (signed zero or NaN payload)"
    if a.t is None:
        assert b.t is None
    else:
        assert a.t.dtype == b.t.dtype and a.t.tobytes() == b.t.tobytes()
    assert (a.fs, a.t0, a.source, a.allow_nan) == (b.fs, b.t0, b.source, b.allow_nan)
    assert dict(a.units) == dict(b.units)
    assert dict(a.metadata) == dict(b.metadata)


def _check_parity(data: bytes, options: dict) -> bool:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "rec.csv"
        path.write_bytes(data)
        slow, _ = _read(path, options, fast=False)
        fast, used = _read(path, options, fast=True)
        assert path.read_bytes() == data, "the input file was modified"
    assert fast[0] == slow[0], (fast, slow)
    if fast[0] == "error":
        assert fast == slow
    else:
        _same_recording(fast[1], slow[1])
    return used


@given(text_recordings())
def test_fast_path_declines_or_matches_pandas(case):
    data, options = case
    used = _check_parity(data, options)
    event(f"fast path {'used' if used else 'declined'}")


# The formats users have, each of which the fast path must take (or it buys no start-up time).
_TAKEN = {
    "senscal writer": (b"t,x,y\n0,0.1,-2.5\n0.001,0.30000000000000004,1e-07\n0.002,,3\n", {"allow_nan": True}),
    "savetxt %.9g": (b"t,ch1,ch2\n0,0.299999999,0\n0.001,0.42913,0.0312\n", {}),
    "units in header": ("t [ms],acc_z [m/s^2],ch1 (V)\n0,1,2\n1,1.5,2.5\n".encode(), {}),
    "comment preamble": (b"# rig 3\n; operator: Jo\nFs,1000\nx;y\n1;2\n3;4\n", {}),
    "CRLF and BOM": (b"\xef\xbb\xbft\tx\r\n0\t1\r\n1\t2\r\n\r\n", {}),
    "whitespace, no header": (b"  0   1.5  2\n  1   2.5  3\n", {"names": ["t", "a", "b"]}),
    "first row empty": (b"t,a,b\n0,,\n1,2,3\n2,3,4\n\n\n", {"allow_nan": True}),
    "integer columns": (b"t,count\n0,17\n1,18\n2,19\n", {}),
}


@pytest.mark.parametrize("name", sorted(_TAKEN))
def test_common_layouts_take_the_fast_path(name):
    data, options = _TAKEN[name]
    assert _check_parity(data, options), f"{name}: the fast path declined a plain numeric file"


@pytest.mark.parametrize("sep, body", [
    (",", b"t,x\n0,1\n1,\"2\"\n"), (",", b"t,x\n0,1\n1,2 # note\n"), (";", b"t;x\n0;1,5\n1;2,5\n"),
    (",", b"t,x\n0,-nan\n1,2\n"), (",", b"t,x\n0,1\r1,2\r"), (",", b"t,x\n0,1\n1,2,\n"), (",", b"t,x\n0, \n1,2\n"),
    (",", b"t,x\n0,1\n  \n1,2\n"), (",", "t,x\n0,1\n1,\u00b5\n".encode()), (",", b"t,x\n0,NA\n1,2\n"),
    (",", b"t,x\n0,1\n1\n"), (",", b"t,x\n0,1e5e\n1,2\n")])
def test_what_only_pandas_reads_is_declined(sep, body, tmp_path):
    path = tmp_path / "d.csv"
    path.write_bytes(body)
    assert read_plain_columns(path, sep=sep, width=2, skip=1) is None
    _check_parity(body, {"allow_nan": True})


def test_fit_of_a_small_csv_imports_no_pandas(tmp_path):
    t = np.arange(2000) / 1000.0
    data = np.column_stack([t, 2.0 * np.sin(2 * np.pi * 12.5 * t + 0.3), 0.5 * np.sin(2 * np.pi * 12.5 * t)])
    path = tmp_path / "small.csv"
    np.savetxt(path, data, delimiter=",", header="t,ch1,ch2", comments="", fmt="%.9g")
    probe = ("import atexit, runpy, sys\n"
             "atexit.register(lambda: sys.stderr.write('PANDAS=%s\\n' % ('pandas' in sys.modules)))\n"
             f"sys.argv = ['senscal', 'fit', {str(path)!r}, '--json']\n"
             "runpy.run_module('senscal', run_name='__main__', alter_sys=True)\n")
    env = {k: v for k, v in os.environ.items() if k != "SENSCAL_MC"}
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert '"ch1"' in r.stdout
    assert "PANDAS=False" in r.stderr, "senscal fit of a small CSV imported pandas"
