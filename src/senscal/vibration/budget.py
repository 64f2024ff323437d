"""GUM uncertainty budgets: type A and type B components, combined and expanded.

References
----------
.. [1] JCGM 100:2008, Evaluation of measurement data - Guide to the
   expression of uncertainty in measurement (GUM), sections 4 and 5.
.. [2] ISO 16063-21:2003, Methods for the calibration of vibration and shock
   transducers - Part 21: Vibration calibration by comparison to a reference
   transducer, annex A (uncertainty budget).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError

__all__ = ["BudgetComponent", "UncertaintyBudget", "make_budget", "mean_with_budget", "COVERAGE_FACTOR"]

COVERAGE_FACTOR = 2.0


@dataclass(frozen=True)
class BudgetComponent(ResultMixin):
    """One line of an uncertainty budget.

    Attributes
    ----------
    source : str
        What the component comes from (e.g. ``"sine fits"``, ``"input amplitude"``).
    kind : str
        ``"A"`` (statistical, from the data) or ``"B"`` (other knowledge, supplied).
    standard_uncertainty : float
        Contribution to the result's standard uncertainty, in the result's unit
        (already multiplied by its sensitivity coefficient).
    """

    source: str
    kind: str
    standard_uncertainty: float


@dataclass(frozen=True)
class UncertaintyBudget(ResultMixin):
    """A result with its GUM budget.

    Attributes
    ----------
    quantity : str
        Name of the measurand.
    value : float
        Best estimate, in ``unit``.
    unit : str
        Unit of ``value`` and of every uncertainty.
    components : tuple of BudgetComponent
        Uncorrelated contributions (correlated inputs are combined inside one
        component through their covariance before they get here).
    combined : float
        Combined standard uncertainty ``sqrt(sum u_i^2)`` (k=1).
    coverage_factor : float
        ``k`` of the expanded uncertainty (2, about 95 % for a normal distribution).
    expanded : float
        ``k * combined``.
    """

    quantity: str
    value: float
    unit: str
    components: tuple[BudgetComponent, ...]
    combined: float
    coverage_factor: float
    expanded: float

    def component(self, source: str) -> BudgetComponent:
        """The component called ``source``."""
        for c in self.components:
            if c.source == source:
                return c
        raise InputError(f"budget of {self.quantity} has no component '{source}'; it has "
                         f"{', '.join(c.source for c in self.components)}")


def make_budget(quantity: str, value: float, unit: str, components: Sequence[tuple[str, str, float]],
                coverage_factor: float = COVERAGE_FACTOR) -> UncertaintyBudget:
    """Combine uncorrelated components by root sum of squares (GUM 5.1.2).

    Parameters
    ----------
    quantity, unit : str
        Name and unit of the measurand.
    value : float
        Best estimate.
    components : sequence of (source, kind, u)
        ``u`` is the standard uncertainty contribution in ``unit``; zero
        components are kept so a certificate can show them as "not applied".
    coverage_factor : float
        ``k`` for the expanded uncertainty.
    """
    comps = []
    for source, kind, u in components:
        if kind not in ("A", "B"):
            raise InputError(f"uncertainty component '{source}' must be type A or B, got {kind!r}")
        u = float(u)
        if not math.isfinite(u) or u < 0:
            raise InputError(f"uncertainty component '{source}' must be a finite non-negative number, got {u!r}")
        comps.append(BudgetComponent(source, kind, u))
    uc = math.sqrt(sum(c.standard_uncertainty ** 2 for c in comps))
    return UncertaintyBudget(quantity, float(value), unit, tuple(comps), uc, float(coverage_factor),
                             float(coverage_factor) * uc)


def mean_with_budget(values: Sequence[float], u_fit: Sequence[float], relative_b: Sequence[tuple[str, float]],
                     quantity: str, unit: str, absolute_b: Sequence[tuple[str, float]] = ()
                     ) -> tuple[float, float, UncertaintyBudget]:
    """Mean of repeated results (repeats, or points of a flat response) with a GUM budget.

    Type A is the larger of the experimental standard deviation of the mean
    ``s / sqrt(n)`` (GUM 4.2.3) and the fits' own ``sqrt(sum u_i^2) / n``:
    both estimate the same random error, so adding them would count it twice,
    and with few repeats ``s`` alone can come out implausibly small.  Type B
    components are relative and common to all repeats, so averaging does not
    reduce them.

    Parameters
    ----------
    values : sequence of float
        Results of the repeats, in ``unit``.
    u_fit : sequence of float
        Their type A standard uncertainties from the fits, in ``unit``.
    relative_b : sequence of (source, relative u)
        Type B components as fractions of the value.
    quantity, unit : str
    absolute_b : sequence of (source, u)
        Type B components in ``unit``.

    Returns
    -------
    mean : float
    std : float
        Experimental standard deviation of the values (0 for one value).
    budget : UncertaintyBudget
    """
    v = np.asarray(values, dtype=float)
    n = v.size
    if n == 0:
        raise InputError(f"no values to average for {quantity}")
    mean = float(v.mean())
    std = float(v.std(ddof=1)) if n > 1 else 0.0
    u_mean_fit = float(np.sqrt(np.sum(np.square(u_fit)))) / n
    u_a = max(std / math.sqrt(n), u_mean_fit)
    comps = [("type A (spread of repeats / fits)", "A", u_a)]
    comps += [(src, "B", rel * abs(mean)) for src, rel in relative_b]
    comps += [(src, "B", u) for src, u in absolute_b]
    return mean, std, make_budget(quantity, mean, unit, comps)
