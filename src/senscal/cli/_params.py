"""Light conversion of command-line values for the parameter types senscal uses.

Typer (0.2x) converts every parameter value through a pydantic ``TypeAdapter``
that it builds on first use, even for an option left unset: the first
command-line value converted imports pydantic (about 150 ms) and each
parameter builds its own adapter.  A command run then spends more time
starting than a small fit takes.

senscal's parameters are ``bool`` flags, ``int``, ``float``, ``str`` and
``pathlib.Path`` (optional or repeated), with no constraints.  For these the
values a user types have a plain grammar (``12.5``, ``-3``, ``1e3``, ``inf``,
a file name), and Python converts them exactly as pydantic does.  Anything
outside that grammar (spaces, underscores, ``1.0`` for an integer, a string
that is not a number at all) goes to Typer's own converter, so an odd value
is converted, or refused with Typer's message, exactly as before; only the
common case skips pydantic.  ``tests/cli/test_startup.py`` compares the two
over every parameter of every command.

Typer has no public hook to set a parameter's converter; the narrowest
private one is ``_TyperParameter._runtime_param``, which
``get_runtime_param()`` fills lazily when it is ``None``.  :func:`install`
presets it only when that hook exists as expected, so another Typer version
falls back to Typer's own conversion (correct, only slower).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Callable, get_args, get_origin

# The plain grammar each type accepts without pydantic.  ASCII digits only ([0-9], not \d: pydantic refuses
# other Unicode digits that Python's int() and float() accept); no surrounding space (trimmed differently by the
# two); no underscores (pydantic's rules for them differ between int and float).  Lengths are capped far above
# any real value so no parser corner (pydantic's 4300-digit limit, huge exponents) is reached.
_INT = re.compile(r"[+-]?[0-9]{1,300}")
_FLOAT = re.compile(r"[+-]?(?:[0-9]{1,300}\.?[0-9]{0,300}|\.[0-9]{1,300})(?:[eE][+-]?[0-9]{1,4})?")
_FLOAT_WORD = re.compile(r"[+-]?inf(?:inity)?|nan", re.IGNORECASE)

# Path flags the light converter reproduces (Typer's defaults: any path, existing or not, readable if it exists).
_PATH_DEFAULTS = {"exists": False, "file_okay": True, "dir_okay": True, "writable": False, "readable": True,
                  "resolve_path": False, "allow_dash": False, "path_type": None}


class _Undecided(Exception):
    """The value is outside the plain grammar: Typer's own converter decides."""


# Defaults arrive as Python values, not strings (``harmonics: int = 1``, ``fs: float = 1000.0``).
_EXACT_FLOAT_INT = 2**53


def _to_int(value: Any) -> int:
    if type(value) is int:
        return value
    if isinstance(value, str) and _INT.fullmatch(value):
        return int(value)
    raise _Undecided


def _to_float(value: Any) -> float:
    if type(value) is float:
        return value
    if type(value) is int and abs(value) <= _EXACT_FLOAT_INT:
        return float(value)
    if isinstance(value, str) and (_FLOAT.fullmatch(value) or _FLOAT_WORD.fullmatch(value)):
        return float(value)
    raise _Undecided


def _to_str(value: Any) -> str:
    if isinstance(value, str):
        return value
    raise _Undecided


def _to_bool(value: Any) -> bool:
    # Flags arrive as bools; a string (an environment variable) has Typer's yes/no/on/off grammar.
    if isinstance(value, bool):
        return value
    raise _Undecided


def _to_path(value: Any) -> Path:
    if isinstance(value, Path):
        path = value  # a default given as a Path is kept as it is, as Typer does
    elif isinstance(value, str):
        path = Path(value)
    else:
        raise _Undecided
    try:
        os.stat(path)
    except OSError:
        return path  # a path that does not exist (yet) is accepted as it is
    except ValueError:
        raise _Undecided from None  # e.g. an embedded NUL: Typer's own handling
    if not os.access(path, os.R_OK):
        raise _Undecided  # Typer refuses an unreadable path with its own message
    return path


_LEAVES: dict[Any, Callable[[Any], Any]] = {int: _to_int, float: _to_float, str: _to_str, bool: _to_bool,
                                            Path: _to_path}


