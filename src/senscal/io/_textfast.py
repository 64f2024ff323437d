"""Plain numeric text bodies read without pandas (the start-up of ``senscal fit small.csv``).

:func:`senscal.io.readers._read_csv` decides the layout of a text recording
(preamble, header, separator, width, first body line) itself; the body it then
hands to pandas is, in almost every file a user has, nothing but numbers,
separators and line breaks.  Importing pandas for that costs about 0.3 s, more
than reading the whole file.  :func:`read_plain_columns` reads such a body with
:func:`numpy.loadtxt` and returns exactly what the pandas path returns, or
``None`` ("not certain") for anything else, so that pandas reads it and raises
its own errors:

- the pandas path reads every field as text (``dtype=object``) and converts it
  with Python's ``float()``; :func:`numpy.loadtxt` converts with the same
  correctly rounded ``PyOS_string_to_double``, so the values agree bit for bit
  (pandas' own C float parser, which can differ in the last ulp, is never used);
- an empty field is missing (NaN) in both; a field of blanks, a negative NaN
  (``-nan``, which pandas reads as a plain NaN), quotes, comments, decimal
  commas, other separators, non-ASCII text, a lone CR, blank-only lines and rows
  of another width are declined.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

__all__ = ["FAST_MAX_BYTES", "read_plain_columns"]

# Above this size the body is left to pandas.  Measured (benchmarks/bench_read.py): the fast path is
# faster than the pandas path at every size up to 10^6 rows (~40 MB), so this bound only caps the
# memory the fast path holds at once (the bytes, their text and numpy's parse buffers, about 3x the
# file); the pandas path holds one Python string per field, which is more.
FAST_MAX_BYTES = 64 * 2**20

_NUMBER_BYTES = b"0123456789+-.eEnNaAiIfFtTyY \t\r\n"
_SEPARATORS = {",": b",", ";": b";", "\t": b"\t", r"\s+": b""}
_BOM = b"\xef\xbb\xbf"


def _has_empty_field(text: str, sep: str) -> bool:
    return (sep + sep in text or text.startswith(sep) or text.endswith(sep) or "\n" + sep in text
            or sep + "\n" in text)


def _fill_empty(text: str, sep: str) -> str:
    """Empty fields written as ``nan``: missing values, as pandas (and senscal's writer) have them."""
    s = f"\n{text}\n"
    # One pass leaves no run of three separators, so a second fills what the first skipped.
    s = s.replace(sep + sep, f"{sep}nan{sep}").replace(sep + sep, f"{sep}nan{sep}")
    return s.replace("\n" + sep, f"\nnan{sep}").replace(sep + "\n", f"{sep}nan\n")[1:-1]


def read_plain_columns(path: Path, *, sep: str, width: int, skip: int) -> list[np.ndarray] | None:
    """The columns of a text file's body, or ``None`` when only pandas can read it with certainty.

    Parameters
    ----------
    path : Path
        A UTF-8 text recording of at most :data:`FAST_MAX_BYTES` bytes.
    sep : str
        ``","``, ``";"``, ``"\\t"`` or ``r"\\s+"`` (runs of blanks), as the
        reader chose it from the header.
    width : int
        Number of columns the header (or ``names``) gives; every body row
        must have exactly this many fields.
    skip : int
        Lines before the body (preamble and header), counted as the reader
        and pandas' ``skiprows`` count them.

    Returns
    -------
    list of numpy.ndarray or None
        ``width`` contiguous float64 columns (NaN for empty fields), equal bit
        for bit to what the pandas path gives; ``None`` for a body that is
        not plain numbers in ``width`` columns, or a file too large or
        unreadable here (the caller then reads it with pandas, which gives
        the error message when there is one).
    """
    delim = _SEPARATORS.get(sep)
    if delim is None or width < 1:
        return None
    try:
        if path.stat().st_size > FAST_MAX_BYTES:
            return None
        data = path.read_bytes()
    except OSError:
        return None
    if data.startswith(_BOM):
        data = data[len(_BOM):]
    start = 0
    for _ in range(skip):
        start = data.find(b"\n", start) + 1
        if start == 0:
            return None
    head, body = data[:start], data[start:]
    # A quote in the preamble can make pandas skip across line breaks; a lone CR ends a line for pandas
    # but not for the line count above.
    if b'"' in head or head.count(b"\r") != head.count(b"\r\n") or body.count(b"\r") != body.count(b"\r\n"):
        return None
    if body.translate(None, _NUMBER_BYTES + delim):
        return None
    text = body.decode("ascii")
    del data, head, body  # the peak memory is a few copies of the file: drop the ones no longer needed
    if "\r" in text:
        text = text.replace("\r\n", "\n")
    # Plain str searches first: the slower checks below run only on files that need them.
    blanks = " " in text or "\t" in text
    if blanks and any(map(str.isspace, text.split("\n"))):
        return None  # pandas skips some blank-only lines and reads others as a row of NaN
    text = text.strip("\n")
    if "\n\n" in text:
        text = "\n".join(filter(None, text.split("\n")))  # blank lines: pandas skips them
    if not text:
        return None
    pad = " \t".replace(sep, "")  # what may stand around a number in a field
    if delim and _has_empty_field(text.replace(" ", "").replace("\t", "") if pad == " \t" else text.replace(" ", ""),
                                  sep):
        d = re.escape(sep)
        if blanks and re.search(rf"(?m)(?:^|{d})[{pad}]+(?={d}|$)", text):
            return None  # blanks only: pandas reads ' ' as missing but '\t' as text
        text = _fill_empty(text, sep)
    try:
        arr = np.loadtxt(io.StringIO(text), dtype=np.float64, delimiter=sep if delim else None, comments=None,
                         quotechar=None, ndmin=2, encoding=None)
    except (ValueError, OverflowError):
        return None
    if arr.ndim != 2 or arr.shape[1] != width or arr.shape[0] == 0:
        return None
    nan = np.isnan(arr)
    if nan.any() and np.signbit(arr[nan]).any():
        return None  # '-nan' is in pandas' list of missing-value markers: a positive NaN there
    return [np.ascontiguousarray(arr[:, k]) for k in range(width)]
