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

__all__ = ["BudgetComponent", "UncertaintyBudget", "make_budget", "mean_with_budget", "COVERAGE_FACTOR",
           "coverage_factor", "welch_satterthwaite", "CONSISTENCY_ALPHA", "MeanBudget", "unique_warnings"]

COVERAGE_FACTOR = 2.0
# k = 2 of a normal distribution covers 95.45 %: the same probability gives the
# Student-t k for a finite number of degrees of freedom (GUM G.3, table G.2).
_P_K2 = 0.9772498680518208
# Significance level of the chi-square test that decides whether values scatter
# more than their own uncertainties explain (false alarm 1 % on consistent data).
CONSISTENCY_ALPHA = 0.01


def coverage_factor(dof: float | None) -> float:
    """Coverage factor for about 95.45 % coverage with ``dof`` degrees of freedom.

    Parameters
    ----------
    dof : float or None
        Effective degrees of freedom; None or inf means the uncertainty is
        known (k = 2 exactly, the normal distribution's 95.45 %).

    Returns
    -------
    float
        Student-t quantile ``t_{0.97725}(dof)`` (GUM G.3): 2.0 for infinite
        dof, 2.52 for 5, 3.31 for 3.
    """
    if dof is None or not math.isfinite(dof) or dof > 1e7:
        return COVERAGE_FACTOR
    if dof < 1:
        raise InputError(f"an uncertainty with {dof:g} < 1 degrees of freedom has no coverage factor")
    from scipy.stats import t as student_t

    return float(student_t.ppf(_P_K2, dof))


def welch_satterthwaite(u: Sequence[float], dof: Sequence[float | None]) -> float:
    """Effective degrees of freedom of a sum of independent contributions (GUM G.4.1).

    Parameters
    ----------
    u : sequence of float
        Contributions (already multiplied by their sensitivity coefficients).
    dof : sequence of float or None
        Their degrees of freedom; None or inf for a contribution known exactly
        (a type B component taken as exact).

    Returns
    -------
    float
        ``(sum u_i^2)^2 / sum(u_i^4 / dof_i)``; inf when every finite-dof
        contribution is zero.
    """
    u = np.asarray(u, dtype=float)
    den = 0.0
    for ui, di in zip(u, dof):
        if di is not None and math.isfinite(di) and ui > 0:
            den += ui**4 / di
    num = float(np.sum(u**2)) ** 2
    return math.inf if den == 0.0 else num / den


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
    dof : float or None
        Its degrees of freedom (None: known exactly, as for a type B value
        taken from a certificate or a type A value from a long record).
    """

    source: str
    kind: str
    standard_uncertainty: float
    dof: float | None = None


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
        ``k`` of the expanded uncertainty: 2 (95.45 % for a normal
        distribution) when the effective degrees of freedom are large, the
        Student-t value for the same probability when they are few.
    expanded : float
        ``k * combined``.
    effective_dof : float or None
        Welch-Satterthwaite effective degrees of freedom (None: infinite).
    """

    quantity: str
    value: float
    unit: str
    components: tuple[BudgetComponent, ...]
    combined: float
    coverage_factor: float
    expanded: float
    effective_dof: float | None = None

    def component(self, source: str) -> BudgetComponent:
        """The component called ``source``."""
        for c in self.components:
            if c.source == source:
                return c
        raise InputError(f"budget of {self.quantity} has no component '{source}'; it has "
                         f"{', '.join(c.source for c in self.components)}")


def make_budget(quantity: str, value: float, unit: str, components: Sequence[tuple],
                coverage_factor: float | None = None) -> UncertaintyBudget:
    """Combine uncorrelated components by root sum of squares (GUM 5.1.2).

    Parameters
    ----------
    quantity, unit : str
        Name and unit of the measurand.
    value : float
        Best estimate.
    components : sequence of (source, kind, u) or (source, kind, u, dof)
        ``u`` is the standard uncertainty contribution in ``unit``; zero
        components are kept so a certificate can show them as "not applied".
        ``dof`` (default None: infinite) enters the Welch-Satterthwaite
        effective degrees of freedom.
    coverage_factor : float, optional
        ``k`` for the expanded uncertainty; by default the Student-t value for
        95.45 % at the effective degrees of freedom (2 when they are large).
    """
    comps = []
    for item in components:
        source, kind, u = item[:3]
        dof = item[3] if len(item) > 3 else None
        if kind not in ("A", "B"):
            raise InputError(f"uncertainty component '{source}' must be type A or B, got {kind!r}")
        u = float(u)
        if not math.isfinite(u) or u < 0:
            raise InputError(f"uncertainty component '{source}' must be a finite non-negative number, got {u!r}")
        dof = None if dof is None or not math.isfinite(float(dof)) else float(dof)
        comps.append(BudgetComponent(source, kind, u, dof))
    uc = math.sqrt(sum(c.standard_uncertainty ** 2 for c in comps))
    nu = welch_satterthwaite([c.standard_uncertainty for c in comps], [c.dof for c in comps])
    k = coverage_factor_for(nu) if coverage_factor is None else float(coverage_factor)
    return UncertaintyBudget(quantity, float(value), unit, tuple(comps), uc, k, k * uc,
                             None if not math.isfinite(nu) else float(nu))


def coverage_factor_for(dof: float) -> float:
    """:func:`coverage_factor`, with dof below 1 clipped to 1 (a W-S value can be fractional)."""
    return coverage_factor(None if not math.isfinite(dof) else max(dof, 1.0))


