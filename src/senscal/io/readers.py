"""Readers and writers: CSV, Parquet, HDF5, NI TDMS and NPZ into :class:`Recording`.

The same data in any of these formats gives the same :class:`Recording`.
Input files are only ever opened for reading.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from senscal.errors import DataError, FileFormatError, InputError
from senscal.io.guard import check_output, note_input
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
) -> Recording:
    """Read a recording file into a :class:`Recording`.

    Parameters
    ----------
    path : str or Path
        CSV/TXT, Parquet, HDF5, TDMS or NPZ file.
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

    Returns
    -------
    Recording
    """
    path = Path(path)
    if not path.exists():
        raise FileFormatError(f"file not found: {path}")
    if path.is_dir():
        raise FileFormatError(f"{path} is a folder; give a recording file")
    note_input(path)
    if path.stat().st_size == 0:
        raise FileFormatError(f"{path} is empty")
    kind = _format_of(path, format)
    reader = {"csv": _read_csv, "parquet": _read_parquet, "hdf5": _read_hdf5, "tdms": _read_tdms, "npz": _read_npz}[kind]
    cols, units, meta, file_fs, file_t0 = reader(path, names=names, group=group)
    if not cols:
        raise FileFormatError(f"{path} holds no data columns")
    src = str(path)
    t = None
    use_fs = fs
    if time_column in cols and units.get(time_column):
        cols[time_column] = _time_in_seconds(cols[time_column], units[time_column], time_column, path)
    if fs is None:
        if time_column in cols:
            t = cols[time_column]
        elif file_fs is not None:
            use_fs = file_fs
        else:
            raise FileFormatError(
                f"{path} has no time column '{time_column}' (columns: {', '.join(cols)}); "
                "name it with --time-column or give the sample rate with --fs"
            )
    elif time_column in cols and cols[time_column].size > 1:
        # Both a time column and --fs: silently preferring one would shift every frequency.
        tc = cols[time_column]
        span = float(tc[-1] - tc[0])
        rate = (tc.size - 1) / span if span > 0 else float("nan")
        if not (np.isfinite(rate) and abs(rate / fs - 1.0) < 0.01):
            raise InputError(f"--fs {fs:g} Hz contradicts the time column '{time_column}' of {path} "
                             f"(about {rate:.6g} samples/s); --fs is for files without a time column")
    cols.pop(time_column, None)
    if not cols:
        raise FileFormatError(f"{path} holds only the time column; it needs data channels")
    if channels is not None:
        missing = [c for c in channels if c not in cols]
        if missing:
            raise InputError(f"no channel '{missing[0]}' in {path}; channels are: {', '.join(cols)}")
        cols = {c: cols[c] for c in channels}
    return Recording(channels=cols, t=t, fs=use_fs, t0=file_t0 if t is None else 0.0,
                     units={k: v for k, v in units.items() if k in cols}, metadata=meta,
                     source=src, allow_nan=allow_nan)


# Time units a header may carry ("t [ms]"); the Recording's time is always in seconds.
_TIME_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "seconds": 1.0, "ms": 1e-3, "us": 1e-6, "\u00b5s": 1e-6,
               "\u03bcs": 1e-6, "ns": 1e-9, "min": 60.0, "h": 3600.0, "d": 86400.0}


def _time_in_seconds(t: np.ndarray, unit: str, name: str, path: Path) -> np.ndarray:
    factor = _TIME_UNITS.get(unit.strip())
    if factor is None:
        raise InputError(f"time column '{name}' of {path} is in {unit!r}, which senscal does not understand; "
                         f"use one of {', '.join(_TIME_UNITS)} or give the time in s")
    return t if factor == 1.0 else t * factor


# -- numeric conversion with a precise message -------------------------------

def _numeric(name: str, values: Any, path: Path) -> np.ndarray:
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        pass
    import pandas as pd

    ser = pd.Series(values)
    num = pd.to_numeric(ser, errors="coerce")
    bad = num.isna() & ser.notna()
    if bad.any():
        row = int(np.flatnonzero(bad.to_numpy())[0])
        raise DataError(
            f"column '{name}' in {path} has a non-numeric value {str(ser.iloc[row])!r} at data row {row}; "
            "keep only numbers in data columns"
        )
    return num.to_numpy(dtype=np.float64)


def _read_csv(path: Path, *, names=None, group=None):
    import pandas as pd

    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        first = ""
        for line in fh:
            if line.strip() and not line.lstrip().startswith("#"):
                first = line
                break
    if not first:
        raise FileFormatError(f"{path} is empty (no data rows)")
    if "," in first:
        sep = ","
    elif ";" in first:
        sep = ";"
    elif "\t" in first:
        sep = "\t"
    else:
        sep = r"\s+"
    fields = [f for f in (first.split() if sep == r"\s+" else first.split(sep)) if f.strip()]

    def _is_number(s: str) -> bool:
        try:
            float(s)
            return True
        except ValueError:
            return False

    header_is_numeric = all(_is_number(f) for f in fields)
    if names is not None:
        if len(names) != len(fields):
            raise InputError(f"{path} has {len(fields)} columns but {len(names)} names were given")
        header = None if header_is_numeric else 0
        kw: dict[str, Any] = dict(names=list(names), header=header)
    else:
        if header_is_numeric:
            raise FileFormatError(
                f"{path} has no header row; give column names, e.g. names=['t','x','y','z'] "
                "(--names t,x,y,z on the command line)"
            )
        kw = dict(header=0)
    try:
        df = pd.read_csv(path, sep=sep, comment="#", skipinitialspace=True,
                         engine="python" if sep == r"\s+" else "c", **kw)
    except pd.errors.EmptyDataError:
        raise FileFormatError(f"{path} is empty (no data rows)") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise FileFormatError(f"{path} is not a readable CSV: {msg}") from None
    if len(df) == 0:
        raise FileFormatError(f"{path} has a header but no data rows")
    df.columns = [str(c).strip() for c in df.columns]
    if len(set(df.columns)) != len(df.columns):
        raise FileFormatError(f"{path} has duplicate column names; make every column name unique")
    units: dict[str, str] = {}
    cols: dict[str, np.ndarray] = {}
    for c in df.columns:
        name = c
        # "accel [m/s^2]" headers carry units.
        if c.endswith("]") and "[" in c:
            name, unit = c[:-1].split("[", 1)
            name = name.strip()
            units[name] = unit.strip()
        cols[name] = _numeric(name, df[c].to_numpy(), path)
    return cols, units, {}, None, 0.0


def _read_parquet(path: Path, *, names=None, group=None):
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except Exception as exc:  # pyarrow raises many types for corrupt files
        raise FileFormatError(f"{path} is not a readable Parquet file: {str(exc).splitlines()[0]}") from None
    meta_raw = (table.schema.metadata or {}).get(b"senscal")
    meta = json.loads(meta_raw) if meta_raw else {}
    cols = {name: _numeric(name, table.column(name).to_numpy(zero_copy_only=False), path) for name in table.column_names}
    return cols, dict(meta.get("units", {})), dict(meta.get("metadata", {})), meta.get("fs"), float(meta.get("t0", 0.0))


def _read_hdf5(path: Path, *, names=None, group=None):
    import h5py

    try:
        fh = h5py.File(path, "r")
    except OSError as exc:
        raise FileFormatError(f"{path} is not a readable HDF5 file: {exc}") from None
    with fh:
        grp = fh
        if group is not None:
            if group not in fh:
                raise FileFormatError(f"no group '{group}' in {path}; groups: {', '.join(k for k in fh if isinstance(fh[k], h5py.Group)) or 'none'}")
            grp = fh[group]
        cols: dict[str, np.ndarray] = {}
        units: dict[str, str] = {}
        for key, obj in grp.items():
            if isinstance(obj, h5py.Dataset) and obj.ndim == 1:
                cols[key] = _numeric(key, obj[()], path)
                u = obj.attrs.get("unit", obj.attrs.get("units"))
                if u is not None:
                    units[key] = u.decode() if isinstance(u, bytes) else str(u)
        fs = grp.attrs.get("fs")
        t0 = float(grp.attrs.get("t0", 0.0))
        meta_raw = grp.attrs.get("metadata")
        meta = json.loads(meta_raw) if meta_raw is not None else {}
    return cols, units, meta, float(fs) if fs is not None else None, t0


def _read_tdms(path: Path, *, names=None, group=None):
    from nptdms import TdmsFile

    try:
        tdms = TdmsFile.read(path)
    except Exception as exc:
        raise FileFormatError(f"{path} is not a readable TDMS file: {str(exc).splitlines()[0]}") from None
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
    units: dict[str, str] = {}
    fs = None
    t0 = 0.0
    for ch in grp.channels():
        cols[ch.name] = _numeric(ch.name, ch[:], path)
        u = ch.properties.get("unit_string")
        if u:
            units[ch.name] = str(u)
        inc = ch.properties.get("wf_increment")
        if inc and fs is None:
            fs = 1.0 / float(inc)
            off = ch.properties.get("wf_start_offset")
            t0 = float(off) if off is not None else 0.0
    meta = {k: (v if isinstance(v, (int, float, str)) else str(v)) for k, v in tdms.properties.items()}
    return cols, units, meta, fs, t0


def _read_npz(path: Path, *, names=None, group=None):
    try:
        npz = np.load(path, allow_pickle=False)
    except Exception as exc:
        raise FileFormatError(f"{path} is not a readable NPZ file: {str(exc).splitlines()[0]}") from None
    with npz:
        cols: dict[str, np.ndarray] = {}
        fs = None
        t0 = 0.0
        units: dict[str, str] = {}
        meta: dict[str, Any] = {}
        for key in npz.files:
            arr = npz[key]
            if key == "fs" and arr.ndim == 0:
                fs = float(arr)
            elif key == "t0" and arr.ndim == 0:
                t0 = float(arr)
            elif key == "__senscal__":
                info = json.loads(str(arr))
                units = info.get("units", {})
                meta = info.get("metadata", {})
            elif arr.ndim == 1:
                cols[key] = _numeric(key, arr, path)
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
    kind = _format_of(path, format)
    check_output(path)
    if time_column in rec.channels:
        raise InputError(f"a data channel is called '{time_column}'; rename it or choose another time_column")
    info = {"units": dict(rec.units), "metadata": {k: v for k, v in rec.metadata.items() if isinstance(v, (str, int, float, bool))}}
    if kind == "csv":
        import pandas as pd

        # Units ride in the header as "name [unit]", which the reader parses back.
        df = pd.DataFrame({time_column: rec.time,
                           **{(f"{n} [{rec.units[n]}]" if units_in_header and rec.units.get(n) else n): rec.channels[n]
                              for n in rec.names}})
        df.to_csv(path, index=False, float_format="%.17g")
    elif kind == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        data = {n: rec.channels[n] for n in rec.names}
        if rec.t is not None:
            data = {time_column: rec.t, **data}
        else:
            info.update(fs=rec.fs, t0=rec.t0)
        table = pa.table(data).replace_schema_metadata({b"senscal": json.dumps(info).encode()})
        pq.write_table(table, path)
    elif kind == "hdf5":
        import h5py

        with h5py.File(path, "w") as fh:
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
        with TdmsWriter(path) as writer:
            writer.write_segment(objs)
    elif kind == "npz":
        arrays: dict[str, Any] = {n: rec.channels[n] for n in rec.names}
        if rec.t is not None:
            arrays[time_column] = rec.t
        else:
            arrays["fs"] = np.float64(rec.fs)
            arrays["t0"] = np.float64(rec.t0)
        arrays["__senscal__"] = np.array(json.dumps(info))
        np.savez(path, **arrays)
    return path
