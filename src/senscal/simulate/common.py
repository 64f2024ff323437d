"""Helpers shared by the simulators."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from senscal._result import to_jsonable


def write_truth(truth: dict[str, Any], path: str | Path) -> Path:
    """Write the simulation truth as JSON (folders created)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(to_jsonable(truth), indent=2) + "\n")
    return path
