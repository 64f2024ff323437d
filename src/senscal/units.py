"""Units as quantities: parse, compare and convert with pint (SI prefixes, ``m/s^2``, ``degC``).

Every unit senscal reads (a CSV header ``output [mV]``, an HDF5/TDMS unit
attribute, an option such as ``--output-unit`` or ``--static-sensitivity
"50 mV/(m/s^2)"``) goes through :func:`parse_unit`; jobs convert data where
the physics allows it (``mV`` to ``V``, ``mm`` to ``m``, ``ms`` to ``s``,
``um/s`` to ``m/s``) with :func:`convert` / :func:`factor`, and refuse with
one line where it does not (``V`` against ``m/s^2``).

Spelling rules on top of pint's own (documented in ``docs/formats.md``):

- ``g`` (also ``gn``, ``g0``, ``g_n``) is standard gravity, 9.80665 m/s^2
  exactly, and ``mg`` is milli-g: senscal measures no masses, and a sensor
  file that says ``g`` means standard gravity.  ``gram`` spelled out is a gram.
- ``G`` and ``Gs`` are gauss, ``LSB``/``lsb``/``counts``/``digits`` are counts.
- ``m s-2`` (a signed power after a symbol) is ``m s^-2``; ``m/s²``,
  ``°``, ``°C``, ``℃``, ``µ``/``μ`` prefixes are read as written.
- Angles are dimensionless in pint; senscal still refuses to convert an angle
  into a ratio or a count (``deg`` is not ``%``).

pint is imported on the first use, not at start-up (its registry takes a
third of a second to build).
"""

from __future__ import annotations

import functools
import math
import re
from typing import Any

import numpy as np

from senscal.errors import InputError

__all__ = ["parse_unit", "is_unit", "dimension_of", "same_unit", "compatible", "factor", "convert",
           "parse_quantity", "unit_text", "is_voltage", "STANDARD_GRAVITY"]

#: Standard gravity g_n in m/s^2 (exact, CGPM 1901).
STANDARD_GRAVITY = 9.80665

# Whole-word spellings pint reads otherwise (or not at all); the right side is what pint gets.
_WORDS = {
    "g": "g_n", "gn": "g_n", "g0": "g_n", "g_0": "g_n", "mg": "milli_g_n", "ug": "micro_g_n", "µg": "micro_g_n",
    "μg": "micro_g_n",
    # pint's gauss is the Gaussian-system unit (another dimension than the tesla); a magnetometer's G is 1e-4 T.
    "G": "si_gauss", "Gs": "si_gauss", "gauss": "si_gauss", "mG": "si_milligauss", "mgauss": "si_milligauss",
    "LSB": "count", "lsb": "count", "counts": "count", "digit": "count", "digits": "count",
    "℃": "degC", "°C": "degC", "°F": "degF", "℉": "degF",
    "sec": "s", "secs": "s", "msec": "ms", "usec": "us", "hr": "hour", "hrs": "hour",
    "dps": "deg/s", "rev": "revolution", "revs": "revolution",
}
_WORD = re.compile(r"(?<![\w°µμ])(°[CF]|[A-Za-z_°µμ℃℉][\w°µμ]*)")
# "m s-2", "s-1": a signed integer straight after a symbol is its power.
_POWER = re.compile(r"(?<=[A-Za-z_µμΩ°)])([+-]\d+)\b")
_ANGLE_ROOT = "radian"


@functools.lru_cache(maxsize=1)
def _registry():
    import pint

    reg = pint.UnitRegistry(autoconvert_offset_to_baseunit=True)
    reg.define("milli_g_n = 1e-3 * standard_gravity")
    reg.define("micro_g_n = 1e-6 * standard_gravity")
    reg.define("si_gauss = 1e-4 * tesla")
    reg.define("si_milligauss = 1e-7 * tesla")
    return reg


def _pint_text(text: str) -> str:
    t = " ".join(str(text).split())
    t = _POWER.sub(r"^\1", t)
    return _WORD.sub(lambda m: _WORDS.get(m.group(1), m.group(1)), t)


@functools.lru_cache(maxsize=512)
def _parse(text: str):
    reg = _registry()
    t = text.strip()
    if t in ("", "1", "-"):
        return reg.dimensionless
    try:
        unit = reg.parse_units(_pint_text(t))
    except Exception:  # pint raises UndefinedUnitError, DefinitionSyntaxError, TypeError, AssertionError ...
        return None
    # No unit has a power beyond a few; 'V^999999' would overflow every conversion.
    if any(not (abs(float(p)) <= 16) for p in dict(unit._units).values()):
        return None
    return unit


