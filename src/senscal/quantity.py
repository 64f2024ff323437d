"""A quoted quantity: value, standard uncertainty, unit and coverage factor.

Light on purpose (no database imports): every job result returns its
quantities as :class:`Quantity`, and the registry stores them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from senscal._result import ResultMixin
from senscal.errors import DataError, InputError

__all__ = ["Quantity", "check_text"]


def check_text(text: str, what: str, *, free: bool = False) -> None:
    """Refuse text no database can store faithfully (control characters, lone surrogates).

    ``free`` text (notes) may hold line breaks and tabs, but never NUL.
    """
    if any(ord(ch) < 32 and not (free and ch in "\n\r\t") for ch in text):
        raise InputError(f"{what} must not contain control characters, got {text!r}")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise InputError(f"{what} is not valid Unicode text (lone surrogate), got {text!r}") from None



@dataclass(frozen=True)
class Quantity(ResultMixin):
    """One quoted quantity of a calibration.

    Attributes
    ----------
    name : str
        e.g. ``sensitivity@80Hz``, ``ch1.amplitude``.
    value : float
        Unit ``unit``.
    uncertainty : float
        Standard uncertainty (k=1), unit ``unit``.
    unit : str
    k : float
        Coverage factor the quantity is quoted with (expanded U = k * uncertainty).
    """

    name: str
    value: float
    uncertainty: float
    unit: str = ""
    k: float = 2.0

    def __post_init__(self):
        if not str(self.name).strip():
            raise InputError("a calibrated quantity needs a name")
        check_text(str(self.name), "quantity name")
        check_text(str(self.unit), "unit")
        if not math.isfinite(float(self.value)):
            raise DataError(f"quantity {self.name!r}: value must be finite, got {self.value}")
        u = float(self.uncertainty)
        if not (math.isfinite(u) and u > 0):
            raise DataError(f"quantity {self.name!r}: standard uncertainty must be positive and finite, got {self.uncertainty}; "
                            "the drift fit weights records by their uncertainties")
        if not (math.isfinite(float(self.k)) and float(self.k) > 0):
            raise InputError(f"quantity {self.name!r}: coverage factor k must be positive, got {self.k}")
