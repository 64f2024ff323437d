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


def write_simulation(recs, truth: dict[str, Any], out: str | Path, stem: str) -> list[Path]:
    """Write simulated recordings as ``<stem>_NN.csv`` and the truth as ``<stem>_truth.json``.

    Parameters
    ----------
    recs : sequence of Recording
        One recording per truth point.
    truth : dict
        Simulation truth with a ``"points"`` list (one per recording); each point gets
        the ``"file"`` name of its recording (the dict is updated in place).
    out : path
        Output folder (created).
    stem : str
        File name stem, e.g. ``centrifuge``.

    Returns
    -------
    list of Path
        The recordings written, in order.
    """
    from senscal.io import write_recording

    paths = []
    for i, (rec, pt) in enumerate(zip(recs, truth["points"]), start=1):
        p = write_recording(rec, Path(out) / f"{stem}_{i:02d}.csv")
        pt["file"] = p.name
        paths.append(p)
    write_truth(truth, Path(out) / f"{stem}_truth.json")
    return paths
