"""``senscal demo``: every job run on simulated truth, one report.

Each job adds itself by a module ``senscal/demo/job_<name>.py`` that defines

* ``ORDER`` (int): position in the report,
* ``TITLE`` (str),
* ``run(out: pathlib.Path, seed: int) -> DemoSection``: simulate, run the
  job, write its outputs/plots under ``out`` and return what to show.

:func:`run_demo` discovers the modules, runs them, and writes ``index.html``.
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

from senscal._result import ResultMixin

__all__ = ["DemoSection", "discover", "run_demo"]


@dataclass(frozen=True)
class DemoSection(ResultMixin):
    """What one job shows in the demo.

    Attributes
    ----------
    key, title : str
        Identifier and heading.
    summary : str
        One or two sentences: what was simulated and what the job did.
    rows : tuple of dict
        Truth vs estimate rows with keys ``quantity``, ``truth``, ``estimate``,
        ``uncertainty`` (standard, k=1), ``unit``; ``truth`` may be None.
    plot : str or None
        Key plot, path relative to the demo folder.
    files : tuple of str
        Output files/certificates, relative to the demo folder.
    tables : tuple of dict
        Extra tables: ``{"title": str, "columns": [...], "rows": [[...], ...]}``.
    """

    key: str
    title: str
    summary: str
    rows: tuple[dict[str, Any], ...] = ()
    plot: str | None = None
    files: tuple[str, ...] = ()
    tables: tuple[dict[str, Any], ...] = field(default=())


def discover() -> list[ModuleType]:
    """The demo job modules, in report order."""
    mods = []
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("job_"):
            mods.append(importlib.import_module(f"{__name__}.{info.name}"))
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.__name__))


def run_demo(out: Path, *, seed: int = 1, only: list[str] | None = None,
             on_start: Callable[[ModuleType], None] | None = None,
             on_done: Callable[[DemoSection], None] | None = None) -> tuple[list[DemoSection], Path]:
    """Run every demo job and write ``out/index.html``.

    Returns
    -------
    sections : list of DemoSection
    index : Path
        The report a person opens first.
    """
    from senscal.report.index import write_index

    from senscal.io.guard import check_output_dir

    out = check_output_dir(out, what="demo folder")
    sections = []
    for mod in discover():
        key = mod.__name__.rsplit(".", 1)[1][len("job_"):]
        if only and key not in only:
            continue
        if on_start:
            on_start(mod)
        sec = mod.run(out, seed)
        sections.append(sec)
        if on_done:
            on_done(sec)
    index = write_index(sections, out, seed=seed)
    return sections, index
