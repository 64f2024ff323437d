"""Options with a physical dimension take quantities: a bare number in the documented unit, or ``'80 mm'``.

A command names its dimensioned options with :func:`units`::

    @app.command("compensate")
    @units(radius="m", window="s")
    def compensate_cmd(..., radius: Annotated[str, typer.Option("--radius", ...)], ...)

The option is declared as text (Click must accept ``80 mm``); before the
command runs (``senscal.cli._with_common_checks``, and ``senscal batch`` for
its job options) :func:`convert_options` replaces the text with a number in
the documented unit: ``80 mm`` -> 0.08 for ``--radius`` in m; a bare ``0.08``
stays 0.08 m.  A unit of another dimension (``--radius '80 V'``) is one line
on stderr and exit 2 (an :class:`~senscal.errors.InputError`).  The command
body then sees exactly what it saw when the option was a float.

Options every reading command shares are in :data:`COMMON`: ``--fs`` in Hz,
``--start``/``--stop`` in s.  A comma-separated list (``--input-amplitudes
'1 g,2 g,5 g'``, ``--taus``) is :class:`ListOf` a unit and reaches the
command as the same list of bare numbers in that unit.  Within one list the
unit is given on every value or on none: ``'10,20,50 g'`` would otherwise
read 10 and 20 in the default unit, silently.

pint is imported only when a value carries a unit (``senscal.units``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping

from senscal.errors import InputError

__all__ = ["ListOf", "units", "convert_options", "option_units", "COMMON"]


@dataclass(frozen=True)
class ListOf:
    """A comma-separated (or repeated) option of quantities in ``unit``."""

    unit: str


#: Parameters with the same meaning in every command that has them.
COMMON: dict[str, str | ListOf] = {"fs": "Hz", "start": "s", "stop": "s"}

_ATTR = "_senscal_units"


def units(**spec: str | ListOf) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Mark a command's parameters as quantities: ``@units(radius="m", input_amplitudes=ListOf("m/s^2"))``.

    The function is returned unchanged (the table is an attribute that
    ``functools.update_wrapper`` carries to Typer's and senscal's wrappers).
    """
    def mark(func: Callable[..., Any]) -> Callable[..., Any]:
        setattr(func, _ATTR, {**getattr(func, _ATTR, {}), **spec})
        return func

    return mark


def option_units(callback: Callable[..., Any] | None, params: Mapping[str, Any]) -> dict[str, str | ListOf]:
    """The quantity parameters of a command: its own table and the :data:`COMMON` names it has."""
    own = dict(getattr(callback, _ATTR, {}) or {})
    return {**{k: v for k, v in COMMON.items() if k in params}, **own}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _one(text: Any, unit: str, option: str) -> float | None:
    # A bare number is read exactly as the float option read it before ('1_000', ' 2', 'inf': the command's own
    # checks name what is wrong with it); only text with a unit goes to pint.
    try:
        return float(text)
    except (TypeError, ValueError):
        pass
    from senscal.units import _QTY, parse_quantity

    if _QTY.match(str(text)) is None:
        # Not even a number first: the message of any other invalid option value, with this option's unit.
        raise InputError(f"invalid value for '{option}': {str(text)!r} is not a number (in {unit}) or a quantity "
                         f"such as '2.5 {unit}'")
    return parse_quantity(text, unit, option=option)


def _list(value: Any, unit: str, option: str) -> str | list[str] | None:
    """Each comma-separated item converted; the unit on every item or on none."""
    if value is None:
        return None
    as_list = isinstance(value, (list, tuple))
    texts = [str(v) for v in value] if as_list else [str(value)]
    out = []
    for text in texts:
        items = [s.strip() for s in text.split(",")]
        bare = [_is_number(s) for s in items if s]
        if any(bare) and not all(bare):
            raise InputError(f"{option} {text!r} gives a unit on some values only; give it on every value "
                             f"('10 g,20 g') or on none (then they are in {unit})")
        nums = [_one(s, unit, option) for s in items if s]
        out.append(",".join(repr(v) for v in nums))
    return out if as_list else out[0]


def convert_options(callback: Callable[..., Any] | None, params: dict[str, Any]) -> dict[str, Any]:
    """``params`` with every quantity option of ``callback`` as a bare number (or list) in its unit.

    None passes through; a bare number (text or not) is read as Python's
    ``float`` reads it, as the option did when it was declared a float.

    Raises
    ------
    InputError
        Not a number, an unknown unit, or a unit of another dimension (one line naming the option).
    """
    table = option_units(callback, params)
    if not table:
        return params
    out = dict(params)
    for name, unit in table.items():
        value = out.get(name)
        if value is None or isinstance(value, bool):
            continue
        if isinstance(unit, ListOf):
            out[name] = _list(value, unit.unit, _flag(name))
        elif isinstance(value, str) or isinstance(value, (int, float)):
            out[name] = _one(value, unit, _flag(name))
    return out
