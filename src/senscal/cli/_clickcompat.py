"""Click as Typer actually uses it, and the exception classes to catch.

Recent Typer releases vendor Click (``typer._click``), older ones use Click
itself; the command line builds its stand-in commands with whichever Typer
uses and catches its exceptions.  Standalone Click is not imported for that
(it costs start-up time), but when something else has imported it, its
exceptions are caught as well: a library raising them must still end in one
line, not a traceback.
"""

from __future__ import annotations

import sys

try:  # Typer >= 0.2x vendors its own copy of Click
    from typer import _click as click  # type: ignore[attr-defined]
except ImportError:  # pragma: no cover - depends on the Typer version
    import click  # type: ignore[no-redef]

__all__ = ["click", "ClickException", "Abort", "Exit"]


def _classes(name: str) -> tuple[type, ...]:
    mods = [click.exceptions]
    standalone = sys.modules.get("click.exceptions")
    if standalone is not None and standalone is not click.exceptions:
        mods.append(standalone)
    return tuple(getattr(m, name) for m in mods if isinstance(getattr(m, name, None), type))


def __getattr__(name: str) -> tuple[type, ...]:
    # Looked up when an `except cx.ClickException:` clause is matched, so a Click imported later counts too.
    if name in ("ClickException", "Abort", "Exit"):
        return _classes(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
