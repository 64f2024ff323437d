"""The ``senscal`` command line.

User errors (:class:`senscal.errors.SenscalError`) become one line on stderr
and exit code 2 (3 for ``--strict`` diagnostics); only bugs give a traceback
(exit code 1).
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from typing import Sequence

import typer

from senscal.cli import _clickcompat as cx
from senscal.cli.app import app, simulate_app
from senscal.errors import SenscalError
from senscal.io.guard import protect_inputs

__all__ = ["app", "simulate_app", "main", "load_commands"]

_loaded = False


def load_commands() -> typer.Typer:
    """Import every ``senscal.cli.cmd_*`` module so its commands register."""
    global _loaded
    if not _loaded:
        for mod in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
            if mod.name.startswith("cmd_"):
                importlib.import_module(f"{__name__}.{mod.name}")
        _loaded = True
    return app


def main(argv: Sequence[str] | None = None) -> None:
    """Entry point of the ``senscal`` console script."""
    command = typer.main.get_command(load_commands())
    try:
        with protect_inputs():
            rv = command.main(args=list(argv) if argv is not None else None, prog_name="senscal",
                              standalone_mode=False)
    except SenscalError as exc:
        print(f"senscal: error: {exc}", file=sys.stderr)
        sys.exit(exc.exit_code)
    except cx.Abort:
        print("senscal: aborted", file=sys.stderr)
        sys.exit(130)
    except cx.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except cx.Exit as exc:
        sys.exit(exc.exit_code)
    except BrokenPipeError:
        sys.exit(0)
    sys.exit(rv if isinstance(rv, int) else 0)
