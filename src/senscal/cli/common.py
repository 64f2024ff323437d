"""Helpers shared by the command modules: options, loading, output."""

from __future__ import annotations

import functools
import json
import math
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator, Optional, Sequence, TypeVar

import typer
from typing_extensions import Annotated

from senscal.errors import InputError
from senscal.io.guard import check_output

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

    from senscal.io import Recording

# numpy (through senscal._result and senscal.io), Rich and the readers load where they are used: `senscal --help`
# and `senscal fit --help` import this module and must start as fast as typer itself.

T = TypeVar("T")


class LazyConsole:
    """A Rich console built on first use (Rich costs ~50 ms to import; ``--help`` prints without it).

    Every attribute read or written goes to the console, so ``console.print``,
    ``console.width = 120`` and monkeypatching behave as on the console itself.
    """

    # The proxy's own state lives in slots, so its ``__dict__`` can be the console's: tools that read an
    # instance's ``__dict__`` to save and restore an attribute (pytest >= 9.2's monkeypatch does, to
    # decide between restoring and deleting) then see the console's own attributes, and restoring
    # ``_width`` no longer deletes it from the real console.
    __slots__ = ("_build", "_real")

    def __init__(self, build: Callable[[], Console]):
        object.__setattr__(self, "_build", build)
        object.__setattr__(self, "_real", None)

    @property
    def __dict__(self) -> dict[str, Any]:  # type: ignore[override]
        return self.real().__dict__

    def real(self) -> Console:
        """The Rich console itself (built now if it was not yet)."""
        con = object.__getattribute__(self, "_real")
        if con is None:
            con = object.__getattribute__(self, "_build")()
            object.__setattr__(self, "_real", con)
        return con

    def __getattr__(self, name: str) -> Any:
        return getattr(self.real(), name)

    def __setattr__(self, name: str, value: Any) -> None:
        setattr(self.real(), name, value)

    def __delattr__(self, name: str) -> None:
        delattr(self.real(), name)


# Markup and emoji codes off: file names, serials, units and notes are user
# strings, and '[/' in one crashed the output (after a registry write had
# committed) while '[link=...]' made a hyperlink.  The few deliberate styles
# pass markup=True and escape whatever user text they carry.
def _stdout_console() -> Console:
    from rich.console import Console

    class _Console(Console):
        """A stdout console that moves to stderr once data went to stdout (``--out -``)."""

        @property
        def file(self):
            from senscal.io.guard import stdout_claimed

            if not self.stderr and self._file is None and stdout_claimed():
                # Tables and "wrote ..." lines would corrupt the data a pipe reads.
                return sys.stderr
            return super().file

        @file.setter
        def file(self, new_file) -> None:
            self._file = new_file

    return _Console(highlight=False, markup=False, emoji=False)


def _stderr_console() -> Console:
    from rich.console import Console

    # soft_wrap: messages stay one line when stderr is a file or pipe (Rich would wrap them at 80 columns).
    return Console(stderr=True, highlight=False, markup=False, emoji=False, soft_wrap=True)


console: Console = LazyConsole(_stdout_console)  # type: ignore[assignment]
err_console: Console = LazyConsole(_stderr_console)  # type: ignore[assignment]

# Options every command that reads recordings shares (same words everywhere).
TimeColumnOpt = Annotated[str, typer.Option("--time-column", help="Name of the time column (seconds).")]
# --fs, --start and --stop are quantities: a bare number in Hz / s, or '2 kHz', '500 ms' (senscal.cli._quantities).
FsOpt = Annotated[Optional[str], typer.Option("--fs", help="Sample rate in Hz for files without a time column "
                                                           "(or with a unit: '2 kHz').")]
TimeUnitOpt = Annotated[Optional[str], typer.Option(
    "--time-unit", help="Unit of a time column whose header gives none: s, ms, us or min (default s).")]