def _leaf_converter(annotation: Any, info: Any) -> Callable[[Any], Any] | None:
    """The light converter of one (non-list) annotation, or None when Typer must convert it."""
    conv = _LEAVES.get(annotation)
    if conv is None or getattr(info, "parser", None) is not None:
        return None
    if getattr(info, "min", None) is not None or getattr(info, "max", None) is not None:
        return None
    if annotation is Path and any(getattr(info, k, object()) != v for k, v in _PATH_DEFAULTS.items()):
        return None
    return conv


def converter_for(param: Any) -> Callable[[Any], Any] | None:
    """The light converter of a Typer parameter, or None when its type is not one senscal's grammar covers.

    Parameters
    ----------
    param
        A Typer parameter (``typer.core.TyperOption`` / ``TyperArgument``).

    Returns
    -------
    callable or None
        Maps a value Click collected (a string, a bool for a flag, a tuple
        for a repeated option) to the converted value; raises
        ``_Undecided`` for a value outside the plain grammar.
    """
    desc = getattr(param, "type_descriptor", None)
    if desc is None or getattr(desc, "file_annotation", None) is not None:
        return None
    annotation, info = desc.annotation, desc.parameter_info
    if get_origin(annotation) is list:
        (item,) = get_args(annotation)
        leaf = _leaf_converter(item, info)
        if leaf is None:
            return None

        def convert_list(value: Any) -> list:
            if not isinstance(value, (list, tuple)):
                raise _Undecided
            return [leaf(v) for v in value]

        return convert_list
    if get_origin(annotation) is not None:
        return None
    return _leaf_converter(annotation, info)


class LightRuntimeParam:
    """Stands in for Typer's ``RuntimeParam``: plain values here, everything else through Typer's.

    Parameters
    ----------
    convert
        From :func:`converter_for`.
    descriptor
        The parameter's ``type_descriptor``, for the fallback.
    build_fallback
        ``typer._coercion.build_runtime_param``.
    """

    def __init__(self, convert: Callable[[Any], Any], descriptor: Any, build_fallback: Callable[[Any], Any]):
        self.convert, self.descriptor, self.build_fallback = convert, descriptor, build_fallback
        self._fallback = None

    def fallback(self) -> Any:
        """Typer's own converter of this parameter (built, and pydantic imported, on first need)."""
        if self._fallback is None:
            self._fallback = self.build_fallback(self.descriptor)
        return self._fallback

    def coerce(self, value: Any, param: Any, ctx: Any) -> Any:
        """Convert ``value`` as Typer's ``RuntimeParam.coerce`` does."""
        multi = param.multiple or param.nargs == -1
        if value is None:
            # An option left unset: what Typer returns, without building its adapter.
            return () if multi else None
        if not (multi and isinstance(value, str)):
            try:
                return self.convert(value)
            except _Undecided:
                pass
        return self.fallback().coerce(value, param=param, ctx=ctx)


def _typer_hook() -> Callable[[Any], Any] | None:
    try:
        from typer._coercion import build_runtime_param
    except ImportError:  # pragma: no cover - another Typer layout: its own conversion stays
        return None
    return build_runtime_param


def install(param: Any) -> bool:
    """Preset ``param``'s runtime converter to the light one; True when installed.

    Leaves the parameter alone (Typer converts it, correctly, with pydantic)
    when Typer's private hook is not there as expected, when a converter is
    already set, or when the type is not one :func:`converter_for` covers.
    """
    if getattr(param, "_runtime_param", False) is not None or not callable(getattr(param, "get_runtime_param", None)):
        return False
    build = _typer_hook()
    convert = converter_for(param)
    if build is None or convert is None:
        return False
    param._runtime_param = LightRuntimeParam(convert, param.type_descriptor, build)
    return True


def install_tree(command: Any) -> Any:
    """Install light converters on every parameter of ``command`` and its subcommands (help options too)."""
    for param in getattr(command, "params", ()):
        install(param)
    if not getattr(command.get_help_option, "_senscal_light", False):
        # Click creates the --help option on first use; convert it lightly too (the root's is converted on
        # every call, `senscal fit --help` included).
        original = command.get_help_option

        def get_help_option(ctx, __original=original):
            option = __original(ctx)
            if option is not None:
                install(option)
            return option

        get_help_option._senscal_light = True  # type: ignore[attr-defined]
        command.get_help_option = get_help_option
    for sub in (getattr(command, "commands", None) or {}).values():
        install_tree(sub)
    return command
