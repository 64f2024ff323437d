"""Helpers shared by the simulators."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from senscal._result import to_jsonable


def write_truth(truth: dict[str, Any], path: str | Path) -> Path:
    """Write the simulation truth as JSON (folders created)."""
    from senscal.io.guard import check_output, write_text

    path = check_output(path)
    write_text(path, json.dumps(to_jsonable(truth), indent=2) + "\n", what="truth file")
    return path
