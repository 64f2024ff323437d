"""Plain-text ``--help`` with the options grouped under their panel names.

Help is Click's plain text, not Rich panels: it reads the same at 80 columns
and in a pipe, and printing it imports neither Rich (about 100 ms with its
Markdown renderer) nor anything else.  Options declared with a
``rich_help_panel`` (``"Sensor registry"``, ``"Certificate"``) are listed under
a section of that name after the ordinary options, in the order they first
appear, as the Rich panels were.
"""

from __future__ import annotations

import inspect
from typing import Any

# Definition-list columns as Click draws them: names up to this wide share one column, longer ones put their
# help on the next line.
_COL_MAX = 30
# Click wraps at hyphens ("back-" / "to-back", "[default: no-" / "drift]"); a non-breaking hyphen while wrapping
# keeps hyphenated words and option names whole.
_NB_HYPHEN = "\u2011"


def _write_dl(formatter: Any, rows: list[tuple[str, str]]) -> None:
    start = len(formatter.buffer)
    formatter.write_dl([(first, second.replace("-", _NB_HYPHEN)) for first, second in rows], col_max=_COL_MAX)
    formatter.buffer[start:] = [piece.replace(_NB_HYPHEN, "-") for piece in formatter.buffer[start:]]


def _sections(command: Any, ctx: Any) -> list[tuple[str, list[tuple[str, str]]]]:
    """``[(heading, [(names, help), ...]), ...]``: arguments, argument panels, options, option panels."""
    order: dict[tuple[int, str], list[tuple[str, str]]] = {(0, "Arguments"): [], (2, "Options"): []}
    for param in command.get_params(ctx):
        record = param.get_help_record(ctx)
        if record is None:
            continue
        is_option = param.param_type_name == "option"
        default = "Options" if is_option else "Arguments"
        panel = getattr(param, "rich_help_panel", None) or default
        rank = (2 if is_option else 0) + (panel != default)
        order.setdefault((rank, panel), []).append(record)
    # Stable sort by rank keeps each group's panels in order of first appearance.
    return [(name, rows) for (_, name), rows in sorted(order.items(), key=lambda kv: kv[0][0]) if rows]


def format_options(command: Any, ctx: Any, formatter: Any) -> None:
    """Write ``command``'s parameters (and a group's commands) as plain sections.

    One column width for every section, so the help texts of "Options" and
    "Sensor registry" line up.
    """
    sections = _sections(command, ctx)
    width = min(max((len(first) for _, rows in sections for first, _ in rows), default=0), _COL_MAX)
    for name, rows in sections:
        with formatter.section(name):
            _write_dl(formatter, [(first.ljust(width) if second else first, second) for first, second in rows])
    if getattr(command, "commands", None) is not None:
        rows = _command_rows(command, ctx)
        if rows:
            with formatter.section("Commands"):
                _write_dl(formatter, rows)


def _command_rows(group: Any, ctx: Any) -> list[tuple[str, str]]:
    """``(name, first paragraph of its help)`` per visible subcommand.

    The whole first paragraph, wrapped, as the Rich panels showed it; Click's
    own short help cuts it at the first word ending in a period ("e.g.").
    """
    rows = []
    for name in group.list_commands(ctx):
        sub = group.get_command(ctx, name)
        if sub is None or sub.hidden:
            continue
        text = inspect.cleandoc(sub.short_help or sub.help or "").partition("\f")[0].split("\n\n")[0]
        rows.append((name, " ".join(w for w in text.split() if w != "\b")))
    return rows


def plain_help(command: Any) -> Any:
    """Give ``command`` and its subcommands plain, panel-grouped help (see the module docstring)."""
    if not getattr(command, "_senscal_plain_help", False):
        # Typer prints plain Click help when a command has no markup mode; the sections are ours.
        command.rich_markup_mode = None
        command.format_options = lambda ctx, formatter, __c=command: format_options(__c, ctx, formatter)
        command._senscal_plain_help = True
    for sub in (getattr(command, "commands", None) or {}).values():
        plain_help(sub)
    return command
