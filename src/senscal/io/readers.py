"""Readers and writers: CSV, Parquet, HDF5, NI TDMS and NPZ into :class:`Recording`.

The same data in any of these formats gives the same :class:`Recording`.
Input files are only ever opened for reading.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from senscal.errors import DataError, FileFormatError, InputError, SenscalError
from senscal.io.guard import STDIO, atomic_output, check_output, is_stdio, note_input, stdin_bytes, write_text
from senscal.io._textfast import read_plain_columns
from senscal.io.recording import Recording

__all__ = ["read_recording", "write_recording", "FORMATS"]

FORMATS = {
    ".csv": "csv", ".txt": "csv", ".tsv": "csv", ".dat": "csv",
    ".parquet": "parquet", ".pq": "parquet",
    ".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5",
    ".tdms": "tdms",
    ".npz": "npz",
}


def _format_of(path: Path, fmt: str | None) -> str:
    if fmt:
        if fmt not in set(FORMATS.values()):
            raise InputError(f"unknown format '{fmt}'; use one of {', '.join(sorted(set(FORMATS.values())))}")
        return fmt
    try:
        return FORMATS[path.suffix.lower()]
    except KeyError:
        raise FileFormatError(
            f"cannot tell the format of {path} from its extension; use one of "
            f"{', '.join(sorted(FORMATS))} or pass format=..."
        ) from None


def read_recording(
    path: str | Path,
    *,
    time_column: str = "t",
    fs: float | None = None,
    channels: Sequence[str] | None = None,
    names: Sequence[str] | None = None,
    group: str | None = None,
    format: str | None = None,
    allow_nan: bool = False,
    skip_rows: int | None = None,
    time_required: bool = True,
    time_unit: str | None = None,
    start: float | None = None,
    stop: float | None = None,
    job: str | None = None,
) -> Recording:
    """Read a recording file into a :class:`Recording`.

    Parameters
    ----------
    path : str or Path
        CSV/TXT, Parquet, HDF5, TDMS or NPZ file; ``"-"`` reads CSV text
        from standard input (binary formats need a file).
    time_column : str
        Name of the time channel in seconds (default ``"t"``).  It is not
        returned as a data channel.
    fs : float, optional
        Sample rate in Hz for files without a time channel.  When given it
        takes precedence over any time channel.
    channels : sequence of str, optional
        Keep only these channels (unknown names raise, listing those that exist).
    names : sequence of str, optional
        Column names for a text file without a header row.
    group : str, optional
        HDF5 group or TDMS group holding the channels (default: the root /
        first group with channels).
    format : str, optional
        Force a format ("csv", "parquet", "hdf5", "tdms", "npz").
    allow_nan : bool
        Keep NaN samples as missing values instead of refusing them.
    skip_rows : int, optional
        Text files: lines before the header (or first data row) to skip.  By
        default a preamble of comment lines (``;``, ``#``, ``%``, ``//``) and
        ``key,value`` metadata lines is detected; an ``Fs``/``sample rate``
        entry in it gives the sample rate (Hz) of a file without time column.
    time_required : bool
        When false, a file with neither a time column nor a sample rate is
        read with sample index as its time base (``fs = 1``, marked in
        ``metadata["time_basis"]``) instead of refused; for jobs that never
        use time (e.g. a triaxial fit of readings).
    time_unit : str, optional
        Unit of a time column whose header gives none (``s``, ``ms``,
        ``us``, ``min``, ...); converted to seconds. A header that states
        another unit, or a file without time column, is refused.
    start, stop : float, optional
        Keep only the samples from ``start`` to ``stop`` seconds after the
        first sample (``--start``/``--stop``; see :meth:`Recording.window`).
    job : str, optional
        The job the recording is read for (``fit``, ``allan``, ``gfimu`` ...):
        selects the limits of the time-base checks
        (:func:`senscal.io.plausibility.time_base_warnings`), whose named
        warnings land in ``Recording.warnings``.

    The time base follows one rule for every job: a rate stated twice (a
    preamble's ``Fs``, ``--fs``, the time column's mean rate) must agree
    within 1 % or the file is refused (:func:`~senscal.io.plausibility.reconcile_rates`);
    a time column named ``time`` or ``Time(S)`` (an oscilloscope's) is the
    time column when no ``t`` exists; suspicions (a time column that looks
    like ms read as s) become ``time-unit-suspect`` warnings.

    Returns
    -------
    Recording

    Raises
    ------
    FileFormatError
        The file is missing, empty, corrupt, or not in a layout senscal
        reads (one line naming the file and what is wrong).
    """
    if is_stdio(path):
        return _read_stdin(time_column=time_column, fs=fs, channels=channels, names=names, group=group,
                           format=format, allow_nan=allow_nan, skip_rows=skip_rows, time_required=time_required,
                           time_unit=time_unit, start=start, stop=stop, job=job)
    path = Path(path)
    if fs is not None and not (isinstance(fs, (int, float, np.floating, np.integer)) and math.isfinite(float(fs))
                               and float(fs) > 0):
        raise InputError(f"--fs must be a positive, finite sample rate in Hz, got {fs!r}")
    if skip_rows is not None and (isinstance(skip_rows, bool) or int(skip_rows) != skip_rows or skip_rows < 0):
        raise InputError(f"--skip-rows must be a whole number >= 0, got {skip_rows!r}")
    if not path.exists():
        raise FileFormatError(f"file not found: {path}")
    if path.is_dir():
        raise FileFormatError(f"{path} is a folder; give a recording file")
    note_input(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise FileFormatError(f"cannot read {path}: {_reason(exc)}") from None
    if size == 0:
        raise FileFormatError(f"{path} is empty")
    kind = _format_of(path, format)
    if not os.access(path, os.R_OK):
        raise FileFormatError(f"cannot read {path}: permission denied")
    reader = {"csv": _read_csv, "parquet": _read_parquet, "hdf5": _read_hdf5, "tdms": _read_tdms, "npz": _read_npz}[kind]
    try:
        cols, units, meta, file_fs, file_t0 = reader(path, names=names, group=group, skip_rows=skip_rows)
        units, meta, file_fs, file_t0 = _check_file_info(path, units, meta, file_fs, file_t0)
    except SenscalError:
        raise
    except MemoryError:
        raise FileFormatError(f"{path} is too large to read into memory (or declares absurd sizes); "
                              "split the recording") from None
    except RecursionError:
        raise FileFormatError(f"{path} is not a readable {_LABEL[kind]} file (nested too deeply)") from None
    except Exception as exc:
        # Third-party parsers raise anything (OSError, KeyError, zipfile/zlib errors, TypeError ...) on a
        # damaged file; whatever it is, the file cannot be read, and the user needs its name, not a traceback.
        raise FileFormatError(f"{path} is not a readable {_LABEL[kind]} file ({_describe(exc)})") from None
    if not cols:
        raise FileFormatError(f"{path} holds no data columns")
    src = str(path)
    t = None
    use_fs = fs
    time_column, units = _recognise_time_column(cols, units, time_column)
    if time_unit is not None:
        _time_unit_agrees(time_unit, units.get(time_column) if time_column in cols else None, time_column, path,
                          has_time=time_column in cols and fs is None)
        if time_column in cols and not units.get(time_column):
            units = {**units, time_column: time_unit}
    stated_unit = units.get(time_column) if time_column in cols else None
    if stated_unit:
        cols[time_column] = _time_in_seconds(cols[time_column], stated_unit, time_column, path)
    # One time-base rule for every job: a rate stated twice must agree (plausibility.reconcile_rates).
    from senscal.io.plausibility import reconcile_rates, time_base_warnings

    reconcile_rates(cols.get(time_column), file_fs=file_fs, user_fs=fs, source=src, time_name=time_column,
                    file_fs_text=_rate_statement(meta, kind))
    if fs is None:
        if time_column in cols:
            t = cols[time_column]
        elif file_fs is not None:
            use_fs = file_fs
        elif not time_required:
            use_fs = 1.0
            meta = {**meta, "time_basis": "sample index: the file has no time column or sample rate"}
        else:
            raise FileFormatError(
                f"{path} has no time column '{time_column}' (columns: {', '.join(cols)}); "
                "name it with --time-column or give the sample rate with --fs"
            )
    warnings: tuple[str, ...] = ()
    if t is not None and t.size > 1 and np.all(np.isfinite(t)):
        factor = _TIME_UNITS.get(stated_unit.strip()) if stated_unit else 1.0
        warnings = time_base_warnings(t, job, unit=stated_unit if factor != 1.0 else None,
                                      declared=bool(stated_unit))
    cols.pop(time_column, None)
    if not cols:
        raise FileFormatError(f"{path} holds only the time column; it needs data channels")
    if channels is not None:
        missing = [c for c in channels if c not in cols]
        if missing:
            raise InputError(f"no channel '{missing[0]}' in {path}; channels are: {', '.join(cols)}")
        cols = {c: cols[c] for c in channels}
    rec = Recording(channels=cols, t=t, fs=use_fs, t0=file_t0 if t is None else 0.0,
                    units={k: v for k, v in units.items() if k in cols}, metadata=meta,
                    source=src, allow_nan=allow_nan, warnings=warnings)
    if (start is not None or stop is not None) and "time_basis" in meta:
        raise InputError(f"--start/--stop are seconds from the first sample, and {path} has no time base (no time "
                         f"column '{time_column}' or sample rate); give the sample rate with --fs")
    return rec.window(start, stop)


# A time column by another name: "time", "Time(S)" (an oscilloscope's export), "TIME (ms)".
_TIME_NAME = re.compile(r"\s*time\s*(?:\(\s*([^()]*?)\s*\))?\s*", re.I)


def _recognise_time_column(cols: dict[str, np.ndarray], units: dict[str, str],
                           time_column: str) -> tuple[str, dict[str, str]]:
    """The time column's name, and the units with its unit: ``Time(S)`` is time in seconds.

    Only when the default ``t`` is asked for and absent, and exactly one
    column is called ``time`` (any case), optionally with a time unit in
    parentheses (``Time(S)``, ``Time (ms)``) or in the header's brackets.
    """
    if time_column != "t" or "t" in cols:
        return time_column, units
    found = []
    for name in cols:
        m = _TIME_NAME.fullmatch(name)
        if not m:
            continue
        unit = m.group(1) if m.group(1) is not None else units.get(name)
        if unit is not None and unit.strip().lower() not in _TIME_UNITS and unit.strip() not in _TIME_UNITS:
            continue  # "Time(samples)": not a time in a unit senscal knows
        found.append((name, unit))
    if len(found) != 1:
        return time_column, units
    name, unit = found[0]
    if unit is not None:
        u = unit.strip()
        units = {**units, name: u if u in _TIME_UNITS else u.lower()}
    return name, units


def _rate_statement(meta: dict, kind: str) -> str:
    """How a file states its own sample rate, for a message: ``'Fs,50.00' in its preamble`` ..."""
    if kind == "csv":
        for key, value in meta.items():
            if isinstance(key, str) and _FS_KEY.match(key):
                return f"'{key},{value}' in its preamble"
        return "its preamble"
    return {"tdms": "its waveform increment", "hdf5": "its fs attribute"}.get(kind, "its fs entry")


_LABEL = {"csv": "CSV/text", "parquet": "Parquet", "hdf5": "HDF5", "tdms": "TDMS", "npz": "NPZ"}

# How the binary formats start: they cannot come through a pipe (their readers seek).
_MAGIC = ((b"PAR1", "parquet"), (b"\x89HDF\r\n\x1a\n", "hdf5"), (b"TDSm", "tdms"), (b"PK\x03\x04", "npz"))
STDIN_NAME = "standard input"


def _read_stdin(*, format: str | None, **options: Any) -> Recording:
    """A CSV recording piped into standard input (``-``), read whole, parsed like a file."""
    import tempfile

    if format not in (None, "csv"):
        raise InputError(f"only CSV text can be read from standard input ('-'), not {_LABEL.get(format, format)}; "
                         "give the file name")
    data = stdin_bytes("recording")
    for magic, kind in _MAGIC:
        if data.startswith(magic):
            raise FileFormatError(f"{STDIN_NAME} holds a {_LABEL[kind]} file; only CSV text can be piped in, "
                                  "give the file name instead")
    with tempfile.TemporaryDirectory(prefix="senscal-stdin-") as folder:
        tmp = Path(folder) / "stdin.csv"
        tmp.write_bytes(data)
        try:
            rec = read_recording(tmp, format="csv", **options)
        except SenscalError as exc:
            # The spool file is an implementation detail: messages name standard input.
            raise type(exc)(str(exc).replace(str(tmp), STDIN_NAME)) from None
    object.__setattr__(rec, "source", STDIN_NAME)
    return rec


def _reason(exc: OSError) -> str:
    return (exc.strerror or str(exc) or type(exc).__name__).rstrip(".").lower()


def _describe(exc: BaseException) -> str:
    """``TypeName: first line of the message``, at most 200 characters."""
    msg = str(exc).strip().splitlines()[0].strip() if str(exc).strip() else ""
    text = f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _check_file_info(path: Path, units: Any, meta: Any, fs: Any, t0: Any):
    """Validate what a file says about itself (units, metadata, fs, t0): types and finiteness."""
    if not isinstance(units, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in units.items()):
        raise FileFormatError(f"{path} has malformed units metadata (it must map channel names to unit strings); "
                              "rewrite the file with senscal or drop the metadata")
    if not isinstance(meta, dict):
        raise FileFormatError(f"{path} has malformed metadata (a {type(meta).__name__}, not a mapping); "
                              "rewrite the file with senscal or drop the metadata")
    if fs is not None:
        fs = _finite_scalar(fs, "sample rate (fs)", path)
        if fs <= 0:
            raise FileFormatError(f"{path} declares a sample rate of {fs:g} Hz; it must be positive")
    t0 = 0.0 if t0 is None else _finite_scalar(t0, "start time (t0)", path)
    return units, meta, fs, t0


def _finite_scalar(value: Any, what: str, path: Path) -> float:
    try:
        arr = np.asarray(value)
        if arr.size != 1 or arr.dtype.kind not in "fiub":
            raise TypeError
        out = float(arr.reshape(()))
    except (TypeError, ValueError, OverflowError):
        raise FileFormatError(f"{path} has a malformed {what}: {str(value)[:60]!r}; it must be one number") from None
    if not math.isfinite(out):
        raise FileFormatError(f"{path} declares a {what} of {out}; it must be finite")
    return out


def _add_column(cols: dict[str, np.ndarray], raw: dict[str, str], name: str, raw_name: str, values: np.ndarray,
                path: Path) -> None:
    """Add a column, refusing a name already taken (pandas and dict() would silently keep one of them)."""
    if name in cols:
        both = f"'{raw[name]}' and '{raw_name}'"
        read_as = f" (both read as '{name}')" if raw[name] != raw_name else ""
        raise FileFormatError(f"{path} has duplicate column names {both}{read_as}; make every column name unique")
    cols[name] = values
    raw[name] = raw_name


# Time units a header may carry ("t [ms]"); the Recording's time is always in seconds.
_TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6,
               "\u03bcs": 1e-6, "ns": 1e-9, "min": 60.0, "h": 3600.0, "d": 86400.0}


def _time_unit_agrees(unit: str, header: str | None, name: str, path: Path, *, has_time: bool) -> None:
    """Refuse a --time-unit that is unknown, has no time column to apply to, or contradicts the header."""
    if unit.strip() not in _TIME_UNITS:
        raise InputError(f"--time-unit {unit!r} is not a time unit senscal knows; use one of {', '.join(_TIME_UNITS)}")
    if not has_time:
        raise InputError(f"--time-unit applies to a time column, and {path} is read without one (column '{name}' "
                         "absent, or --fs given); drop --time-unit")
    if header and _TIME_UNITS.get(header.strip()) != _TIME_UNITS[unit.strip()]:
        raise InputError(f"--time-unit {unit} contradicts the header of {path}, which gives '{name}' in {header}; "
                         "drop --time-unit or fix the header")


def _time_in_seconds(t: np.ndarray, unit: str, name: str, path: Path) -> np.ndarray:
    factor = _TIME_UNITS.get(unit.strip())
    if factor is None:
        raise InputError(f"time column '{name}' of {path} is in {unit!r}, which senscal does not understand; "
                         f"use one of {', '.join(_TIME_UNITS)} or give the time in s")
    return t if factor == 1.0 else t * factor


# -- numeric conversion with a precise message -------------------------------

def _numeric(name: str, values: Any, path: Path) -> np.ndarray:
    """A 1-D float64 column, or a one-line DataError saying why the values are not numbers."""
    arr = np.asarray(values)
    kind = arr.dtype.kind
    if arr.ndim != 1:
        raise DataError(f"column '{name}' in {path} has shape {arr.shape}; data columns must be 1-D")
    if kind in "fiub":
        with np.errstate(over="ignore"):
            # float128 beyond float64's range becomes inf, which check_finite reports by sample.
            return arr.astype(np.float64)
    if kind == "c":
        raise DataError(f"column '{name}' in {path} holds complex numbers; store real and imaginary parts "
                        "as two real columns")
    if kind in "mM":
        raise DataError(f"column '{name}' in {path} holds dates/durations ({arr.dtype}); give time as seconds")
    if kind not in "OSU":
        raise DataError(f"column '{name}' in {path} has data type {arr.dtype}, which is not a number")
    try:
        out = np.asarray(values, dtype=np.float64)
        if out.ndim == 1:
            return out
    except (TypeError, ValueError, OverflowError):
        pass
    import pandas as pd

    ser = pd.Series(list(arr), dtype=object)
    num = pd.to_numeric(ser, errors="coerce")
    bad = num.isna() & ser.notna()
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        cell = str(ser.iloc[row])
        cell = cell if len(cell) <= 40 else cell[:37] + "..."
        hint = ("keep only numbers in data columns" if not _DECIMAL_COMMA.match(cell.strip()) else
                "it has a decimal comma: senscal reads decimal commas in files separated by ';' or tabs when "
                "every number of the column has one; export the CSV with '.' as decimal mark, or with ';' as "
                "separator")
        raise DataError(f"column '{name}' in {path} has a non-numeric value {cell!r} in data row {row + 1} "
                        f"(the {_ordinal(row + 1)} row below the header); {hint}")
    return num.to_numpy(dtype=np.float64)


# A preamble line naming the sample rate: "Fs,50.00", ";Sample rate,1e+06", "sampling frequency [Hz];200".
_FS_KEY = re.compile(r"^(fs|sample[ _-]?rate|sampling[ _-]?(rate|frequency)|sample[ _-]?frequency)"
                     r"\s*(\[\s*(hz|s/s|sps)\s*\]|\(\s*(hz|s/s|sps)\s*\))?$", re.I)
_COMMENT = (";", "#", "%", "//")
_SNIFF_LINES = 500


def _ordinal(n: int) -> str:
    return f"{n}{'th' if 10 <= n % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


def _is_number(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


# A number written with a decimal comma (Excel in many locales): "0,001", "-1,5e-3", ",5".
_DECIMAL_COMMA = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")


def _decimal_comma_row(fields: list[str]) -> bool:
    """True for fields that are numbers, some with a decimal comma (and no field that is neither)."""
    fields = [f.strip() for f in fields if f.strip()]
    return (any(_DECIMAL_COMMA.match(f) for f in fields)
            and all(_is_number(f) or _DECIMAL_COMMA.match(f) for f in fields))


def _sep_of(line: str) -> str:
    if "," in line:
        # "0,001;1,25": ';' (or tab) separates and the commas are decimal marks.
        for sep in (";", "\t"):
            if sep in line and _decimal_comma_row(line.rstrip("\r\n").split(sep)):
                return sep
        return ","
    if ";" in line:
        return ";"
    if "\t" in line:
        return "\t"
    return r"\s+"


def _data_like(fields: list[str]) -> bool:
    """True for a row of numbers, some of which may be empty (missing values) or have a decimal comma."""
    return any(fields) and all(_is_number(f) or _DECIMAL_COMMA.match(f) for f in fields if f)


def _fields(line: str, sep: str) -> list[str]:
    parts = line.split() if sep == r"\s+" else line.rstrip("\r\n").split(sep)
    return [f.strip() for f in parts]


def _read_csv(path: Path, *, names=None, group=None, skip_rows=None):
    head: list[str] = []
    try:
        with open(path, "r", encoding="utf-8-sig", newline="") as fh:
            for i, line in enumerate(fh):
                if i >= _SNIFF_LINES + (skip_rows or 0):
                    break
                head.append(line)
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{path} is not UTF-8 text (bad byte at offset {exc.start}); "
                              "save it as UTF-8 CSV") from None
    if any("\x00" in line for line in head):
        raise FileFormatError(f"{path} holds NUL bytes: it is a binary file, not CSV text; "
                              "check the file or give its format")
    # Split the start of the file into preamble (comments, key,value metadata), header and data.
    start = int(skip_rows or 0)
    if start >= len(head) and skip_rows:
        raise FileFormatError(f"{path} has no lines after --skip-rows {skip_rows}")
    content = [i for i in range(start, len(head)) if head[i].strip()
               and (skip_rows is not None or not head[i].lstrip().startswith(_COMMENT))]
    if skip_rows is None:
        content = [i for i in content if not head[i].lstrip().startswith(_COMMENT)]
    if not content:
        raise FileFormatError(f"{path} is empty (no data rows)")
    # A data row may have empty fields (NaN, as pandas and senscal write them), never a name.
    first_data = next((i for i in content if _data_like(_fields(head[i], _sep_of(head[i])))), None)
    header_i: int | None
    if first_data is None:
        header_i = content[0]  # no numeric row near the top: the first line is the header
    else:
        before = [i for i in content if i < first_data]
        header_i = None
        if before:
            cand = before[-1]
            sep_d = _sep_of(head[first_data])
            if len(_fields(head[cand], sep_d)) == len(_fields(head[first_data], sep_d)):
                header_i = cand
            elif skip_rows is None or cand != content[0] or len(before) > 1:
                header_i = None
            else:
                header_i = cand  # --skip-rows put us on the header: its width is checked below
    data_i = first_data if first_data is not None else (header_i + 1 if header_i is not None else content[0])
    preamble = [head[i] for i in range(0, header_i if header_i is not None else data_i) if head[i].strip()]
    meta, file_fs = _preamble_metadata(preamble, path)
    ref_line = head[data_i] if data_i < len(head) else head[header_i]  # type: ignore[index]
    sep = _sep_of(ref_line if header_i is None else head[header_i])
    if names is not None:
        fields = list(names)
    elif header_i is None:
        n = len(_fields(ref_line, sep))
        names_line = [i for i in content if first_data is not None and i < first_data][-1:]
        if sep == "," and names_line and len(_fields(head[names_line[0]], ",")) < n:
            # "t,x" over "0,5,1,25": decimal commas in a comma-separated file cannot be told from separators.
            raise FileFormatError(f"{path}: the header has {len(_fields(head[names_line[0]], ','))} columns but the "
                                  f"data rows have {n}; if the numbers use decimal commas ('0,5'), they cannot be "
                                  "told from the separators: export the CSV with ';' as separator (senscal reads its "
                                  "decimal commas) or with '.' as decimal mark")
        raise FileFormatError(f"{path} has no header row ({n} columns); give column names, e.g. "
                              f"{_names_hint(head[data_i:], sep, n, file_fs)}")
    else:
        fields = _fields(head[header_i], sep)
    if names is not None and header_i is not None:
        width = len(_fields(head[header_i], sep))
        if width != len(fields):
            raise InputError(f"{path} has {width} columns but {len(fields)} names were given")
    if any(not f for f in fields):
        k = [i for i, f in enumerate(fields) if not f][0]
        raise FileFormatError(f"{path}: column {k + 1} of the header has no name; name every column")
    body_start = (header_i + 1) if header_i is not None else data_i
    if names is not None and header_i is None:
        width = len(_fields(ref_line, sep))
        if width != len(fields):
            raise InputError(f"{path} has {width} columns but {len(fields)} names were given")
    # Split "name [unit]" and refuse duplicates before pandas renames them ("ch1", "ch1.1").
    cols_meta: list[tuple[str, str, str | None]] = []
    seen_raw: set[str] = set()
    for f in fields:
        if f in seen_raw:
            raise FileFormatError(f"{path} has the column name '{f}' twice; make every column name unique")
        seen_raw.add(f)
        if f.endswith("]") and "[" in f:
            nm, unit = f[:-1].split("[", 1)
            cols_meta.append((f, nm.strip(), unit.strip()))
        else:
            cols_meta.append((f, f, None))
    # Plain numbers (nearly every recording) are read without importing pandas; anything else goes to pandas.
    body = read_plain_columns(path, sep=sep, width=len(fields), skip=body_start)
    if body is None:
        body = _read_body_pandas(path, sep=sep, width=len(fields), skip=body_start)
    _check_not_truncated(path, sep, len(fields))
    if sep != ",":
        body = [_decimal_points(col, nm, path) for col, (_, nm, _) in zip(body, cols_meta)]
    units: dict[str, str] = {}
    cols: dict[str, np.ndarray] = {}
    raw: dict[str, str] = {}
    for k, (f, nm, unit) in enumerate(cols_meta):
        _add_column(cols, raw, nm, f, _numeric(nm, body[k], path), path)
        if unit is not None:
            units[nm] = unit
    return cols, units, meta, file_fs, 0.0


def _decimal_points(col: np.ndarray, name: str, path: Path) -> np.ndarray:
    """A text column whose numbers use a decimal comma ("1,25"), with decimal points; others unchanged.

    Only a file separated by ';', tabs or blanks gets here: there a comma can only be a decimal mark.  A
    column that mixes commas with points is refused naming the first point (``1.234`` beside ``0,5`` may
    be a thousands separator: never guessed).
    """
    if col.dtype.kind != "O":
        return col
    text = [v.strip() if isinstance(v, str) else "" for v in col]
    commas = [i for i, v in enumerate(text) if _DECIMAL_COMMA.match(v)]
    if not commas:
        return col
    dots = [i for i, v in enumerate(text) if "." in v]
    if dots:
        raise DataError(f"column '{name}' in {path} mixes decimal commas ({text[commas[0]]!r} in data row "
                        f"{commas[0] + 1}) with decimal points ({text[dots[0]]!r} in data row {dots[0] + 1}); "
                        "export the CSV again with one decimal mark")
    return np.array([v.replace(",", ".") if isinstance(v, str) else v for v in col], dtype=object)


def _names_hint(rows: list[str], sep: str, n: int, file_fs: float | None) -> str:
    """``--names ...`` for a headerless file: a first column that strictly increases is time, else all data.

    Three columns of readings (x, y, z) are not told ``t,x,y``: without a time
    column they need a sample rate (``--fs``) unless the job ignores time.
    """
    first = []
    for line in rows[:200]:
        f = _fields(line, sep)
        if len(f) != n or not f[0] or not _is_number(f[0]):
            continue
        first.append(float(f[0]))
    increasing = n >= 2 and len(first) >= 3 and all(b > a for a, b in zip(first, first[1:]))
    data = {2: ["x", "y"], 3: ["x", "y", "z"]}.get(n - 1 if increasing else n) or \
        [f"c{k}" for k in range(1, (n - 1 if increasing else n) + 1)]
    if increasing:
        return f"--names {','.join(['t', *data])} (the first column increases like time stamps in s)"
    rate = "" if file_fs is not None else " (no column increases like time: give --fs HZ where the job needs a time base)"
    return f"--names {','.join(data)}{rate}"


def _read_body_pandas(path: Path, *, sep: str, width: int, skip: int) -> list[np.ndarray]:
    """The body's ``width`` columns as text (object arrays, NaN for empty fields), read by pandas.

    Every field stays text so that :func:`_numeric` converts it with Python's
    ``float()`` (correctly rounded, like the fast path) and names the first
    cell that is not a number.
    """
    import pandas as pd

    try:
        df = pd.read_csv(path, sep=sep, comment="#", skipinitialspace=True, header=None,
                         names=list(range(width)), skiprows=skip, skip_blank_lines=True,
                         index_col=False, dtype=object, encoding="utf-8-sig",
                         engine="python" if sep == r"\s+" else "c", on_bad_lines="error")
    except pd.errors.EmptyDataError:
        raise FileFormatError(f"{path} has a header but no data rows") from None
    except pd.errors.ParserError as exc:
        raise FileFormatError(f"{path} is not a readable CSV: {_describe(exc).split(': ', 1)[-1]}; every row "
                              f"needs the header's {width} columns") from None
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{path} is not UTF-8 text (bad byte at offset {exc.start}); "
                              "save it as UTF-8 CSV") from None
    if len(df) == 0:
        raise FileFormatError(f"{path} has a header but no data rows")
    return [df[k].to_numpy() for k in range(width)]


def _check_not_truncated(path: Path, sep: str, width: int, tail_bytes: int = 65536) -> None:
    """Refuse a CSV whose last line was cut off (an interrupted copy or export).

    A cut-off last line parses as a valid, shorter recording whose last value
    is wrong (``0.12`` of ``0.1234``) or missing.  Only a file that does not
    end with a line break is suspect; it is refused when its last line has
    fewer fields than the header, or when a field of the last line is shorter
    than that field is on every one of the (up to 50) lines before it.
    """
    try:
        with open(path, "rb") as fh:
            fh.seek(0, 2)
            size = fh.tell()
            fh.seek(max(0, size - tail_bytes))
            tail = fh.read()
    except OSError:
        return
    if not tail or tail.endswith((b"\n", b"\r")):
        return
    lines = [ln.rstrip(b"\r") for ln in tail.split(b"\n")]
    last = lines[-1].decode("utf-8", "replace")
    if not last.strip() or last.lstrip().startswith(_COMMENT):
        return
    # lines[0] may start mid-line when the tail was cut from a longer file.
    prev = [ln.decode("utf-8", "replace") for ln in lines[1:-1] if ln.strip()][-50:]
    prev = [ln for ln in prev if not ln.lstrip().startswith(_COMMENT) and len(_fields(ln, sep)) == width]
    last_fields = _fields(last, sep)
    short = len(last_fields) < width
    if not short and len(prev) >= 3:
        prev_fields = [_fields(ln, sep) for ln in prev]
        short = any(len(last_fields[k]) < min(len(pf[k]) for pf in prev_fields) for k in range(width))
    if short:
        raise DataError(f"{path}: the last line ({last.strip()[:60]!r}) is shorter than the lines before it and the "
                        "file does not end with a line break, so it looks truncated (a cut-off number would be read "
                        "as a wrong value); copy or export the file again, delete the last line, or, if it is "
                        "complete, end it with a line break")


def _preamble_metadata(lines: list[str], path: Path) -> tuple[dict[str, str], float | None]:
    """``key,value`` pairs of a CSV preamble (comment marks stripped) and the sample rate it names."""
    meta: dict[str, str] = {}
    fs = None
    for line in lines:
        text = line.strip()
        for mark in _COMMENT:
            if text.startswith(mark):
                text = text[len(mark):].strip()
                break
        if not text:
            continue
        sep = _sep_of(text) if any(c in text for c in ",;\t") else None
        if sep is None:
            key, value = (text.split(":", 1) + [""])[:2] if ":" in text else (text, "")
        else:
            key, *rest = [f.strip() for f in text.split(sep)]
            value = sep.join(r for r in rest if r)
        key, value = key.strip(), value.strip()
        if key:
            meta[key] = value
            if _FS_KEY.match(key) and _is_number(value):
                v = float(value)
                if not (math.isfinite(v) and v > 0):
                    raise FileFormatError(f"{path} states a sample rate of {value!r} in '{key}'; it must be a "
                                          "positive number of Hz (fix the line or skip it with --skip-rows)")
                fs = v
    return meta, fs


def _read_parquet(path: Path, *, names=None, group=None, skip_rows=None):
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises many types for corrupt files
        raise FileFormatError(f"{path} is not a readable Parquet file ({_describe(exc)})") from None
    meta_raw = (table.schema.metadata or {}).get(b"senscal")
    meta: Any = {}
    if meta_raw:
        meta = _embedded_json(meta_raw, path, "senscal metadata", "its metadata")
    cols: dict[str, np.ndarray] = {}
    raw: dict[str, str] = {}
    for i, name in enumerate(table.column_names):
        _add_column(cols, raw, name, name, _numeric(name, table.column(i).to_numpy(zero_copy_only=False), path), path)
    return cols, meta.get("units", {}), meta.get("metadata", {}), meta.get("fs"), meta.get("t0", 0.0)


def _read_hdf5(path: Path, *, names=None, group=None, skip_rows=None):
    import h5py

    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise FileFormatError(f"{path} is not a readable HDF5 file ({_describe(exc)})") from None
    with fh:
        grp = fh
        if group is not None:
            if group not in fh:
                raise FileFormatError(f"no group '{group}' in {path}; groups: {', '.join(k for k in fh if isinstance(fh[k], h5py.Group)) or 'none'}")
            grp = fh[group]
            if not isinstance(grp, h5py.Group):
                raise FileFormatError(f"'{group}' in {path} is a dataset, not a group; give the group holding "
                                      "the channels")
        cols: dict[str, np.ndarray] = {}
        raw: dict[str, str] = {}
        units: dict[str, str] = {}
        for key, obj in grp.items():
            if isinstance(obj, h5py.Dataset) and obj.ndim == 1:
                if obj.dtype.kind == "V" or obj.dtype.names:
                    raise DataError(f"dataset '{key}' in {path} is a compound/opaque type ({obj.dtype}); "
                                    "store each channel as a 1-D numeric dataset")
                _add_column(cols, raw, key, key, _numeric(key, obj[()], path), path)
                u = obj.attrs.get("unit", obj.attrs.get("units"))
                if u is not None:
                    units[key] = _attr_text(u, f"unit of '{key}'", path)
        fs = grp.attrs.get("fs")
        t0 = grp.attrs.get("t0", 0.0)
        meta_raw = grp.attrs.get("metadata")
        meta: Any = {}
        if meta_raw is not None:
            meta = _embedded_json(_attr_text(meta_raw, "metadata attribute", path), path, "a metadata attribute",
                                  "the attribute", mapping=False)
    return cols, units, meta, fs, t0


def _embedded_json(text: str | bytes, path: Path, what: str, drop: str, *, mapping: bool = True) -> Any:
    """Parse the JSON a file carries about itself (Parquet metadata, HDF5 attribute, NPZ entry).

    ``what`` names where it sits and ``drop`` what the user may remove, for the
    one-line error; with ``mapping`` the document must be a JSON object.
    """
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError):
        raise FileFormatError(f"{path} has {what} that is not valid JSON; rewrite the file with senscal or "
                              f"drop {drop}") from None
    if mapping and not isinstance(doc, dict):
        raise FileFormatError(f"{path} has {what} that is a {type(doc).__name__}, not a mapping; rewrite the file "
                              f"with senscal or drop {drop}")
    return doc


def _attr_text(value: Any, what: str, path: Path) -> str:
    if isinstance(value, bytes):
        try:
            return value.decode("utf-8")
        except UnicodeDecodeError:
            raise FileFormatError(f"{path} has a {what} that is not UTF-8 text") from None
    if isinstance(value, str):
        return value
    arr = np.asarray(value)
    if arr.ndim == 0 and arr.dtype.kind in "OSU":
        return _attr_text(arr.item(), what, path)
    raise FileFormatError(f"{path} has a {what} that is not text ({type(value).__name__}); "
                          "rewrite the file with senscal or drop the attribute")


def _read_tdms(path: Path, *, names=None, group=None, skip_rows=None):
    from nptdms import TdmsFile

    try:
        tdms = TdmsFile.read(path)
    except Exception as exc:
        raise FileFormatError(f"{path} is not a readable TDMS file ({_describe(exc)})") from None
    groups = tdms.groups()
    if group is not None:
        try:
            grp = tdms[group]
        except KeyError:
            raise FileFormatError(f"no group '{group}' in {path}; groups: {', '.join(g.name for g in groups)}") from None
    else:
        with_data = [g for g in groups if g.channels()]
        if not with_data:
            raise FileFormatError(f"{path} has no channels")
        grp = with_data[0]
    cols: dict[str, np.ndarray] = {}
    raw: dict[str, str] = {}
    units: dict[str, str] = {}
    fs = None
    t0: Any = 0.0
    for ch in grp.channels():
        _add_column(cols, raw, ch.name, ch.name, _numeric(ch.name, ch[:], path), path)
        u = ch.properties.get("unit_string")
        if u:
            units[ch.name] = str(u)
        inc = ch.properties.get("wf_increment")
        if inc and fs is None:
            inc = _finite_scalar(inc, f"wf_increment of channel '{ch.name}'", path)
            if inc <= 0:
                raise FileFormatError(f"{path}: channel '{ch.name}' has a sample interval (wf_increment) of "
                                      f"{inc:g} s; it must be positive")
            fs = 1.0 / inc
            off = ch.properties.get("wf_start_offset")
            t0 = off if off is not None else 0.0
    meta = {k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in tdms.properties.items()}
    return cols, units, meta, fs, t0


def _read_npz(path: Path, *, names=None, group=None, skip_rows=None):
    try:
        npz = np.load(path, allow_pickle=False)
    except Exception as exc:
        raise FileFormatError(f"{path} is not a readable NPZ file ({_describe(exc)})") from None
    if not hasattr(npz, "files"):
        # np.load also reads a bare .npy array (or a pickle it then refuses).
        raise FileFormatError(f"{path} is a single array, not an NPZ archive of named channels; "
                              "save it with numpy.savez(path, t=..., x=...)")
    with npz:
        cols: dict[str, np.ndarray] = {}
        raw: dict[str, str] = {}
        fs = None
        t0: Any = 0.0
        units: Any = {}
        meta: Any = {}
        if len(set(npz.files)) != len(npz.files):
            dup = next(k for k in npz.files if npz.files.count(k) > 1)
            raise FileFormatError(f"{path} holds the array '{dup}' twice; make every channel name unique")
        for key in npz.files:
            try:
                arr = npz[key]
            except ValueError as exc:
                if "allow_pickle" in str(exc):
                    raise FileFormatError(f"array '{key}' in {path} holds Python objects (a pickle), which senscal "
                                          "never loads; save plain numeric arrays") from None
                raise
            if key == "fs" and arr.ndim == 0:
                fs = arr
            elif key == "t0" and arr.ndim == 0:
                t0 = arr
            elif key == "__senscal__":
                info = _embedded_json(_attr_text(arr, "'__senscal__' entry", path), path, "a '__senscal__' entry",
                                      "the entry")
                units = info.get("units", {})
                meta = info.get("metadata", {})
            elif arr.ndim == 1:
                _add_column(cols, raw, key, key, _numeric(key, arr, path), path)
    return cols, units, meta, fs, t0


# -- writers -----------------------------------------------------------------

def write_recording(rec: Recording, path: str | Path, *, format: str | None = None, time_column: str = "t",
                    units_in_header: bool = False) -> Path:
    """Write a recording to CSV, Parquet, HDF5, TDMS or NPZ.

    CSV always gets an explicit time column; the binary formats keep ``fs``
    (and ``t0``) for uniform recordings made from a sample rate, and units.
    With ``units_in_header`` CSV headers read ``name [unit]`` (the reader
    parses that back); by default they are the bare channel names, which
    output-file contracts rely on.

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    if time_column in rec.channels:
        raise InputError(f"a data channel is called '{time_column}'; rename it or choose another time_column")
    if is_stdio(path):
        return _write_stdout(rec, format=format, time_column=time_column, units_in_header=units_in_header)
    kind = _format_of(path, format)
    check_output(path)
    info = {"units": dict(rec.units), "metadata": {k: v for k, v in rec.metadata.items() if isinstance(v, (str, int, float, bool))}}
    # Written to a temporary file and renamed: a full disk or a crash never leaves half a recording.
    with atomic_output(path, what="recording") as tmp:
        if kind == "csv":
            _csv_frame(rec, time_column, units_in_header).to_csv(tmp, index=False, float_format="%.17g")
        elif kind == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            data = {n: rec.channels[n] for n in rec.names}
            if rec.t is not None:
                data = {time_column: rec.t, **data}
            else:
                info.update(fs=rec.fs, t0=rec.t0)
            table = pa.table(data).replace_schema_metadata({b"senscal": json.dumps(info).encode()})
            pq.write_table(table, tmp)
        elif kind == "hdf5":
            import h5py

            with h5py.File(tmp, "w") as fh:
                if rec.t is not None:
                    fh.create_dataset(time_column, data=rec.t)
                else:
                    fh.attrs["fs"] = rec.fs
                    fh.attrs["t0"] = rec.t0
                for n in rec.names:
                    ds = fh.create_dataset(n, data=rec.channels[n])
                    if n in rec.units:
                        ds.attrs["unit"] = rec.units[n]
                fh.attrs["metadata"] = json.dumps(info["metadata"])
        elif kind == "tdms":
            from nptdms import ChannelObject, TdmsWriter

            objs = []
            for n in rec.names:
                props: dict[str, Any] = {}
                if n in rec.units:
                    props["unit_string"] = rec.units[n]
                if rec.t is None:
                    props["wf_increment"] = 1.0 / rec.fs
                    props["wf_start_offset"] = rec.t0
                objs.append(ChannelObject("data", n, np.asarray(rec.channels[n]), properties=props))
            if rec.t is not None:
                objs.insert(0, ChannelObject("data", time_column, np.asarray(rec.t)))
            with TdmsWriter(tmp) as writer:
                writer.write_segment(objs)
        elif kind == "npz":
            arrays: dict[str, Any] = {n: rec.channels[n] for n in rec.names}
            if rec.t is not None:
                arrays[time_column] = rec.t
            else:
                arrays["fs"] = np.float64(rec.fs)
                arrays["t0"] = np.float64(rec.t0)
            arrays["__senscal__"] = np.array(json.dumps(info))
            np.savez(tmp, **arrays)
    return path


def _csv_frame(rec: Recording, time_column: str, units_in_header: bool):
    import pandas as pd

    # Units ride in the header as "name [unit]", which the reader parses back.
    return pd.DataFrame({time_column: rec.time,
                         **{(f"{n} [{rec.units[n]}]" if units_in_header and rec.units.get(n) else n): rec.channels[n]
                            for n in rec.names}})


def _write_stdout(rec: Recording, *, format: str | None, time_column: str, units_in_header: bool) -> Path:
    """``write_recording(rec, "-")``: CSV text on standard output (a pipe takes no binary format)."""
    if format not in (None, "csv"):
        raise InputError(f"only CSV can be written to standard output ('-'), not {_LABEL.get(format, format)}; "
                         "give a file name")
    text = _csv_frame(rec, time_column, units_in_header).to_csv(index=False, float_format="%.17g")
    return write_text(STDIO, text, what="the recording")
