"""Saved calibrations in one format: one loader, one type key, JSON or HDF5.

Every calibration senscal saves -- the shaft gravity model, the triaxial
calibration, the frequency response -- is a document whose top level holds
``"type"`` (what it is) and ``"format_version"`` (how it is laid out),
written as JSON or as a real HDF5 file (:mod:`senscal.persist.hdf5`); the
suffix of the path decides (``.h5``/``.hdf5``/``.hdf`` -> HDF5, anything
else JSON).  :func:`load_calibration` reads any of them and returns the
typed object, whose ``apply()`` corrects new data.

Format versions: 1 is what senscal wrote before this module (shaft models
tagged ``"kind"``, triaxial files ``"format"``, responses ``"type"``; a
``.h5`` response held JSON text); 2 tags every file ``"type"`` and writes
``.h5`` as HDF5.  Both load; a file without ``format_version`` is read as
version 1; a newer version is refused with "upgrade senscal".

Examples
--------
>>> import senscal                                            # doctest: +SKIP
>>> cal = senscal.load_calibration("params.h5")               # doctest: +SKIP
>>> corrected = cal.apply(raw_xyz)                            # doctest: +SKIP
"""

from __future__ import annotations

import importlib
import json
import os
from pathlib import Path
from typing import Any, Mapping

from senscal.errors import FileFormatError, SenscalError

__all__ = ["FORMAT_VERSION", "TYPES", "HDF5_SUFFIXES", "load_calibration", "read_document", "write_document",
           "document", "calibration_type", "check_version"]

#: Layout version every saved calibration is written with.
FORMAT_VERSION = 2

#: Type key -> (module, class with ``from_document(doc, source=...)``, name in words, what makes one).
TYPES: dict[str, tuple[str, str, str, str]] = {
    "senscal.shaft.GravityModel": ("senscal.shaft.model", "GravityModel", "shaft gravity model",
                                   "senscal shaft calibrate ... --out FILE"),
    "senscal.triaxial.TriaxialCalibration": ("senscal.triaxial.models", "TriaxialCalibration",
                                             "triaxial calibration", "senscal triaxial calibrate ... --out FILE"),
    "senscal.vibration.FrequencyResponse": ("senscal.vibration.response", "FrequencyResponse", "frequency response",
                                            "senscal response ... --save-response FILE"),
    "senscal.imu.ImuCalibration": ("senscal.imu.model", "ImuCalibration", "IMU calibration",
                                   "senscal imu calibrate ... --out FILE"),
}

# Version-1 files told their type through other keys.
_LEGACY_TAGS = (("kind", "senscal.shaft.GravityModel", "senscal.shaft.GravityModel"),
                ("format", "senscal.triaxial.calibration", "senscal.triaxial.TriaxialCalibration"))

HDF5_SUFFIXES = (".h5", ".hdf5", ".hdf")
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _is_hdf5_path(path: Path) -> bool:
    return path.suffix.lower() in HDF5_SUFFIXES


def write_document(doc: Mapping[str, Any], path: str | os.PathLike, *, what: str = "calibration file") -> Path:
    """Write a saved-calibration document atomically, as HDF5 or JSON by suffix.

    Parameters
    ----------
    doc : mapping
        JSON-ready document (:func:`senscal._result.to_jsonable` output)
        starting with ``type`` and ``format_version``.
    path : path-like
        Target; ``.h5``/``.hdf5``/``.hdf`` write HDF5, anything else JSON.
    what : str
        What the file is, for error messages.

    Returns
    -------
    Path
    """
    from senscal.io.guard import atomic_output, check_output, write_text

    path = check_output(path, what=what)
    if not _is_hdf5_path(path):
        return write_text(path, json.dumps(dict(doc), indent=1) + "\n", what=what)
    from senscal.persist.hdf5 import write_tree

    with atomic_output(path, what=what) as tmp:
        write_tree(tmp, dict(doc))
    return path


