"""Shared behaviour of the immutable result dataclasses."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

__all__ = ["ResultMixin", "to_jsonable"]


def to_jsonable(value: Any) -> Any:
    """Convert NumPy scalars/arrays, dataclasses and paths to JSON types.

    Non-finite floats become ``None`` (JSON has no NaN).
    """
    # numpy loads with the first conversion, not with this module: result classes are imported by
    # `senscal fit --help` and friends, which should start without numpy. A value can only be a numpy
    # object if numpy is loaded already, so plain values (registry records) never load it.
    np = sys.modules.get("numpy")

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if hasattr(value, "to_dict"):
            return value.to_dict()
        return {f.name: to_jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if np is not None and isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, bool) or (np is not None and isinstance(value, np.bool_)):
        return bool(value)
    if np is not None and isinstance(value, np.integer):
        return int(value)
    if isinstance(value, float) or (np is not None and isinstance(value, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, Path):
        return str(value)
    return value


class ResultMixin:
    """Mixin for frozen result dataclasses: ``to_dict()`` for JSON."""

    def to_dict(self) -> dict[str, Any]:
        """Return the result as plain JSON-serialisable Python types."""
        return {
            f.name: to_jsonable(getattr(self, f.name))
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
            if f.repr
        }