@dataclass(frozen=True)
class MeanBudget(ResultMixin):
    """Mean of repeated results with its budget and the consistency check.

    Unpacks as ``mean, std, budget = mean_with_budget(...)`` (the first three
    attributes) for code written before the check existed.

    Attributes
    ----------
    mean : float
        Arithmetic mean of the values, in the values' unit.
    std : float
        Experimental standard deviation of the values (0 for one value).
    budget : UncertaintyBudget
        Type A by the rule of :func:`mean_with_budget`, type B carried over.
    estimator : str
        ``"spread"`` (``s / sqrt(n)`` with ``n - 1`` degrees of freedom) or,
        for one value, ``"fits"`` (its fit uncertainty).
    birge_ratio : float
        ``sqrt(chi2 / (n - 1))`` of the values about their weighted mean
        with the fits' uncertainties (1 on average when those are right;
        nan for one value).
    chi2_p : float
        Probability of a chi-square at least this large when the fits'
        uncertainties explain the scatter (nan for one value).
    warnings : tuple of str
        ``excess-scatter`` when ``chi2_p < CONSISTENCY_ALPHA``.
    """

    mean: float
    std: float
    budget: UncertaintyBudget
    estimator: str
    birge_ratio: float
    chi2_p: float
    warnings: tuple[str, ...] = ()

    def __iter__(self):
        return iter((self.mean, self.std, self.budget))


def mean_with_budget(values: Sequence[float], u_fit: Sequence[float], relative_b: Sequence[tuple[str, float]],
                     quantity: str, unit: str, absolute_b: Sequence[tuple[str, float]] = (),
                     fit_dof: Sequence[float | None] | None = None) -> MeanBudget:
    """Mean of repeated results (repeats, or points of a flat response) with a GUM budget.

    One estimator of type A, by a stated rule: for two or more values it is
    the experimental standard deviation of the mean ``s / sqrt(n)`` with
    ``n - 1`` degrees of freedom, expanded with Student's ``t_{95.45}(n-1)``
    (GUM 4.2.3, G.3).  Its coverage is exact whatever varies between records
    (noise only, or also remounting, temperature, input level), which the
    fits' own uncertainties cannot see; the old rule (the larger of ``s /
    sqrt(n)`` and the fits' ``sqrt(sum u_i^2) / n``) took the maximum of two
    estimates of the same spread and came out 10-18 % too large, and
    choosing between them by a test undercovers when a between-record
    variation is too small to be detected but not too small to matter.  With
    one value, type A is that value's fit uncertainty.

    The fits' uncertainties still serve as a diagnostic: a chi-square test of
    the values about their weighted mean (``n - 1`` dof) raises the named
    warning ``excess-scatter`` when ``p < CONSISTENCY_ALPHA`` (0.01): the
    records differ by more than their noise, so something varies between
    them that a single record does not show.  Type B components are common
    to all values, so averaging does not reduce them.

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
    fit_dof : sequence of float or None, optional
        Degrees of freedom of each ``u_i`` (default: infinite); used for one value.

    Returns
    -------
    MeanBudget
        Unpacks as ``(mean, std, budget)``.

    References
    ----------
    .. [1] JCGM 100:2008 (GUM) 4.2.3 (type A of a mean), G.3 (t factor).
    .. [2] R. T. Birge, Phys. Rev. 40, 207 (1932): the ratio of external to
       internal consistency.
    """
    from senscal.diagnostics import named

    v = np.asarray(values, dtype=float)
    u = np.asarray(u_fit, dtype=float)
    n = v.size
    if n == 0:
        raise InputError(f"no values to average for {quantity}")
    if u.shape != v.shape:
        raise InputError(f"give one fit uncertainty per value for {quantity} ({u.size} for {n})")
    dofs = list(fit_dof) if fit_dof is not None else [None] * n
    mean = float(v.mean())
    std = float(v.std(ddof=1)) if n > 1 else 0.0
    birge, p, warnings = math.nan, math.nan, ()
    if n == 1:
        estimator, u_a, nu_a = "fits", float(u[0]), (math.inf if dofs[0] is None else float(dofs[0]))
    else:
        estimator, u_a, nu_a = "spread", std / math.sqrt(n), float(n - 1)
        if np.all(u > 0):
            from scipy.stats import chi2 as chi2_dist

            w = 1.0 / u**2
            vw = float(np.sum(w * v) / np.sum(w))
            c2 = float(np.sum(w * (v - vw) ** 2))
            birge, p = math.sqrt(c2 / (n - 1)), float(chi2_dist.sf(c2, n - 1))
            if p < CONSISTENCY_ALPHA:
                warnings = (named("excess-scatter", (
                    f"the {n} values of {quantity} scatter {birge:.3g} times more than their fit uncertainties "
                    f"explain (chi2 p = {p:.2g}): something varies between records that one record cannot show "
                    f"(mounting, temperature, input level); type A is their spread s/sqrt(n), which contains it, "
                    f"with k = {coverage_factor(n - 1):.3g} ({n - 1} dof); find the cause, or add repeats for a "
                    "smaller k")),)
    comps = [("type A (fit)" if estimator == "fits" else "type A (spread of repeats)", "A", u_a,
              None if not math.isfinite(nu_a) else nu_a)]
    comps += [(src, "B", rel * abs(mean)) for src, rel in relative_b]
    comps += [(src, "B", ub) for src, ub in absolute_b]
    return MeanBudget(mean, std, make_budget(quantity, mean, unit, comps), estimator, birge, p, warnings)


def unique_warnings(*groups) -> tuple[str, ...]:
    """Warnings of several results, one per name (first text kept), order kept."""
    from senscal.diagnostics import warning_name

    out, seen = [], set()
    for g in groups:
        for w in g:
            key = warning_name(w) or w
            if key not in seen:
                seen.add(key)
                out.append(w)
    return tuple(out)
