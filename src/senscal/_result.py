"""Shared behaviour of the immutable result dataclasses."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

__all__ = ["ResultMixin", "to_jsonable"]


def to_jsonable(value: Any) -> Any:
    """Convert NumPy scalars/arrays, dataclasses and paths to JSON types.

    Non-finite floats become ``None`` (JSON has no NaN).
    """
    # numpy loads with the first conversion, not with this module: result classes are imported by
    # `senscal fit --help` and friends, which should start without numpy.
    import numpy as np

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        if hasattr(value, "to_dict"):
            return value.to_dict()
        return {f.name: to_jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
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
