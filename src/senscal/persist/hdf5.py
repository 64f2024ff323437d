"""A JSON document stored as a real HDF5 tree, and read back to the same document.

Mapping (readable by any HDF5 tool, e.g. ``h5dump`` or ``h5py``):

- an object is a group; its text, number, boolean and null members are
  attributes of the group (null as an empty attribute), its other members
  children;
- a list of numbers (any rectangular nesting, e.g. a 3x3 matrix) or of
  strings is a dataset;
- any other list (of objects, mixed, ragged, empty) is a group marked with
  the attribute ``senscal_list`` = its length, members named ``0``, ``1``, ...

Names are percent-escaped where HDF5 forbids them (``/``, a lone ``.``, an
empty name).
"""

from __future__ import annotations

import numbers
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["write_tree", "read_tree", "LIST_MARK"]

LIST_MARK = "senscal_list"


def _name(key: str) -> str:
    key = str(key).replace("%", "%25").replace("/", "%2F")
    return {".": "%2E", "": "%00"}.get(key, key)


def _key(name: str) -> str:
    if name in ("%2E", "%00"):
        return {"%2E": ".", "%00": ""}[name]
    return name.replace("%2F", "/").replace("%25", "%")


def _is_scalar(v: Any) -> bool:
    return v is None or isinstance(v, (str, bool, numbers.Number))


def _numeric_array(v: list) -> np.ndarray | None:
    try:
        arr = np.asarray(v)
    except (ValueError, TypeError):  # ragged
        return None
    if arr.size == 0 or arr.dtype.kind not in "biuf":
        return None
    # Only when the array gives the same document back: no int rounded to float, no bool made a number.
    if arr.tolist() != v or (arr.dtype.kind != "b" and any(isinstance(x, bool) for x in _leaves(v))):
        return None
    return arr


def _leaves(v: Any):
    for x in v:
        if isinstance(x, (list, tuple)):
            yield from _leaves(x)
        else:
            yield x


def _put(group, key: str, value: Any) -> None:
    import h5py

    name = _name(key)
    if value is None:
        group.attrs[name] = h5py.Empty("f8")
    elif _is_scalar(value):
        group.attrs[name] = value
    elif isinstance(value, dict):
        sub = group.create_group(name)
        for k, v in value.items():
            _put(sub, k, v)
    elif isinstance(value, (list, tuple)):
        arr = _numeric_array(list(value))
        if arr is not None:
            group.create_dataset(name, data=arr)
        elif value and all(isinstance(v, str) for v in value):
            group.create_dataset(name, data=list(value), dtype=h5py.string_dtype())
        else:
            sub = group.create_group(name)
            sub.attrs[LIST_MARK] = len(value)
            for i, v in enumerate(value):
                _put(sub, str(i), v)
    else:
        raise TypeError(f"cannot store {type(value).__name__} in HDF5")


def write_tree(path: str | Path, doc: dict[str, Any]) -> None:
    """Write the JSON-ready mapping ``doc`` as the root group of a new HDF5 file ``path``."""
    import h5py

    with h5py.File(path, "w") as fh:
        for k, v in doc.items():
            _put(fh, k, v)


def _plain(value: Any) -> Any:
    import h5py

    if isinstance(value, h5py.Empty):
        return None
    if isinstance(value, bytes):
        return value.decode("utf-8")
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()] if value.dtype.kind in "OSU" else value.tolist()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _get(node) -> Any:
    import h5py

    if isinstance(node, h5py.Dataset):
        return _plain(node[()])
    attrs = {_key(k): _plain(v) for k, v in node.attrs.items()}
    if LIST_MARK in attrs and not isinstance(attrs[LIST_MARK], (dict, list)):
        n = int(attrs.pop(LIST_MARK))
        members = {**attrs, **{_key(k): _get(node[k]) for k in node}}
        return [members[str(i)] for i in range(n)]
    return {**attrs, **{_key(k): _get(node[k]) for k in node}}


def read_tree(path: str | Path) -> dict[str, Any]:
    """Read an HDF5 file written by :func:`write_tree` back into the JSON-ready mapping."""
    import h5py

    with h5py.File(path, "r") as fh:
        return _get(fh)