def read_document(path: str | os.PathLike, *, what: str = "calibration file") -> Any:
    """Read a saved document (JSON, HDF5, or the JSON text old senscal put in ``.h5`` files).

    Raises
    ------
    FileFormatError
        Missing, unreadable, or neither valid JSON nor a readable HDF5 file
        (one line naming the file).
    """
    from senscal.io.guard import is_stdio, note_input
    from senscal.io.sidefiles import read_json, read_text

    if is_stdio(path):
        return _read_stdin_document(what)
    path = Path(path)
    note_input(path)
    if not path.exists():
        raise FileFormatError(f"{what} {path} not found (the file does not exist); check the name, or save "
                              "the calibration first")
    if path.is_dir():
        raise FileFormatError(f"{what} {path} is a folder; give a file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(_HDF5_SIGNATURE))
    except OSError as exc:
        raise FileFormatError(f"cannot read {what} {path}: {(exc.strerror or str(exc)).lower()}") from None
    if head == _HDF5_SIGNATURE:
        from senscal.persist.hdf5 import read_tree

        try:
            return read_tree(path)
        except Exception as exc:  # h5py raises OSError, KeyError, ValueError ... on a damaged file
            raise FileFormatError(f"{what} {path} is a damaged HDF5 file ({type(exc).__name__}: "
                                  f"{str(exc).splitlines()[0] if str(exc) else 'unreadable'}); save it again") from None
    if _is_hdf5_path(path) and not read_text(path, what).lstrip().startswith("{"):
        raise FileFormatError(f"{what} {path} is neither an HDF5 file nor JSON; give a file saved by senscal")
    return read_json(path, what, expect=None)


def _read_stdin_document(what: str) -> Any:
    from senscal.io.guard import stdin_bytes

    data = stdin_bytes(what)
    if data.startswith(_HDF5_SIGNATURE):
        raise FileFormatError(f"{what} on standard input is HDF5, which needs a file; give the file name "
                              "(or pipe the JSON form)")
    try:
        return json.loads(data.decode("utf-8-sig"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise FileFormatError(f"{what} on standard input is not valid JSON ({str(exc).splitlines()[0][:120]}); "
                              "pipe a file saved by senscal") from None


def calibration_type(doc: Any) -> str | None:
    """The type key of a saved document (version-1 tags mapped to today's), or None."""
    if not isinstance(doc, dict):
        return None
    if isinstance(doc.get("type"), str):
        return doc["type"]
    for key, old, new in _LEGACY_TAGS:
        if doc.get(key) == old:
            return new
    cal = doc.get("calibration")
    if isinstance(cal, dict) and cal.get("format") == "senscal.triaxial.calibration":
        # a version-1 'triaxial calibrate --out' file: the report with the calibration inside
        return "senscal.triaxial.TriaxialCalibration"
    return None


def check_version(doc: Mapping[str, Any], source: str) -> int:
    """The document's ``format_version`` (1 when absent); refuse versions newer than this senscal reads."""
    ver = doc.get("format_version", 1)
    if isinstance(ver, bool) or not isinstance(ver, int) or ver < 1:
        raise FileFormatError(f"{source} has format_version {ver!r}, not a positive whole number; "
                              "the file is damaged: save the calibration again")
    if ver > FORMAT_VERSION:
        raise FileFormatError(f"{source} has format version {ver}, newer than this senscal reads "
                              f"({FORMAT_VERSION}); upgrade senscal")
    return ver


def load_calibration(path: str | os.PathLike, *, expect: str | None = None) -> Any:
    """Load any saved calibration and return its typed object.

    Parameters
    ----------
    path : path-like
        A file written by a calibration's ``save`` / a command's ``--out``
        or ``--save-response`` (JSON or HDF5; version 1 or 2).
    expect : str, optional
        Required type key (one of :data:`TYPES`); another type is refused
        with what to give instead.

    Returns
    -------
    GravityModel, TriaxialCalibration or FrequencyResponse
        Each has ``apply()`` (see its class).

    Raises
    ------
    FileFormatError
        Missing or corrupt file, not a senscal calibration, a calibration of
        another type than ``expect``, or a newer format version.
    """
    from senscal.io.guard import is_stdio

    path = Path(path)
    what = "calibration file"
    doc = read_document(path, what=what)
    if is_stdio(path):
        path = Path("standard input")
    kind = calibration_type(doc)
    source = f"{what} {path}"
    if expect is not None and kind != expect:
        label, make = TYPES[expect][2:]
        held = f"it holds a {TYPES[kind][2]}" if kind in TYPES else (
            f"its type is {kind!r}" if kind else _what_else(doc))
        raise FileFormatError(f"{path} is not a senscal {label} ({held}); give the file written by '{make}'")
    if kind not in TYPES:
        known = ", ".join(sorted(TYPES))
        detail = f"its type is {kind!r}" if kind else _what_else(doc)
        raise FileFormatError(f"{path} is not a senscal calibration ({detail}; known types: {known}); "
                              "give a file saved by a calibration command")
    check_version(doc, source)
    bad = _first_bad_number(doc)
    if bad is not None:
        # senscal writes a missing number as null, never NaN or inf, and no negative uncertainty.
        raise FileFormatError(f"{source} holds {bad[1]} at {bad[0]}, which senscal never writes (a damaged or "
                              "hand-edited file?); save the calibration again")
    module, cls = TYPES[kind][:2]
    try:
        return getattr(importlib.import_module(module), cls).from_document(doc, source=source)
    except SenscalError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as exc:
        # The typed readers check the fields they know; a field of the wrong kind can still break them.
        raise FileFormatError(f"{source} is damaged or hand-edited ({type(exc).__name__}: "
                              f"{str(exc).splitlines()[0][:120] if str(exc) else 'bad field'}); save the calibration "
                              "again") from None


def _is_uncertainty(key: str) -> bool:
    return key in ("u", "U_k2") or key.startswith("u_")


def _what_else(doc: Any) -> str:
    """What a document without a calibration type is, in words (a drift state, a fleet configuration ...)."""
    if isinstance(doc, Mapping) and isinstance(doc.get("kind"), str) and doc["kind"].startswith("senscal "):
        return f"it is a {doc['kind'][8:60]}"
    if isinstance(doc, Mapping) and "type" in doc:
        return f"its 'type' is a {type(doc['type']).__name__}, not a text"
    return "it has no 'type' key"


def _first_bad_number(doc: Any, where: str = "", key: str = "") -> tuple[str, str] | None:
    """``(where, what)`` of the first NaN/inf, or negative uncertainty (``u``, ``u_*``, ``U_k2``), in a document."""
    import numpy as np

    if isinstance(doc, Mapping):
        for k, v in doc.items():
            found = _first_bad_number(v, f"{where}.{k}" if where else str(k), str(k))
            if found is not None:
                return found
    elif isinstance(doc, (list, tuple)):
        for i, v in enumerate(doc):
            found = _first_bad_number(v, f"{where}[{i}]", key)
            if found is not None:
                return found
    elif isinstance(doc, (np.ndarray, float, np.floating)) and not isinstance(doc, bool):
        a = np.asarray(doc)
        if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
            return where, "a non-finite number"
        if _is_uncertainty(key) and a.dtype.kind in "fiu" and np.any(a < 0):
            return where, "a negative uncertainty"
    elif isinstance(doc, int) and not isinstance(doc, bool) and _is_uncertainty(key) and doc < 0:
        return where, "a negative uncertainty"
    return None


def document(type_key: str, fields: Mapping[str, Any], *, drop: tuple[str, ...] = ()) -> dict[str, Any]:
    """``{"type", "format_version", **fields}`` JSON-ready, without ``drop`` and older tag keys."""
    from senscal._result import to_jsonable

    skip = {"type", "format_version", *drop}
    return {"type": type_key, "format_version": FORMAT_VERSION,
            **{k: v for k, v in to_jsonable(dict(fields)).items() if k not in skip}}
