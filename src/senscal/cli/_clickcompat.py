"""Click's exception classes as Typer actually raises them.

Recent Typer releases vendor Click (``typer._click``), older ones use Click
itself; the command line must catch whichever is in use.
"""

from __future__ import annotations

import click

_mods = [click.exceptions]
try:  # Typer >= 0.2x vendors its own copy of Click
    from typer._click import exceptions as _vendored  # type: ignore[attr-defined]

    _mods.append(_vendored)
except ImportError:  # pragma: no cover - depends on the Typer version
    pass



def _classes(name: str) -> tuple[type, ...]:
    return tuple(getattr(m, name) for m in _mods if isinstance(getattr(m, name, None), type))


ClickException = _classes("ClickException")
Abort = _classes("Abort")
Exit = _classes("Exit")
