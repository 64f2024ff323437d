"""The ``senscal`` command line.

User errors (:class:`senscal.errors.SenscalError`) become one line on stderr
and exit code 2 (3 for ``--strict`` diagnostics).  Anything else is a bug:
the safety net in :func:`main` prints one line asking for a report and exits
1; ``--debug`` (or ``SENSCAL_DEBUG=1``) shows the traceback instead.
"""

from __future__ import annotations

import functools
import importlib
import math
import os
import sys
import warnings
from typing import Sequence

import typer

from senscal.cli import _clickcompat as cx
from senscal.cli._help import plain_help
from senscal.cli._params import install_tree
from senscal.cli.app import app, simulate_app
from senscal.errors import InputError, SenscalError
from senscal.io.guard import allow_new_folders, protect_inputs

__all__ = ["app", "simulate_app", "main", "load_commands", "debug_enabled"]

_loaded = False
_debug_flag = False
_command = None


def load_commands() -> typer.Typer:
    """Import every ``senscal.cli.cmd_*`` module so its commands register."""
    global _loaded
    if not _loaded:
        import pkgutil  # only here: every other run loads one command's module by name

        for mod in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
            if mod.name.startswith("cmd_"):
                importlib.import_module(f"{__name__}.{mod.name}")
        _loaded = True
    return app


def _print_version(value: bool) -> None:
    if value:
        from senscal import __version__

        print(f"senscal {__version__}")
        raise typer.Exit()


@app.callback()
def _root(debug: bool = typer.Option(False, "--debug", help="Show the Python traceback of an internal error "
                                                             "(also SENSCAL_DEBUG=1)."),
          version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                       help="Print senscal's version and exit."),
          mkdir: bool = typer.Option(False, "--mkdir", help="Create missing folders of the outputs (without it a "
                                                            "missing folder is refused: a typo would grow a new "
                                                            "tree).")) -> None:
    """Calibrate sensors and correct their errors."""
    global _debug_flag
    _debug_flag = _debug_flag or debug


# The simulators allocate whole records in memory and write them as text (~20 bytes a value): beyond this many
# samples per channel (0.8 GB of float64, several GB of CSV) a request is a typo, not a simulation.
MAX_SIMULATED_SAMPLES = 100_000_000
# Sizes given as counts (readings, poses, records, samples) share the limit.
_COUNT_OPTIONS = ("n", "samples", "records", "readings", "poses", "points", "n_points")


def check_common_options(command_path: str, kw: dict) -> None:
    """Checks every command shares, applied once here instead of in each command.

    ``--seed`` must be a non-negative integer (numpy's generators refuse
    others deep inside a simulator); for ``simulate`` commands the sample
    rate and durations must be positive and finite, and the record they
    describe at most :data:`MAX_SIMULATED_SAMPLES` samples.

    Raises
    ------
    InputError
        Naming the option and the fix.
    """
    seed = kw.get("seed")
    if seed is not None and not isinstance(seed, bool) and isinstance(seed, int) and not 0 <= seed < 2**63:
        raise InputError(f"--seed must be a whole number from 0 to 2^63-1, got {seed}")
    check_counts(command_path, kw)
    if " simulate " not in f" {command_path} ":
        return
    for name in ("fs", *(k for k in kw if k == "duration" or k.endswith("_duration"))):
        v = kw.get(name)
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise InputError(f"--{name.replace('_', '-')} must be a positive, finite number, got {v!r}")
    fs = kw.get("fs")
    for name in (k for k in kw if k == "duration" or k.endswith("_duration")):
        if fs is not None and kw[name] is not None and fs * kw[name] > MAX_SIMULATED_SAMPLES:
            raise InputError(f"--fs {fs:g} Hz over --{name.replace('_', '-')} {kw[name]:g} s is "
                             f"{fs * kw[name]:.3g} samples per channel; the simulators write at most "
                             f"{MAX_SIMULATED_SAMPLES:.0e}: shorten the record or lower the rate")
    for name in _COUNT_OPTIONS:
        v = kw.get(name)
        if isinstance(v, int) and not isinstance(v, bool) and v > MAX_SIMULATED_SAMPLES:
            raise InputError(f"--{name.replace('_', '-')} {v} is more than the simulators write "
                             f"({MAX_SIMULATED_SAMPLES:.0e}); ask for fewer")