def parse_unit(text: str | None, *, what: str = "unit"):
    """A pint unit for ``text``, or a one-line :class:`InputError`.

    Parameters
    ----------
    text : str or None
        ``"mV"``, ``"m/s^2"``, ``"m s-2"``, ``"V/(m/s²)"``, ``"g"`` (standard
        gravity), ``"degC"`` ...; ``""``/``None``/``"1"`` is dimensionless.
    what : str
        Names the unit in the message, e.g. ``"the unit of column 'x' in run.csv"``.

    Returns
    -------
    pint.Unit
    """
    unit = _parse(str(text or ""))
    if unit is None:
        raise InputError(f"{what} {text!r} is not a unit senscal knows; write it with SI symbols and prefixes "
                         "(V, mV, m, mm, m/s^2, g, deg, degC, ...)")
    return unit


def is_unit(text: str | None) -> bool:
    """Whether ``text`` parses as a unit (``""`` counts as dimensionless)."""
    return _parse(str(text or "")) is not None


def _angle_power(unit) -> float:
    _, root = _registry().get_root_units(unit)
    return float(dict(root._units).get(_ANGLE_ROOT, 0))


# Dimensions in words for messages (SI base units as the key); others print pint's dimensionality.
_DIM_WORDS = {"V": "a voltage", "m": "a length", "s": "a time", "m/s": "a velocity", "m/s^2": "an acceleration",
              "C": "a charge", "A": "a current", "T": "a magnetic flux density", "Hz": "a frequency",
              "K": "a temperature", "N": "a force", "Pa": "a pressure", "1": "a ratio or count",
              "V/(m/s^2)": "a voltage per acceleration", "V/(m/s)": "a voltage per velocity",
              "V/m": "a voltage per length", "C/(m/s^2)": "a charge per acceleration",
              "1/(m/s^2)": "a count per acceleration", "V/T": "a voltage per flux density"}
_ANGLE_WORDS = {"rad": "an angle", "rad/s": "an angular velocity", "rad/s^2": "an angular acceleration"}


def dimension_of(text: str | None) -> str:
    """The physical dimension of a unit in words: ``"a voltage"``, ``"an acceleration"``, ``"an angle"`` ..."""
    unit = parse_unit(text)
    words = _ANGLE_WORDS if _angle_power(unit) else _DIM_WORDS
    for name, word in words.items():
        ref = _parse(name)
        if ref.dimensionality == unit.dimensionality and _angle_power(ref) == _angle_power(unit):
            return word
    return str(unit.dimensionality)


def compatible(a: str | None, b: str | None) -> bool:
    """Whether data in unit ``a`` can be converted to unit ``b`` (same dimension, angles only into angles)."""
    ua, ub = _parse(str(a or "")), _parse(str(b or ""))
    if ua is None or ub is None:
        return False
    return ua.dimensionality == ub.dimensionality and _angle_power(ua) == _angle_power(ub)


def same_unit(a: str | None, b: str | None) -> bool:
    """Whether two spellings name the same unit, scale included (``m/s²`` == ``m s-2``; ``mV`` != ``V``).

    Text that is not a unit equals only itself (spaces aside).
    """
    ua, ub = _parse(str(a or "")), _parse(str(b or ""))
    if ua is None or ub is None:
        return " ".join(str(a or "").split()) == " ".join(str(b or "").split())
    return compatible(a, b) and math.isclose(_scale(ua, ub), 1.0, rel_tol=1e-12) and _offset(ua, ub) == 0.0


def _scale(ua, ub) -> float:
    reg = _registry()
    f = float(reg.Quantity(1.0, ua).to(ub).magnitude - reg.Quantity(0.0, ua).to(ub).magnitude)
    # pint goes through base units (1e-6 / 1e-9 = 999.9999999999999): 15 digits give the factor as written.
    return float(f"{f:.15g}")


def _offset(ua, ub) -> float:
    return float(_registry().Quantity(0.0, ua).to(ub).magnitude)


def _refuse(have: str, want: str, what: str, fix: str) -> InputError:
    return InputError(f"{what} is in {have!r} ({dimension_of(have)}), which cannot be converted to {want!r} "
                      f"({dimension_of(want)}); {fix}")


