"""The rate-table file of ``senscal imu calibrate --rate-table FILE``: segments of known angular rate.

A rate table turns the IMU about one axis at a rate it states; each segment
of constant rate is one row.  The file is CSV (``.csv``, ``.txt``) or YAML
(``.yaml``, ``.yml``); every number carries its unit (a quantity, parsed by
:mod:`senscal.units`), a bare number is refused::

    # senscal rate table: times on the recording's time axis
    start, stop, axis, rate, u_rate, u_axis
    160 s, 170 s, +z, 30 deg/s, 0.002 deg/s, 0.05 deg
    175 s, 185 s, +z, -30 deg/s, 0.002 deg/s, 0.05 deg

or::

    segments:
      - {start: 160 s, stop: 170 s, axis: +z, rate: 30 deg/s, u_rate: 0.002 deg/s, u_axis: 0.05 deg}
      - {start: 175 s, stop: 185 s, axis: [0, 0, 1], rate: -30 deg/s, u_rate: 0.01 %}

Columns
-------
start, stop
    The constant-rate part of the segment (time: ``s``, ``ms``, ``min``) on the recording's time axis (its
    time column; a record without one starts at 0 at its first sample).
axis
    The table's axis in the IMU's accelerometer frame: ``x``, ``+y``, ``-z`` or a vector (``0 0.6 0.8``
    in CSV, a list in YAML; normalised).
rate
    The table's rate about ``axis`` (signed; ``deg/s``, ``rad/s``, ``rpm``).
u_rate
    Standard uncertainty (k=1) of the stated rate: an angular rate, or relative (``%``, ``ppm``).
u_axis
    Optional: standard uncertainty of the axis direction as mounted (an angle per tilt direction, ``deg``,
    ``mrad``); default 0 (the axis exactly as stated).
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import FileFormatError, InputError

__all__ = ["RateTable", "read_rate_table", "rate_table_text", "COLUMNS"]

COLUMNS = ("start", "stop", "axis", "rate", "u_rate", "u_axis")
_REQUIRED = COLUMNS[:5]
_AXES = {"x": 0, "y": 1, "z": 2}
_NUMBER = re.compile(r"^\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\s*$")


@dataclass(frozen=True)
class RateTable(ResultMixin):
    """Rate-table segments in SI units (what :func:`senscal.imu.calibrate_imu` takes).

    Attributes
    ----------
    start, stop : ndarray, shape (K,)
        Constant-rate part of each segment, s on the recording's time axis.
    axis : ndarray, shape (K, 3)
        Unit vectors of the table axis in the accelerometer frame.
    rate : ndarray, shape (K,)
        Stated rate about ``axis``, rad/s (signed).
    u_rate : ndarray, shape (K,)
        Its standard uncertainty, rad/s.
    u_axis : ndarray, shape (K,)
        Standard uncertainty of the axis direction per tilt direction, rad.
    source : str
    """

    start: np.ndarray
    stop: np.ndarray
    axis: np.ndarray
    rate: np.ndarray
    u_rate: np.ndarray
    u_axis: np.ndarray
    source: str = "rate table"

    @property
    def n_segments(self) -> int:
        return int(self.rate.size)

    @property
    def rate_vectors(self) -> np.ndarray:
        """``rate * axis`` per segment, shape (K, 3), rad/s."""
        return self.rate[:, None] * self.axis

    def label(self, k: int) -> str:
        """``'segment 2 (160-170 s, 0.5236 rad/s about +z)'`` for messages."""
        a = self.axis[k]
        big = int(np.argmax(np.abs(a)))
        ax = (("+" if a[big] > 0 else "-") + "xyz"[big]) if abs(abs(a[big]) - 1) < 1e-12 else \
            "(" + ", ".join(f"{v:.3g}" for v in a) + ")"
        return f"segment {k + 1} ({self.start[k]:g}-{self.stop[k]:g} s, {self.rate[k]:.6g} rad/s about {ax})"


def _quantity(value: Any, unit: str, what: str, *, relative_to: float | None = None) -> float:
    """A cell with its unit in ``unit``; a bare number is refused (units are quantities, never implied)."""
    from senscal.units import parse_quantity

    if isinstance(value, bool) or value is None or (isinstance(value, str) and not value.strip()):
        raise InputError(f"{what} is empty; give a number with its unit, e.g. '1 {unit}'")
    if isinstance(value, (int, float)) or _NUMBER.match(str(value)):
        raise InputError(f"{what} {value!r} has no unit; write the unit after the number, e.g. '{value} {unit}'")
    text = str(value).strip()
    if relative_to is not None and re.search(r"(%|ppm|ppb)\s*$", text):
        return abs(relative_to) * float(parse_quantity(text, "1", option=what))
    return float(parse_quantity(text, unit, option=what))


def _axis(value: Any, what: str) -> np.ndarray:
    if isinstance(value, str):
        s = value.strip().lower()
        m = re.fullmatch(r"([+-]?)\s*([xyz])", s)
        if m:
            v = np.zeros(3)
            v[_AXES[m.group(2)]] = -1.0 if m.group(1) == "-" else 1.0
            return v
        parts = [p for p in re.split(r"[\s;,]+", s.strip("[]() ")) if p]
    elif isinstance(value, (list, tuple)):
        parts = list(value)
    else:
        parts = []
    try:
        v = np.array([float(p) for p in parts], float)
    except (TypeError, ValueError):
        v = np.zeros(0)
    if v.shape != (3,) or not np.isfinite(v).all() or not np.linalg.norm(v) > 0:
        raise InputError(f"{what} {value!r} is not an axis; give x, +y, -z or three numbers (a direction in the "
                         "accelerometer frame)")
    return v / np.linalg.norm(v)


def _rows_csv(text: str, source: str) -> list[dict[str, Any]]:
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise FileFormatError(f"rate table {source} holds no rows; give a header 'start, stop, axis, rate, u_rate' "
                              "and one row per segment")
    reader = csv.reader(io.StringIO("\n".join(lines)), skipinitialspace=True)
    rows = list(reader)
    head = [h.strip().lower() for h in rows[0]]
    out = []
    for n, r in enumerate(rows[1:], start=2):
        if len(r) != len(head):
            raise FileFormatError(f"rate table {source}, row {n}: {len(r)} cells for {len(head)} columns "
                                  f"({', '.join(head)}); a vector axis is written with spaces, '0 0 1'")
        out.append(dict(zip(head, (c.strip() for c in r))))
    _check_columns(head, source)
    return out


def _check_columns(head, source: str) -> None:
    miss = [c for c in _REQUIRED if c not in head]
    if miss:
        raise FileFormatError(f"rate table {source} lacks the column(s) {', '.join(miss)}; its columns are "
                              f"{', '.join(map(str, head)) or 'none'} (needed: {', '.join(_REQUIRED)}, optional u_axis)")
    extra = [c for c in head if c not in COLUMNS]
    if extra:
        raise FileFormatError(f"rate table {source}: unknown column(s) {', '.join(map(str, extra))}; the columns are "
                              f"{', '.join(COLUMNS)}")


def read_rate_table(path: str | Path) -> RateTable:
    """Read a rate-table file (CSV, or YAML for ``.yaml``/``.yml``; the format in this module's docstring).

    Raises
    ------
    FileFormatError, InputError
        Unreadable file, missing columns, a number without its unit, a unit of the wrong dimension, a stop not
        after its start, a negative u, no rows (one line naming the row and the fix).
    """
    from senscal.io.sidefiles import read_text, read_yaml

    p = Path(path)
    src = str(path)
    if p.suffix.lower() in (".yaml", ".yml"):
        doc = read_yaml(p, "rate table", expect=None)
        rows = doc.get("segments") if isinstance(doc, dict) else doc
        if not isinstance(rows, list) or not rows or not all(isinstance(r, dict) for r in rows):
            raise FileFormatError(f"rate table {src} must hold 'segments:', a list of mappings with "
                                  f"{', '.join(_REQUIRED)}")
        for r in rows:
            _check_columns([str(k).lower() for k in r], src)
        rows = [{str(k).lower(): v for k, v in r.items()} for r in rows]
    else:
        rows = _rows_csv(read_text(p, "rate table"), src)
    if not rows:
        raise FileFormatError(f"rate table {src} holds a header but no segment; add one row per constant-rate segment")
    cols: dict[str, list] = {c: [] for c in COLUMNS}
    for n, r in enumerate(rows, start=1):
        where = f"rate table {src}, segment {n}:"
        start = _quantity(r["start"], "s", f"{where} start")
        stop = _quantity(r["stop"], "s", f"{where} stop")
        if not stop > start:
            raise InputError(f"{where} stop {r['stop']} is not after start {r['start']}; give the constant-rate part")
        rate = _quantity(r["rate"], "rad/s", f"{where} rate")
        u_rate = _quantity(r["u_rate"], "rad/s", f"{where} u_rate", relative_to=rate)
        u_axis = _quantity(r["u_axis"], "rad", f"{where} u_axis") if r.get("u_axis") not in (None, "") else 0.0
        if not (rate != 0 and math.isfinite(rate)):
            raise InputError(f"{where} rate {r['rate']} is zero; a rate-table segment turns (still data are poses)")
        if not (u_rate >= 0 and u_axis >= 0):
            raise InputError(f"{where} u_rate and u_axis are standard uncertainties and cannot be negative")
        for c, v in zip(COLUMNS, (start, stop, _axis(r["axis"], f"{where} axis"), rate, u_rate, u_axis)):
            cols[c].append(v)
    return RateTable(start=np.array(cols["start"]), stop=np.array(cols["stop"]), axis=np.array(cols["axis"]),
                     rate=np.array(cols["rate"]), u_rate=np.array(cols["u_rate"]), u_axis=np.array(cols["u_axis"]),
                     source=src)


def rate_table_text(table: RateTable) -> str:
    """The CSV form of ``table`` (what ``senscal simulate imu --rate-table`` writes), rates in deg/s."""
    lines = ["# senscal rate table: constant-rate segments, times on the recording's time axis",
             "start, stop, axis, rate, u_rate, u_axis"]
    for k in range(table.n_segments):
        a = table.axis[k]
        big = int(np.argmax(np.abs(a)))
        ax = (("+" if a[big] > 0 else "-") + "xyz"[big]) if abs(abs(a[big]) - 1) < 1e-12 else \
            " ".join(f"{v:.12g}" for v in a)
        lines.append(f"{table.start[k]:.6f} s, {table.stop[k]:.6f} s, {ax}, {math.degrees(table.rate[k]):.12g} deg/s, "
                     f"{math.degrees(table.u_rate[k]):.6g} deg/s, {math.degrees(table.u_axis[k]):.6g} deg")
    return "\n".join(lines) + "\n"
