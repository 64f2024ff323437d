"""Units compared as units: ``m/s²`` == ``m/s^2`` == ``m s-2``, ``deg`` == ``°``.

A saved calibration remembers the unit of the data it was made from; the
data it is later applied to must be in the same unit.  Comparing the
strings would refuse ``m/s²`` against ``m/s^2`` (the same unit) while a
conversion library would silently accept ``g`` for ``m/s^2`` (a factor
9.81 away).  This module does neither: it parses a unit into symbols with
integer powers, maps the spellings of one symbol onto one name through the
explicit table :data:`SYMBOL_ALIASES`, and calls two units equal when those
agree.  Scale never converts: ``mV`` is not ``V`` and ``g`` is not
``m/s^2``, so data in another scale are refused with a message that says to
convert them.
"""

from __future__ import annotations

import re
from typing import Mapping

from senscal.errors import InputError

__all__ = ["SYMBOL_ALIASES", "parse_unit", "canonical_unit", "same_unit", "check_unit", "numerator"]

#: Spellings of one unit symbol -> the name it is compared by.  Only
#: spellings of the *same* unit belong here (no conversions).
SYMBOL_ALIASES: Mapping[str, str] = {
    "°": "deg", "deg": "deg", "degree": "deg", "degrees": "deg", "degs": "deg",
    "rad": "rad", "radian": "rad", "radians": "rad",
    "s": "s", "sec": "s", "second": "s", "seconds": "s",
    "ms": "ms", "msec": "ms",
    "us": "us", "µs": "us", "μs": "us", "usec": "us",
    "min": "min", "minute": "min", "minutes": "min",
    "h": "h", "hr": "h", "hour": "h", "hours": "h",
    "Hz": "Hz", "hz": "Hz",
    "m": "m", "meter": "m", "metre": "m", "meters": "m", "metres": "m",
    "mm": "mm", "um": "um", "µm": "um", "μm": "um",
    "V": "V", "volt": "V", "volts": "V", "mV": "mV", "uV": "uV", "µV": "uV", "μV": "uV",
    "T": "T", "tesla": "T", "mT": "mT", "uT": "uT", "µT": "uT", "μT": "uT", "nT": "nT",
    "G": "gauss", "gauss": "gauss", "Gs": "gauss", "mG": "mgauss", "mgauss": "mgauss",
    "g": "g_n", "gn": "g_n", "g_n": "g_n",  # standard gravity as a unit (not gram)
    "A": "A", "mA": "mA", "pC": "pC", "C": "C",
    "Ohm": "Ohm", "ohm": "Ohm", "Ω": "Ohm",
    "N": "N", "Pa": "Pa", "K": "K", "°C": "degC", "degC": "degC", "℃": "degC",
    "count": "count", "counts": "count", "LSB": "count", "lsb": "count",
    "rpm": "rpm", "%": "%",
}

_SUPERSCRIPT = str.maketrans({"⁰": "0", "¹": "1", "²": "2", "³": "3", "⁴": "4", "⁵": "5", "⁶": "6", "⁷": "7",
                              "⁸": "8", "⁹": "9", "⁻": "-", "⁺": "+"})
_SUPERSCRIPT_RUN = re.compile(r"([⁻⁺]?[⁰¹²³⁴⁵⁶⁷⁸⁹]+)")
_TOKEN = re.compile(r"\s*(?:(?P<sym>°[CF]|[A-Za-z_°µμΩ℃%]+)|(?P<op>\*\*|[*/.·^()])|"
                    r"(?P<num>[+-]?\d+))")


def _tokens(text: str) -> list[tuple[str, str]]:
    # "m/s²" -> "m/s^2"; a superscript run is always a power of the symbol before it.
    text = _SUPERSCRIPT_RUN.sub(lambda m: "^" + m.group(1).translate(_SUPERSCRIPT), text.strip())
    out, pos = [], 0
    while pos < len(text):
        if text[pos:].strip() == "":
            break
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise ValueError(text)
        kind = m.lastgroup or ""
        out.append((kind, m.group(kind)))
        pos = m.end()
    return out


