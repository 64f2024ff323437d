"""Readers for the small side files commands take (models, parameters, layouts, registry exports).

Each turns every way a file can be bad -- missing, a folder, unreadable,
not UTF-8, not JSON/YAML, nested so deep the parser recurses out, the wrong
type at the top, arrays of the wrong shape -- into one
:class:`~senscal.errors.FileFormatError` that names the file and what is
wrong.  The modules that own each file kind keep checking their own keys;
these helpers only take care of the generic failures, so every loader fails
the same way.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from senscal.errors import FileFormatError
from senscal.io.guard import is_stdio, note_input, stdin_bytes

__all__ = ["read_text", "read_json", "read_yaml", "array_field"]

# Side files are a few kB; anything far larger is not one (and would be read whole into memory).
MAX_SIDE_FILE_BYTES = 64 * 1024 * 1024


def read_text(path: str | os.PathLike, what: str = "file") -> str:
    """Read a UTF-8 text side file.

    Parameters
    ----------
    path : path-like
        The file; ``-`` reads standard input.
    what : str
        What the file is (``"model file"``), used in messages.

    Returns
    -------
    str
        The file's text.

    Raises
    ------
    FileFormatError
        Missing, a folder, unreadable, too large or not UTF-8.
    """
    if is_stdio(path):
        data = stdin_bytes(what)
        try:
            return data.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise FileFormatError(f"{what} on standard input is not UTF-8 text (bad byte at offset {exc.start}); "
                                  "give the file name") from None
    path = Path(path)
    note_input(path)
    if not path.exists():
        raise FileFormatError(f"{what} {path} does not exist")
    if path.is_dir():
        raise FileFormatError(f"{what} {path} is a folder; give a file")
    try:
        size = path.stat().st_size
        if size > MAX_SIDE_FILE_BYTES:
            raise FileFormatError(f"{what} {path} is {size / 2**20:.0f} MiB; a {what} is a small text file, "
                                  "check the file name")
        data = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(f"cannot read {what} {path}: {(exc.strerror or str(exc)).lower()}") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FileFormatError(f"{what} {path} is not UTF-8 text (bad byte at offset {exc.start}); "
                              "save it as UTF-8") from None


def read_json(path: str | os.PathLike, what: str = "file", *, expect: type | None = dict) -> Any:
    """Read a JSON side file.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file is, used in messages.
    expect : type, optional
        Required type of the top-level value (default ``dict``; None: any).

    Returns
    -------
    Any
        The parsed document.

    Raises
    ------
    FileFormatError
        Any failure of :func:`read_text`, invalid JSON (with line and column),
        nesting too deep to parse, or the wrong top-level type.
    """
    path = Path(path)
    text = read_text(path, what)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"{what} {path} is not valid JSON ({exc.msg} at line {exc.lineno} column {exc.colno})"
                              ) from None
    except RecursionError:
        raise FileFormatError(f"{what} {path} is nested too deeply to be a {what}") from None
    except ValueError as exc:  # e.g. integers with too many digits
        raise FileFormatError(f"{what} {path} is not valid JSON ({str(exc).splitlines()[0]})") from None
    _check_type(doc, expect, what, path)
    return doc


def read_yaml(path: str | os.PathLike, what: str = "file", *, expect: type | None = dict) -> Any:
    """Read a YAML side file with ``yaml.safe_load``; failures as in :func:`read_json`."""
    import yaml

    path = Path(path)
    text = read_text(path, what)
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise FileFormatError(f"{what} {path} is not valid YAML ({' '.join(str(exc).split())[:200]})") from None
    except RecursionError:
        raise FileFormatError(f"{what} {path} is nested too deeply to be a {what}") from None
    except (ValueError, TypeError, OverflowError) as exc:  # odd scalars (dates out of range ...)
        raise FileFormatError(f"{what} {path} has a value YAML cannot convert ({str(exc).splitlines()[0]})") from None
    _check_type(doc, expect, what, path)
    return doc


def _check_type(doc: Any, expect: type | None, what: str, path: Path) -> None:
    if expect is not None and not isinstance(doc, expect):
        names = {dict: "an object/mapping", list: "a list"}
        raise FileFormatError(f"{what} {path} holds {type(doc).__name__} at the top; it must be "
                              f"{names.get(expect, expect.__name__)}")


def array_field(value: Any, shape: Sequence[int], what: str) -> np.ndarray:
    """Convert a side file's value to a finite float array of an exact shape.

    Parameters
    ----------
    value : Any
        The parsed value (nested lists of numbers).
    shape : sequence of int
        Required shape, e.g. ``(3, 3)``; ``-1`` allows any length on that axis.
    what : str
        Names the field and file, e.g. ``"'gain' in model file m.json"``.

    Returns
    -------
    ndarray
        float64 array of that shape.

    Raises
    ------
    FileFormatError
        Not numbers, not finite, or of another shape.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError, RecursionError):
        raise FileFormatError(f"{what} must be numbers in an array of shape {tuple(shape)}") from None
    ok = arr.ndim == len(shape) and all(s == -1 or s == n for s, n in zip(shape, arr.shape))
    if not ok:
        raise FileFormatError(f"{what} has shape {arr.shape}; it must have shape {tuple(shape)}")
    if not np.all(np.isfinite(arr)):
        raise FileFormatError(f"{what} holds NaN or inf; it must be finite numbers")
    return arr
