"""A saved calibration's unit against the unit of the data it is applied to.

A saved calibration remembers the unit of the data it was made from; data
in another unit of the same dimension are converted (``uT`` data to an
``nT`` calibration, ``m/s²`` to ``m/s^2``, ``g`` to ``m/s^2``), data of
another dimension are refused with one line (``V`` against ``m/s^2``).
The units themselves are parsed and converted by :mod:`senscal.units`
(pint), never compared as strings.
"""

from __future__ import annotations

from senscal.errors import InputError
from senscal.units import compatible, dimension_of, factor, is_unit, same_unit

__all__ = ["same_unit", "unit_factor", "check_unit", "numerator"]


def unit_factor(have: str | None, want: str | None, *, what: str, fix: str) -> float:
    """The factor that converts data in ``have`` to a calibration's unit ``want`` (1 when either is unknown).

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

    Returns
    -------
    float
        ``factor("uT", "nT") == 1000``: multiply the data by it.

    Raises
    ------
    InputError
        Both units are given and name different dimensions, or one is text
        that is no unit (and not the same text as the other).
    """
    h, w = (have or "").strip(), (want or "").strip()
    if not h or not w:
        return 1.0
    if not (is_unit(h) and is_unit(w)):
        if " ".join(h.split()) == " ".join(w.split()):
            return 1.0
        bad = h if not is_unit(h) else w
        raise InputError(f"{what} is in {h!r} but the sensor was calibrated in {w!r}, and {bad!r} is not a unit "
                         f"senscal knows; {fix}")
    if not compatible(h, w):
        raise InputError(f"{what} is in {h!r} ({dimension_of(h)}) but the sensor was calibrated in {w!r} "
                         f"({dimension_of(w)}); {fix}")
    return factor(h, w, what=what, fix=fix)


def check_unit(have: str | None, want: str | None, *, what: str, fix: str) -> None:
    """Refuse data whose unit cannot be converted to the calibration's (see :func:`unit_factor`)."""
    unit_factor(have, want, what=what, fix=fix)


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