def parse_unit(text: str) -> dict[str, int]:
    """Parse a unit into ``{symbol: power}`` with the symbols' canonical names.

    Parameters
    ----------
    text : str
        ``"m/s^2"``, ``"m s-2"``, ``"m/s²"``, ``"m*s**-2"``, ``"V/(m/s^2)"``,
        ``"°"`` ...; juxtaposition, ``*``, ``.`` and ``·`` multiply, ``/``
        divides the factor after it, ``^``/``**`` or a bare signed integer
        after a symbol is its power.

    Returns
    -------
    dict
        Canonical symbol -> integer power, zero powers dropped (``{}`` for
        a dimensionless ``"1"`` or ``""``).

    Raises
    ------
    ValueError
        The text is not a unit expression of that form.
    """
    toks = _tokens(text)
    pos = 0

    def peek() -> tuple[str, str] | None:
        return toks[pos] if pos < len(toks) else None

    def power() -> int:
        nonlocal pos
        t = peek()
        if t is not None and t[0] == "op" and t[1] in ("^", "**"):
            pos += 1
            t = peek()
            if t is None or t[0] != "num":
                raise ValueError(text)
        if t is not None and t[0] == "num":
            pos += 1
            return int(t[1])
        return 1

    def factor() -> dict[str, int]:
        nonlocal pos
        t = peek()
        if t is None:
            raise ValueError(text)
        pos += 1
        if t == ("op", "("):
            inner = product()
            if peek() != ("op", ")"):
                raise ValueError(text)
            pos += 1
            base = inner
        elif t[0] == "sym":
            base = {SYMBOL_ALIASES.get(t[1], t[1]): 1}
        elif t == ("num", "1"):
            base = {}
        else:
            raise ValueError(text)
        p = power()
        return {k: v * p for k, v in base.items()}

    def product() -> dict[str, int]:
        nonlocal pos
        acc = factor()
        while True:
            t = peek()
            if t is None or t == ("op", ")"):
                return acc
            sign = 1
            if t[0] == "op" and t[1] in ("*", ".", "·", "/"):
                sign = -1 if t[1] == "/" else 1
                pos += 1
            for k, v in factor().items():
                acc[k] = acc.get(k, 0) + sign * v

    if not toks:
        return {}
    result = product()
    if pos != len(toks):
        raise ValueError(text)
    return {k: v for k, v in sorted(result.items()) if v != 0}


def canonical_unit(text: str | None) -> str:
    """A unit written one way: ``"m/s²"`` and ``"m s-2"`` both give ``"m s^-2"``.

    Text that is not a unit expression comes back stripped, so it still
    compares equal to itself.
    """
    if text is None:
        return ""
    whole = SYMBOL_ALIASES.get(text.strip())
    if whole is not None:
        return whole
    try:
        parts = parse_unit(text)
    except ValueError:
        return " ".join(text.split())
    return " ".join(k if v == 1 else f"{k}^{v}" for k, v in parts.items())


def same_unit(a: str | None, b: str | None) -> bool:
    """Whether two unit spellings name the same unit (no scale conversion).

    Examples
    --------
    >>> same_unit("m/s²", "m s-2"), same_unit("deg", "°"), same_unit("g", "m/s^2")
    (True, True, False)
    """
    return canonical_unit(a) == canonical_unit(b)


def check_unit(have: str | None, want: str | None, *, what: str, fix: str) -> None:
    """Refuse data whose unit differs from a calibration's; unknown units pass.

    Parameters
    ----------
    have : str or None
        Unit of the data ('' or None when the file does not say).
    want : str or None
        Unit the calibration was made in ('' or None when unknown).
    what : str
        Names the data, e.g. ``"channel 'x' of run.csv"``.
    fix : str
        What to do, e.g. ``"convert the data or calibrate again"``.

    Raises
    ------
    InputError
        Both units are known and :func:`same_unit` says they differ.
    """
    if have and want and have.strip() and want.strip() and not same_unit(have, want):
        raise InputError(f"{what} is in '{have}' but the sensor was calibrated in '{want}'; {fix}")


def numerator(text: str | None) -> str:
    """What stands before a unit's top-level ``/``: ``"V/(m/s^2)"`` -> ``"V"``.

    A sensitivity's unit is output unit per input unit; this is the output
    unit, what a recording's output channel should be in.
    """
    text = (text or "").strip()
    depth = 0
    for i, ch in enumerate(text):
        depth += {"(": 1, ")": -1}.get(ch, 0)
        if ch == "/" and depth == 0:
            return text[:i].strip()
    return text