def factor(have: str | None, want: str | None, *, what: str = "the data",
           fix: str = "check the unit in the file header or the option") -> float:
    """The number data in ``have`` are multiplied by to be in ``want`` (``factor("mV", "V") == 1e-3``).

    Parameters
    ----------
    have, want : str
        Units; both must parse (:func:`parse_unit`).
    what : str
        Names the data in the refusal.
    fix : str
        What to do, for the refusal.

    Raises
    ------
    InputError
        A unit senscal does not know, another dimension (``V`` against
        ``m/s^2``), or an offset scale (``degC`` against ``K``: use
        :func:`convert` for absolute temperatures).
    """
    ua = parse_unit(have, what=f"the unit of {what}")
    ub = parse_unit(want, what="the unit")
    if not compatible(have, want):
        raise _refuse(str(have), str(want), what, fix)
    off = _offset(ua, ub)
    if off != 0.0:
        raise InputError(f"{what} is in {have!r}, which differs from {want!r} by an offset, not a factor; "
                         "give temperature differences in K")
    return _scale(ua, ub)


def convert(values: Any, have: str | None, want: str | None, *, what: str = "the data",
            fix: str = "check the unit in the file header or the option") -> np.ndarray:
    """``values`` (array or scalar) in ``have`` converted to ``want``; offsets (``degC`` to ``K``) included.

    Returns the input unchanged (as a float array) when the units are the same.
    Raises :class:`InputError` as :func:`factor` does.
    """
    arr = np.asarray(values, dtype=float)
    ua = parse_unit(have, what=f"the unit of {what}")
    ub = parse_unit(want, what="the unit")
    if not compatible(have, want):
        raise _refuse(str(have), str(want), what, fix)
    if ua == ub:
        return arr
    with np.errstate(over="ignore"):  # beyond float range becomes inf, which the callers refuse
        return np.asarray(_registry().Quantity(arr, ua).to(ub).magnitude, dtype=float)


_QTY = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$")


def parse_quantity(text: str | float | None, unit: str, *, option: str) -> float | None:
    """An option's value in ``unit``: a bare number is in ``unit``; ``"50 mV/(m/s^2)"`` is converted to it.

    Parameters
    ----------
    text : str, float or None
        What the user gave (None passes through).
    unit : str
        The unit the job works in (and in which a bare number is read).
    option : str
        The option's name for messages (``--static-sensitivity``).

    Raises
    ------
    InputError
        Not a number, an unknown unit, or a unit of another dimension.
    """
    if text is None:
        return None
    if isinstance(text, (int, float, np.integer, np.floating)) and not isinstance(text, bool):
        if not math.isfinite(float(text)):
            raise InputError(f"{option} must be a finite number in {unit}, got {text!r}")
        return float(text)
    m = _QTY.match(str(text))
    if m is not None and m.group(2)[:1] in (",", "."):
        raise InputError(f"{option} {text!r} has a decimal comma or a stray mark; write the number with a decimal "
                         f"point, e.g. 0.05 or '0.05 {unit}'")
    if m is None:
        raise InputError(f"{option} must be a number, optionally with a unit (e.g. 0.05 or '0.05 {unit}'), "
                         f"got {text!r}")
    value, given = float(m.group(1)), m.group(2)
    if given.startswith("/"):
        given = "1" + given  # '1e-4 /h', '2/day': a rate per unit of time
    if given:
        fix = f"give {option} in {unit} or a unit convertible to it"
        ua = parse_unit(given, what=f"the unit of {option} {text}")
        if compatible(given, unit) and _offset(ua, parse_unit(unit)) == 0.0:
            with np.errstate(over="ignore"):
                value = value * _scale(ua, parse_unit(unit))  # the factor as written: '50 uT' is 50000 nT exactly
        else:
            value = float(convert(value, given, unit, what=f"{option} {text}", fix=fix))  # offsets, or the refusal
    if not math.isfinite(value):
        raise InputError(f"{option} {text} is beyond the range of a float ({value} {unit}); give a finite value")
    return value


def unit_text(text: str | None) -> str:
    """A unit as senscal prints it: the user's spelling with spaces tidied (``""`` for none)."""
    return " ".join(str(text or "").split())


def is_voltage(text: str | None) -> bool:
    """Whether ``text`` is a unit of electric potential (``V``, ``mV``, ``uV`` ...)."""
    return bool(text) and compatible(text, "V")
