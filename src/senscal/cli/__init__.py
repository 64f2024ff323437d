"""The ``senscal`` command line.

User errors (:class:`senscal.errors.SenscalError`) become one line on stderr
and exit code 2 (3 for ``--strict`` diagnostics).  Anything else is a bug:
the safety net in :func:`main` prints one line asking for a report and exits
1; ``--debug`` (or ``SENSCAL_DEBUG=1``) shows the traceback instead.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys
import warnings
from typing import Sequence

import typer

from senscal.cli import _clickcompat as cx
from senscal.cli.app import app, simulate_app
from senscal.errors import SenscalError
from senscal.io.guard import protect_inputs

__all__ = ["app", "simulate_app", "main", "load_commands", "debug_enabled"]

_loaded = False
_debug_flag = False
_command = None


def load_commands() -> typer.Typer:
    """Import every ``senscal.cli.cmd_*`` module so its commands register."""
    global _loaded
    if not _loaded:
        for mod in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
            if mod.name.startswith("cmd_"):
                importlib.import_module(f"{__name__}.{mod.name}")
        _loaded = True
    return app


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show the Python traceback of an internal error "
                                                             "(also SENSCAL_DEBUG=1).")) -> None:
    """Calibrate sensors and correct their errors."""
    global _debug_flag
    _debug_flag = _debug_flag or debug


def debug_enabled() -> bool:
    """True when ``--debug`` was given or ``SENSCAL_DEBUG`` is set to a true value."""
    return _debug_flag or os.environ.get("SENSCAL_DEBUG", "").strip().lower() in ("1", "true", "yes", "on")


def _one_line(text: object, limit: int = 400) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    # Library warnings (numpy overflow, pandas dtype notes) are not actionable for a command-line user and
    # would break the one-line promise; senscal's own diagnostics are named warnings.  --debug shows them.
    if debug_enabled():
        print(f"senscal: debug: {category.__name__}: {_one_line(message)} ({filename}:{lineno})", file=sys.stderr)


def _fail(text: str, code: int) -> None:
    print(f"senscal: {_one_line(text)}", file=sys.stderr)
    sys.exit(code)


def main(argv: Sequence[str] | None = None) -> None:
    """Entry point of the ``senscal`` console script.

    Exit codes: 0 success, 2 user error (bad input, unreadable or unwritable
    file), 3 ``--strict`` diagnostic, 1 internal error (a bug), 130 interrupted.
    """
    global _debug_flag, _command
    _debug_flag = False
    if _command is None:
        # Building the Click tree from the Typer signatures costs ~0.5-2 s; it is the same for every call
        # (in-process test runners, batch workers), so build it once.
        _command = typer.main.get_command(load_commands())
    command = _command
    from senscal.cli.common import err_console

    # Messages stay one line when stderr is a file or pipe (Rich would wrap them at 80 columns).
    err_console.soft_wrap = True
    args = list(argv) if argv is not None else sys.argv[1:]
    if "--debug" in args[1:args.index("--") if "--" in args else len(args)]:
        # Accepted after the command too ("senscal fit x.csv --debug"), where users type it on a rerun.
        args.remove("--debug")
        _debug_flag = True
    saved_showwarning = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        with protect_inputs():
            rv = command.main(args=args, prog_name="senscal",
                              standalone_mode=False)
    except SenscalError as exc:
        _fail(f"error: {exc}", exc.exit_code)
    except cx.Abort:
        _fail("aborted", 130)
    except KeyboardInterrupt:
        _fail("interrupted", 130)
    except cx.Exit as exc:
        sys.exit(exc.exit_code)
    except cx.ClickException as exc:
        # Click prints usage + a boxed message over several lines; one line says the same.
        ctx = getattr(exc, "ctx", None)
        hint = f"; see '{ctx.command_path} --help'" if ctx is not None else ""
        _fail(f"error: {exc.format_message().rstrip('.')}{hint}", exc.exit_code)
    except BrokenPipeError:
        sys.exit(0)
    except RecursionError as exc:
        if debug_enabled():
            raise
        _fail(f"internal error (RecursionError: {exc}); please report it; rerun with --debug for the traceback", 1)
    except MemoryError:
        if debug_enabled():
            raise
        _fail("error: out of memory; the input or the options ask for more data than fits "
              "(check sizes, durations and sample rates)", 2)
    except OSError as exc:
        if debug_enabled():
            raise
        if exc.filename is not None:
            # An OS failure on a path the user named (unreadable input, full disk, permission): a user problem.
            where = exc.filename if exc.filename2 is None else f"{exc.filename} -> {exc.filename2}"
            reason = (exc.strerror or type(exc).__name__).rstrip(".").lower()
            _fail(f"error: {where}: {reason}", 2)
        _fail(f"internal error ({type(exc).__name__}: {exc}); please report it; rerun with --debug for the "
              "traceback", 1)
    except Exception as exc:
        # The last line of defence, not the fix: every user mistake should already be a SenscalError.
        if debug_enabled():
            raise
        _fail(f"internal error ({type(exc).__name__}: {exc}); please report it; rerun with --debug for the "
              "traceback", 1)
    finally:
        warnings.showwarning = saved_showwarning
    sys.exit(rv if isinstance(rv, int) else 0)