def check_counts(command_path: str, kw: dict) -> None:
    """Bound every whole-number option by what this machine can hold (see :mod:`senscal.cli._limits`).

    ``--workers`` is bounded by cores and memory; every other count (channels,
    samples, harmonics, chunk sizes, ...) by the float64 values memory holds,
    and for a simulator the channels times the samples of each.

    Raises
    ------
    InputError
        Naming the option, the machine and the largest value accepted.
    """
    from senscal.cli import _limits

    counts = {k: v for k, v in kw.items()
              if isinstance(v, int) and not isinstance(v, bool) and k != "seed"}
    if not counts:
        return
    workers = counts.pop("workers", None)
    if workers is not None and workers > _limits.max_workers():
        raise InputError(f"--workers {workers} is more than this machine runs ({_limits.describe()}: at most "
                         f"{_limits.max_workers()} worker processes); ask for fewer")
    for name, v in counts.items():
        if v > _limits.max_values():
            raise InputError(f"--{name.replace('_', '-')} {v} is more than fits in this machine's memory "
                             f"({_limits.describe()}); ask for fewer")
    if " simulate " in f" {command_path} ":
        per_channel = next((kw[k] for k in ("samples", "n") if isinstance(kw.get(k), int)), None)
        fs, duration = kw.get("fs"), kw.get("duration")
        if per_channel is None and isinstance(fs, (int, float)) and isinstance(duration, (int, float)) \
                and math.isfinite(fs * duration):
            per_channel = int(fs * duration)
        chans = kw.get("channels")
        if isinstance(chans, int) and not isinstance(chans, bool) and per_channel is not None \
                and chans * per_channel > _limits.max_values():
            raise InputError(f"--channels {chans} of {per_channel} samples each is more than fits in this "
                             f"machine's memory ({_limits.describe()}: at most {_limits.max_values():.3g} values); "
                             "ask for fewer channels or samples")


def _with_common_checks(group, path: str = "senscal"):
    """Wrap every command's callback in :func:`check_common_options` (once, when the tree is built)."""
    for name, cmd in getattr(group, "commands", {}).items():
        sub = f"{path} {name}"
        if getattr(cmd, "commands", None):
            _with_common_checks(cmd, sub)
        elif cmd.callback is not None and not getattr(cmd.callback, "_senscal_checked", False):
            def checked(*args, __f=cmd.callback, __p=sub, **kw):
                from senscal.cli._quantities import convert_options
                from senscal.cli.common import check_command_outputs, set_window

                kw = convert_options(__f, kw)  # '80 mm' -> 0.08 for --radius in m (senscal.cli._quantities)
                set_window(kw.get("start"), kw.get("stop"))  # recorded in --json, --save and the certificate
                check_common_options(__p, kw)
                check_command_outputs(__p, kw)  # every output, before any work (see senscal.io.guard)
                return __f(*args, **kw)

            functools.update_wrapper(checked, cmd.callback)
            checked._senscal_checked = True  # type: ignore[attr-defined]
            cmd.callback = checked
            _say_units(cmd)
    return group


def _say_units(cmd) -> None:
    """Each quantity option's help says that a unit may be given (see senscal.cli._quantities)."""
    from senscal.cli._quantities import ListOf, option_units

    table = option_units(cmd.callback, {p.name: None for p in cmd.params})
    for p in cmd.params:
        unit = table.get(p.name)
        if unit is None:
            continue
        if isinstance(unit, ListOf):
            unit, p.metavar = unit.unit, p.metavar or "<qty,...>"
        else:
            p.metavar = p.metavar or "<qty>"
        if "with a unit" not in (p.help or ""):
            p.help = f"{(p.help or '').rstrip()} [number in {unit}, or with a unit]"