NamesOpt = Annotated[Optional[str], typer.Option("--names", help="Column names for a text file without header, comma separated.")]
SkipRowsOpt = Annotated[Optional[int], typer.Option(
    "--skip-rows", help="Text files: lines before the header to skip (default: a preamble of ';'/'#' comments and "
                        "key,value lines such as 'Fs,50' is detected).")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print a machine-readable JSON result on stdout.")]
StartOpt = Annotated[Optional[str], typer.Option(
    "--start", help="Drop the samples before this many seconds after the recording's first sample (or with a "
                    "unit: '500 ms').")]
StopOpt = Annotated[Optional[str], typer.Option(
    "--stop", help="Drop the samples after this many seconds after the recording's first sample (or with a "
                   "unit: '2 min').")]


# --- outputs: one check for every command, before it runs --------------------------------------------------

#: Options that name what a command writes: ``{parameter: (what, kind)}`` (kinds as in
#: :func:`senscal.io.guard.declare_outputs`).  A new command using these names is covered automatically.
OUTPUT_PARAMS: dict[str, tuple[str, str]] = {
    "out": ("--out", "file"), "plot": ("--plot", "file"), "report": ("--report", "file"),
    "dcc": ("--dcc", "file"), "save_response_to": ("--save-response", "file"), "state": ("--state", "update"),
}
#: Commands whose output options name a folder or differ from the table above.
OUTPUT_EXCEPTIONS: dict[str, dict[str, tuple[str, str]]] = {
    "demo": {"out": ("--out", "folder")},
    "drift-fleet": {"out": ("--out", "folder"), "state": ("--state", "update-folder")},
    "simulate": {"out": ("--out", "folder")},  # every simulator writes a folder of files
    "registry export": {"file": ("FILE", "file")},
}
# Extensions an output must have, checked before the work (the writers check them again).
_REPORT_SUFFIXES = (".html", ".htm", ".pdf")


def _output_params(command_path: str) -> dict[str, tuple[str, str]]:
    words = command_path.split()[1:]  # without "senscal"
    table = dict(OUTPUT_PARAMS)
    for n in range(1, len(words) + 1):
        table.update(OUTPUT_EXCEPTIONS.get(" ".join(words[:n]), {}))
    return table


def _path_values(value: Any) -> list[str]:
    if isinstance(value, (str, Path)) and str(value):
        return [str(value)]
    if isinstance(value, (list, tuple)):
        return [str(v) for v in value if isinstance(v, (str, Path)) and str(v)]
    return []


def _plot_suffixes() -> tuple[str, ...]:
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple("." + k for k in FigureCanvasBase.get_supported_filetypes())


def check_command_outputs(command_path: str, kw: dict) -> None:
    """Check every output a command line names before the command runs (see :func:`senscal.io.guard.declare_outputs`).

    Outputs are the options in :data:`OUTPUT_PARAMS` (and the exceptions per
    command); inputs are every other parameter that names an existing file.
    Extensions of plots, reports and DCCs are checked here too, so a bad
    ``--plot`` fails before a long run, not after ``--out`` was written.

    Raises
    ------
    InputError
        One line naming the option and the fix.
    """
    from senscal.io.guard import declare_outputs

    table = _output_params(command_path)
    outputs: dict[str, tuple[str, str]] = {}
    for name, (what, kind) in table.items():
        value = kw.get(name)
        if isinstance(value, (str, Path)) and str(value):
            outputs[str(value)] = (what, kind)
    inputs: dict[str, str] = {}
    for name, value in kw.items():
        if name in table:
            continue  # an output (an in-out one, --state, is compared with the other inputs, not with itself)
        for v in _path_values(value):
            if v != "-" and Path(v).is_file():
                inputs.setdefault(v, "input")
    if outputs:
        declare_outputs(outputs, inputs)  # an input named as an output is the first thing to say
    for name, (what, kind) in table.items():
        value = kw.get(name)
        if kind != "file" or not isinstance(value, (str, Path)) or str(value) in ("", "-"):
            continue
        allowed = {"plot": _plot_suffixes, "report": lambda: _REPORT_SUFFIXES, "dcc": lambda: (".xml",)}.get(name)
        suffix = Path(value).suffix.lower()
        if allowed is not None and suffix not in allowed():
            raise InputError(f"{what} {value} has an unsupported extension {suffix or '(none)'!r}; use one of "
                             f"{', '.join(sorted(allowed()))}")


def split_names(text: str | None) -> list[str] | None:
    """Split ``"a,b,c"`` into names (None stays None)."""
    if text is None:
        return None
    names = [s.strip() for s in text.split(",") if s.strip()]
    if not names:
        raise InputError(f"expected comma-separated names, got {text!r}")
    return names


def parse_floats(text: str, what: str) -> list[float]:
    """Parse ``"1,2.5,3"`` into floats with a clear error."""
    try:
        values = [float(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise InputError(f"{what} must be comma-separated numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{what} must be finite numbers, got {text!r}")
    return values


def parse_relative(text: str, what: str) -> float:
    """Parse ``"0.2%"`` (percent) or ``"0.002"`` (fraction) into a fraction."""
    s = text.strip()
    try:
        value = float(s[:-1]) / 100.0 if s.endswith("%") else float(s)
    except ValueError:
        raise InputError(f"{what} must be a number or a percentage like 0.2%, got {text!r}") from None
    if not math.isfinite(value):
        raise InputError(f"{what} must be a finite number, got {text!r}")
    if value < 0:
        raise InputError(f"{what} must not be negative, got {text!r}")
    if value >= 1e6:
        # No tolerance or relative uncertainty is a million times its quantity; such values (1e308%) are typos
        # and overflow the budgets that square them.
        raise InputError(f"{what} is a relative value, a fraction or a percentage; {text!r} is far too large")
    return value


def load(path: Path | str, *, time_column: str = "t", fs: float | None = None,
         names: str | None = None, channels: Sequence[str] | None = None,
         allow_nan: bool = False, time_unit: str | None = None, skip_rows: int | None = None,
         time_required: bool = True, start: float | None = None, stop: float | None = None,
         job: str | None = None) -> Recording:
    """Read a recording for a command (errors are one-line SenscalErrors).

    ``time_required=False`` for jobs that never use time: a file with neither
    time column nor sample rate is then read on a sample-index time base.
    ``-`` reads a CSV recording from standard input. ``start``/``stop``
    (``--start``/``--stop``) keep a window in seconds from the first sample;
    ``job`` selects the time-base checks, whose warnings are in the
    Recording's ``warnings`` (the command must report them).
    """
    from senscal.io import read_recording

    return read_recording(path, time_column=time_column, fs=fs, names=split_names(names),
                          channels=channels, allow_nan=allow_nan, time_unit=time_unit, skip_rows=skip_rows,
                          time_required=time_required, start=start, stop=stop, job=job)


# --- the part of the record a run used: --start/--stop ---------------------------------------------------

# Set by senscal.cli before every command (None without --start/--stop); the JSON document, the registry
# record and the certificate carry it, so a saved result says which part of the recording it used.
_WINDOW: dict[str, Any] | None = None


def set_window(start: float | None, stop: float | None) -> None:
    """Note the ``--start``/``--stop`` window (s from the first sample) of the command about to run."""
    global _WINDOW
    _WINDOW = None if start is None and stop is None else {
        "start_s": start, "stop_s": stop, "relative_to": "the first sample of each recording"}


def run_window() -> dict[str, Any] | None:
    """The window of the running command: ``{"start_s", "stop_s", "relative_to"}``, or None (whole record)."""
    return None if _WINDOW is None else dict(_WINDOW)


def window_text() -> str | None:
    """The window in words for a certificate: ``"0.5 s to 1.5 s after the first sample of each recording"``."""
    w = _WINDOW
    if w is None:
        return None
    start, stop = w["start_s"], w["stop_s"]
    if stop is None:
        return f"from {start:g} s after the first sample of each recording to its end"
    if start is None:
        return f"from the first sample of each recording to {stop:g} s after it"
    return f"from {start:g} s to {stop:g} s after the first sample of each recording"


def with_window(doc: Any) -> Any:
    """``doc`` (a JSON document) with ``"window"`` added when the run used only part of its records."""
    if _WINDOW is None or not isinstance(doc, dict) or "window" in doc:
        return doc
    return {**doc, "window": run_window()}


def print_json(obj: Any) -> None:
    """Print ``obj`` as indented JSON on stdout (with the run's ``--start/--stop`` ``window``, if any).

    Raises
    ------
    InputError
        Stdout already holds the command's data (``--out -``): the two would mix.
    """
    from senscal.io.guard import claim_stdout

    claim_stdout("--json")
    from senscal._result import to_jsonable

    sys.stdout.write(json.dumps(to_jsonable(with_window(obj)), indent=2) + "\n")


def write_json(obj: Any, path: Path | str) -> Path:
    """Write ``obj`` as JSON to ``path`` (folders created; ``-`` is stdout)."""
    from senscal.io.guard import write_text

    from senscal._result import to_jsonable

    path = check_output(path)
    write_text(path, json.dumps(to_jsonable(obj), indent=2) + "\n")  # atomic: no half-written JSON
    return path


@functools.lru_cache(maxsize=None)
def _stacking_table_class() -> type:
    from rich.table import Table
    from rich.text import Text

    class StackingTable(Table):
        """A Rich table that never elides a number.

        Where the table fits the terminal (or pipe: 80 columns) it prints as a
        table; where it does not, each row prints as a block of ``column: value``
        lines under the row's first cell, so every digit stays readable.
        """

        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, **kwargs)
            self._plain_rows: list[list[str]] = []

        def add_plain_row(self, cells: Sequence[str]) -> None:
            self._plain_rows.append([str(c) for c in cells])
            self.add_row(*[Text(c) for c in cells])

        def natural_width(self) -> int:
            """Characters the table needs on one line: cells, padding (2) and borders (1 per column + 1)."""
            heads = [c.header.plain if isinstance(c.header, Text) else str(c.header) for c in self.columns]
            widths = [max([len(h)] + [len(r[i]) for r in self._plain_rows if i < len(r)])
                      for i, h in enumerate(heads)]
            return sum(widths) + 3 * len(widths) + 1

        def __rich_console__(self, console, options):
            if self.natural_width() <= options.max_width or not self._plain_rows:
                yield from super().__rich_console__(console, options)
                return
            heads = [c.header.plain if isinstance(c.header, Text) else str(c.header) for c in self.columns]
            if self.title is not None:
                yield Text(self.title.plain if isinstance(self.title, Text) else str(self.title), style="italic")
            pad = max(len(h) for h in heads[1:]) if len(heads) > 1 else 0
            for row in self._plain_rows:
                yield Text(f"{heads[0]}: {row[0]}" if heads[0] else row[0], style="bold")
                for h, v in zip(heads[1:], row[1:]):
                    yield Text(f"  {h.ljust(pad)}  {v}")

    return StackingTable


def __getattr__(name: str) -> Any:
    # `from senscal.cli.common import StackingTable` still works; Rich is imported only then.
    if name == "StackingTable":
        return _stacking_table_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def table(title: str, columns: Sequence[str], rows: Iterable[Sequence[Any]]) -> Table:
    """A Rich table with right-aligned numeric columns that stacks rather than elide (see StackingTable)."""
    from rich.text import Text

    # Text objects are never parsed as markup, whichever console renders the table.
    tab = _stacking_table_class()(title=Text(str(title)), title_justify="left")
    for i, c in enumerate(columns):
        tab.add_column(Text(str(c)), justify="left" if i == 0 else "right", overflow="fold")
    for r in rows:
        tab.add_plain_row([fmt(v) for v in r])
    return tab


def fmt(v: Any, digits: int = 6) -> str:
    """Format a number for a table (strings pass through)."""
    if v is None:
        return "-"
    if isinstance(v, str):
        return v
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    return f"{f:.{digits}g}"


@contextmanager
def progress_bar(description: str, total: int | None, *, disable: bool = False) -> Iterator[Any]:
    """A Rich progress bar on stderr (so ``--json`` stdout stays clean)."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    con = err_console.real()  # Rich's Live display wants the console itself, not the lazy stand-in
    prog = Progress(TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    console=con, transient=True, disable=disable or not con.is_terminal)
    with prog:
        task = prog.add_task(description, total=total)
        yield lambda n=1: prog.advance(task, n)


def track(items: Sequence[T], description: str) -> Iterator[T]:
    """Iterate with a progress bar on stderr."""
    with progress_bar(description, len(items)) as advance:
        for item in items:
            yield item
            advance()


StrictOpt = Annotated[bool, typer.Option(
    "--strict", help="Exit with code 3 when the data raise a warning (a departure from the method's model).")]


def emit_warnings(warnings: Iterable[str], strict: bool = False) -> None:
    """Print each warning as one line on stderr; with ``strict`` exit 3.

    Warnings are plain text (user strings inside them are never read as Rich
    markup).  Call this after the result has been printed or written, so
    ``--strict`` still leaves the output for inspection.
    """
    from rich.markup import escape

    from senscal.errors import DiagnosticError

    warnings = [str(w) for w in warnings]
    for w in warnings:
        err_console.print(f"[yellow]warning:[/yellow] {escape(w)}", soft_wrap=True, markup=True)
    if strict and warnings:
        more = f" (and {len(warnings) - 1} more)" if len(warnings) > 1 else ""
        raise DiagnosticError(f"--strict: {warnings[0]}{more}")
