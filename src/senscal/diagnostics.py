"""Named warnings: what departs from a method's model, said in one line.

Every result that can be wrong when real data depart from the model carries a
``warnings`` tuple of plain strings.  A *named* warning starts with a short
kebab-case name and a colon (``"coloured-noise: the residual is not white
(Ljung-Box p = 1e-9); uncertainties use the noise at the fitted frequency"``),
so scripts can match the name while people read the sentence.  The command
line prints each warning on stderr and ``--strict`` turns any of them into
exit code 3 (:class:`senscal.errors.DiagnosticError`).
"""

from __future__ import annotations

import re
from typing import Iterable

__all__ = ["named", "warning_name", "warning_names", "has_warning"]

_NAME = re.compile(r"^([a-z][a-z0-9]*(?:-[a-z0-9]+)*): ")


def named(name: str, text: str) -> str:
    """Return the warning ``"name: text"``.

    Parameters
    ----------
    name : str
        Kebab-case name of the departure (``coloured-noise``,
        ``encoder-zero-unknown``, ...).  Stable: scripts and tests match it.
    text : str
        One sentence that says what departs and what to do.
    """
    if not _NAME.match(name + ": "):
        raise ValueError(f"warning name must be kebab-case, got {name!r}")
    return f"{name}: " + " ".join(str(text).split())


def warning_name(warning: str) -> str | None:
    """The name of a named warning, or None for an unnamed one."""
    m = _NAME.match(str(warning))
    return m.group(1) if m else None


def warning_names(warnings: Iterable[str]) -> tuple[str, ...]:
    """Names of the named warnings in ``warnings`` (order kept)."""
    return tuple(n for n in (warning_name(w) for w in warnings) if n is not None)


def has_warning(warnings: Iterable[str], name: str) -> bool:
    """True when a warning called ``name`` is among ``warnings``."""
    return name in warning_names(warnings)