class _LazyGroup:
    """Behaviour bound onto a built Typer group so its commands load on first use.

    ``senscal --help`` lists the commands from :mod:`senscal.cli._manifest_data`
    without importing them; ``senscal NAME ...`` imports only NAME's module
    (numba, scipy.stats and dask stay unloaded for a registry command).
    """

    def __init__(self, group, table: dict, path: tuple):
        self.group, self.table, self.path, self.listing = group, table, path, False
        self._format_help = group.format_help
        group.list_commands = self.list_commands
        group.get_command = self.get_command
        group.format_help = self.format_help

    def list_commands(self, ctx):
        names = list(self.table)
        return names + [n for n in self.group.commands if n not in self.table]

    def get_command(self, ctx, cmd_name):
        cmd = self.group.commands.get(cmd_name)
        if cmd is not None:
            return cmd
        entry = self.table.get(cmd_name)
        if entry is None:
            return None
        module, short_help = entry
        if self.listing:
            # Listing for --help: a stand-in with the manifest's help, nothing imported.
            return typer.core.TyperCommand(cmd_name, help=short_help, short_help=short_help)
        importlib.import_module(f"{__name__}.{module}")
        node = typer.main.get_command(app)
        for part in self.path:
            node = node.commands[part]
        cmd = node.commands.get(cmd_name)
        if cmd is None:
            return None
        _prepare(cmd)
        _with_common_checks(_Holder({cmd_name: cmd}), " ".join(("senscal", *self.path)))
        self.group.commands[cmd_name] = cmd
        return cmd

    def format_help(self, ctx, formatter):
        self.listing = True
        try:
            return self._format_help(ctx, formatter)
        finally:
            self.listing = False


def _prepare(command):
    """Plain help and light parameter conversion for ``command`` and its subcommands (see _help, _params)."""
    return install_tree(plain_help(command))


class _Holder:
    def __init__(self, commands):
        self.commands = commands


def _lazy_root():
    """The root Click group with every command (and simulator) loaded on first use."""
    from senscal.cli._manifest_data import COMMANDS, SIMULATORS

    root = typer.main.get_command(app)
    # A command module already imported (tests, batch workers) is simply found in the table too.
    root.commands = {n: c for n, c in root.commands.items() if n == "simulate"}
    sim = root.commands["simulate"]
    sim.commands = {}
    _LazyGroup(sim, SIMULATORS, ("simulate",))
    _LazyGroup(root, {**COMMANDS, "simulate": ("", "")}, ())
    return _prepare(root)


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
        # The root group loads a command's module only when that command runs (see _LazyGroup); it is
        # the same for every call (in-process test runners, batch workers), so it is built once.
        _command = _lazy_root()
    command = _command
    args = list(argv) if argv is not None else sys.argv[1:]
    if "--debug" in args[1:args.index("--") if "--" in args else len(args)]:
        # Accepted after the command too ("senscal fit x.csv --debug"), where users type it on a rerun.
        args.remove("--debug")
        _debug_flag = True
    mkdir = "--mkdir" in args[:args.index("--") if "--" in args else len(args)]
    if mkdir:
        args.remove("--mkdir")  # accepted anywhere, like --debug
    saved_showwarning = warnings.showwarning
    warnings.showwarning = _show_warning
    # Library log records (nptdms prints "[nptdms.reader WARNING] ..." with its own handler for a damaged
    # file) would break the one-line promise like library warnings do; --debug lets them through.
    import logging

    saved_disable = logging.root.manager.disable
    if not debug_enabled():
        logging.disable(logging.CRITICAL)
    try:
        with protect_inputs():
            allow_new_folders(mkdir)
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
        ctx = getattr(exc, "ctx", None)
        if type(exc).__name__ == "NoArgsIsHelpError" and ctx is not None:
            # `senscal` or `senscal registry` alone: the help is what the user wants to see, then one line.
            print(exc.format_message())
            _fail(f"error: missing command; see '{ctx.command_path} --help'", exc.exit_code)
        # Click prints usage + a boxed message over several lines; one line says the same.
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
    except ValueError as exc:
        if debug_enabled():
            raise
        if "Maximum allowed size exceeded" in str(exc):
            # numpy's words for an array whose size overflows: the same as running out of memory.
            _fail("error: the options ask for an array too large to allocate (check sizes, durations, "
                  "frequencies and sample rates)", 2)
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
        logging.disable(saved_disable)
    sys.exit(rv if isinstance(rv, int) else 0)
