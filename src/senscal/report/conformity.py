"""Statements of conformity by a decision rule (ILAC-G8:09/2019, JCGM 106:2012).

A *specification* gives the tolerance interval of one quantity of a result:
``sensitivity=0.05+-2%`` (nominal value and a relative tolerance),
``sensitivity=50 mV/(m/s^2)+-1 mV/(m/s^2)`` (absolute, with units),
``sensitivity=0.049..0.051`` (both limits), or one-sided
``phase_delay_deg<=5`` / ``sensitivity>=0.049``.  A number without a unit is
in the result's unit; a unit is converted to it (:func:`senscal.units.factor`).

Decision rules (ILAC-G8:09/2019 section 4):

``simple``
    Guard band w = 0 (shared risk): pass when the measured value lies in the
    tolerance interval, else fail.
``guard-band``
    w = U = k u: pass when the value lies in the acceptance interval, the
    tolerance interval shrunk by U at each limit; else fail.  The specific
    probability of a false accept of a passed value is then below about 2.5 %.
``non-binary``
    w = U: pass inside the acceptance interval; *conditional pass* inside the
    tolerance interval but within U of a limit; *conditional fail* outside the
    tolerance interval but within U of it; fail beyond that.

Each decision carries its specific risk (JCGM 106 section 9.5): with the
measurand's state of knowledge normal, mean the measured value y and
standard deviation its standard uncertainty u, the probability that the
true value conforms is p_c = Phi((T_U - y)/u) - Phi((T_L - y)/u).  An
accepted value (pass, conditional pass) has ``probability_false_accept``
1 - p_c; a rejected one has ``probability_false_reject`` p_c.

Pure: numbers and frozen dataclasses in and out.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Mapping, MutableMapping, Sequence

from senscal._result import ResultMixin
from senscal.errors import InputError

__all__ = ["RULES", "Specification", "Decision", "parse_specification", "decide", "probability_conforming",
           "overall", "dcc_conformity", "rule_text", "apply_to_document"]

RULES = ("simple", "guard-band", "non-binary")
PASS, FAIL, COND_PASS, COND_FAIL = "pass", "fail", "conditional pass", "conditional fail"
# worst first: the overall statement is the worst point's
_ORDER = (FAIL, COND_FAIL, COND_PASS, PASS)

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_NAME = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(<=|>=|=)\s*(.+?)\s*$")
_QTY = re.compile(rf"^\s*({_NUM})\s*(.*?)\s*$")

_HOW = ("write NAME=VALUE+-TOL (TOL absolute or in %), NAME=LOW..HIGH, NAME>=LOW or NAME<=HIGH, "
        "e.g. 'sensitivity=0.05+-2%'")


@dataclass(frozen=True)
class Specification(ResultMixin):
    """A tolerance interval [lower, upper] of one quantity; a missing limit is None (one-sided).

    ``lower``/``upper`` are in ``unit`` ("" = the result's unit).
    """

    quantity: str
    lower: float | None
    upper: float | None
    unit: str = ""
    text: str = ""

    def in_unit(self, unit: str) -> "Specification":
        """The limits converted to ``unit`` (the result's)."""
        if not self.unit or not unit:
            return self
        from senscal.units import factor

        f = factor(self.unit, unit, what=f"the --conformity limits of {self.quantity}",
                   fix=f"give them in a unit of the same kind as the result's {unit!r}")
        return Specification(self.quantity, None if self.lower is None else self.lower * f,
                             None if self.upper is None else self.upper * f, unit, self.text)

    def describe(self, unit: str = "") -> str:
        """``0.049 <= sensitivity <= 0.051 V/(m/s^2)``."""
        u = f" {unit or self.unit}".rstrip()
        if self.lower is not None and self.upper is not None:
            return f"{self.lower:.6g} <= {self.quantity} <= {self.upper:.6g}{u}"
        if self.lower is not None:
            return f"{self.quantity} >= {self.lower:.6g}{u}"
        return f"{self.quantity} <= {self.upper:.6g}{u}"


@dataclass(frozen=True)
class Decision(ResultMixin):
    """The decision on one measured value."""

    conformity: str                   # pass | conditional pass | conditional fail | fail
    probability_conforming: float     # p_c, the probability the true value lies in the tolerance interval
    probability_false_accept: float   # 1 - p_c when accepted (pass, conditional pass), else 0
    probability_false_reject: float   # p_c when rejected (fail, conditional fail), else 0
    guard_band: float                 # w, in the value's unit

    @property
    def accepted(self) -> bool:
        return self.conformity in (PASS, COND_PASS)


def _quantity(text: str, spec: str) -> tuple[float, str]:
    m = _QTY.match(text)
    if not m:
        raise InputError(f"--conformity {spec!r}: {text.strip()!r} is not a number; {_HOW}")
    v = float(m.group(1))
    if not math.isfinite(v):
        raise InputError(f"--conformity {spec!r}: {text.strip()!r} is not finite; {_HOW}")
    unit = m.group(2).strip()
    if unit and unit != "%":
        from senscal.units import parse_unit

        parse_unit(unit, what=f"the unit in --conformity {spec!r}")
    return v, unit


def parse_specification(text: str) -> Specification:
    """The :class:`Specification` of a ``--conformity`` text.

    Raises
    ------
    InputError
        A malformed text, a negative or relative-to-zero tolerance, an empty interval, mixed units.
    """
    spec = str(text)
    m = _NAME.match(spec)
    if not m:
        raise InputError(f"--conformity {spec!r} is not a specification; {_HOW}")
    name, op, rest = m.groups()
    if op in ("<=", ">="):
        v, unit = _quantity(rest, spec)
        if unit == "%":
            raise InputError(f"--conformity {spec!r}: a one-sided limit is a value, not a percentage; {_HOW}")
        return Specification(name, v if op == ">=" else None, v if op == "<=" else None, unit, spec)
    if ".." in rest:
        lo_t, _, hi_t = rest.partition("..")
        (lo, ulo), (hi, uhi) = _quantity(lo_t, spec), _quantity(hi_t, spec)
        if "%" in (ulo, uhi):
            raise InputError(f"--conformity {spec!r}: limits are values, not percentages; {_HOW}")
        unit = uhi or ulo
        if ulo and uhi and ulo != uhi:
            raise InputError(f"--conformity {spec!r}: give both limits in one unit ({ulo!r} and {uhi!r})")
    else:
        parts = re.split(r"\+-|\+/-|±", rest)
        if len(parts) != 2:
            raise InputError(f"--conformity {spec!r} has no tolerance; {_HOW}")
        nominal, unit = _quantity(parts[0], spec)
        tol, utol = _quantity(parts[1], spec)
        if tol < 0:
            raise InputError(f"--conformity {spec!r}: the tolerance must not be negative")
        if utol == "%":
            if nominal == 0:
                raise InputError(f"--conformity {spec!r}: a percentage of a zero nominal value is zero; "
                                 "give the tolerance as a value")
            tol = abs(nominal) * tol / 100.0
        elif utol:
            if unit and unit != utol:
                from senscal.units import factor

                tol *= factor(utol, unit, what=f"the tolerance in --conformity {spec!r}",
                              fix="give the tolerance in a unit of the nominal value's kind")
            else:
                unit = utol
        lo, hi = nominal - tol, nominal + tol
    if not lo < hi:
        raise InputError(f"--conformity {spec!r}: the tolerance interval [{lo:g}, {hi:g}] is empty; "
                         "give a positive tolerance or LOW..HIGH with LOW < HIGH")
    return Specification(name, lo, hi, unit, spec)


def probability_conforming(value: float, u: float, spec: Specification) -> float:
    """p_c = P(T_L <= Y <= T_U) with Y ~ N(value, u^2); 0 or 1 when u is 0."""
    from scipy.special import ndtr

    lo = -math.inf if spec.lower is None else spec.lower
    hi = math.inf if spec.upper is None else spec.upper
    if u <= 0:
        return 1.0 if lo <= value <= hi else 0.0
    # the smaller tail differences keep precision far from the limits
    return float(max(0.0, ndtr((hi - value) / u) - ndtr((lo - value) / u)))


def decide(value: float, u: float, spec: Specification, rule: str = "simple", k: float = 2.0) -> Decision:
    """The decision on a measured ``value`` with standard uncertainty ``u`` (same unit as ``spec``).

    Parameters
    ----------
    value, u : float
        Measured value and its standard uncertainty.
    spec : Specification
        Tolerance interval (in the value's unit: :meth:`Specification.in_unit`).
    rule : str
        ``simple``, ``guard-band`` or ``non-binary``.
    k : float
        Coverage factor of the expanded uncertainty U = k u that is the guard band.
    """
    if rule not in RULES:
        raise InputError(f"--decision-rule {rule!r} is not known; use one of {', '.join(RULES)}")
    if not (math.isfinite(value) and math.isfinite(u) and u >= 0 and math.isfinite(k) and k > 0):
        raise InputError(f"a statement of conformity needs a finite value and u >= 0, got {value!r} +- {u!r}; "
                         "check the result")
    lo = -math.inf if spec.lower is None else spec.lower
    hi = math.inf if spec.upper is None else spec.upper
    w = 0.0 if rule == "simple" else k * u
    inside = lo <= value <= hi
    in_acceptance = lo + w <= value <= hi - w
    if rule == "simple":
        verdict = PASS if inside else FAIL
    elif rule == "guard-band":
        verdict = PASS if in_acceptance else FAIL
    elif in_acceptance:
        verdict = PASS
    elif inside:
        verdict = COND_PASS
    elif lo - w <= value <= hi + w:
        verdict = COND_FAIL
    else:
        verdict = FAIL
    pc = probability_conforming(value, u, spec)
    accepted = verdict in (PASS, COND_PASS)
    return Decision(verdict, pc, (1.0 - pc) if accepted else 0.0, 0.0 if accepted else pc, w)


def overall(verdicts: Sequence[str]) -> str:
    """The statement of a result of several points: its worst point's verdict."""
    if not verdicts:
        raise ValueError("no verdicts")
    return min(verdicts, key=_ORDER.index)


def dcc_conformity(verdict: str) -> str:
    """The DCC 3.1.2 ``stringConformityStatementStatusType`` value of a verdict (``conditionalPass``)."""
    key = re.sub(r"[\s_-]", "", str(verdict).split("(")[0].split(":")[0]).lower()
    return {v.lower(): v for v in ("pass", "fail", "conditionalPass", "conditionalFail", "noPass",
                                   "noFail")}.get(key, "")


def rule_text(rule: str) -> str:
    """The decision rule as a certificate states it."""
    return {
        "simple": "simple acceptance, guard band w = 0 (ILAC-G8:09/2019 4.2.1; shared risk, specific probability "
                  "of false accept up to 50 % at a limit)",
        "guard-band": "guarded acceptance, guard band w = U (ILAC-G8:09/2019 4.2.2; specific probability of "
                      "false accept below 2.5 % for k = 2)",
        "non-binary": "non-binary statement with guard band w = U (ILAC-G8:09/2019 4.2.3: pass, conditional "
                      "pass, conditional fail, fail)",
    }[rule]


def _unit_of(q: str, doc: Mapping[str, Any]) -> str:
    """The unit of a result quantity (the JSON names carry it: ``*_deg``, ``*_percent``, ``*_hz``)."""
    if q in ("sensitivity", "slope"):
        return str(doc.get("unit") or "")
    if q in ("output_amplitude", "intercept"):
        return str(doc.get("output_unit") or "")
    for suffix, unit in (("_deg", "deg"), ("_hz", "Hz"), ("_percent", "percent"), ("_m", "m")):
        if q.endswith(suffix):
            return unit
    return ""


def apply_to_document(doc: MutableMapping[str, Any], spec: Specification, rule: str) -> tuple[str, str]:
    """Decide every point of a command's JSON document; return (statement, decision rule) for the certificate.

    The quantity ``q`` is read per point (``doc["points"]``) when the points carry it, else from the
    document's top level: its value ``q``, standard uncertainty ``u_q`` and expanded uncertainty ``U_q``
    (k = U_q / u_q, else the document's ``coverage_factor``, else 2).  Each decided entry gets
    ``conformity``, ``probability_conforming``, ``probability_false_accept`` and
    ``probability_false_reject``; ``doc["conformity"]`` gets the specification, rule and statement, and
    ``no_acceptance_interval_points``: how many points have U >= half the tolerance interval, so that a guard band
    w = U leaves nothing to pass (the command warns ``conformity-no-acceptance-interval``).

    Raises
    ------
    InputError
        The result has no such quantity, or none with a standard uncertainty.
    """
    q = spec.quantity
    points = [p for p in doc.get("points") or [] if isinstance(p, MutableMapping)]
    entries = [p for p in points if q in p] or ([doc] if q in doc else [])
    if not entries:
        known = sorted({k for p in [*points, doc] for k in p if f"u_{k}" in p and isinstance(p.get(k), (int, float))})
        raise InputError(f"--conformity: the result has no quantity {q!r}; use one of {', '.join(known) or 'none'}")
    unit = _unit_of(q, doc)
    if spec.unit and not unit:
        raise InputError(f"--conformity {spec.text!r}: senscal knows no unit of {q!r}; give its limits as bare "
                         "numbers in the result's unit")
    spec_u = spec.in_unit(unit)
    verdicts = []
    undecidable = 0   # points whose guard bands leave no acceptance interval: U >= half the tolerance
    for p in entries:
        value, u = p.get(q), p.get(f"u_{q}")
        if not isinstance(value, (int, float)) or not isinstance(u, (int, float)):
            raise InputError(f"--conformity: {q!r} has no standard uncertainty u_{q} in this result; "
                             "choose a quantity with one")
        big = p.get(f"U_{q}")
        # a point without its own U takes k = 2 (its u is a point's, not the fit's with Student's t)
        k = (float(big) / float(u) if isinstance(big, (int, float)) and u > 0
             else float(doc.get("coverage_factor") or 2.0) if p is doc else 2.0)
        d = decide(float(value), float(u), spec_u, rule, k)
        p.update(conformity=d.conformity, probability_conforming=d.probability_conforming,
                 probability_false_accept=d.probability_false_accept,
                 probability_false_reject=d.probability_false_reject, guard_band=d.guard_band)
        verdicts.append(d)
        if d.guard_band > 0 and spec_u.lower is not None and spec_u.upper is not None \
                and 2 * d.guard_band >= spec_u.upper - spec_u.lower:
            undecidable += 1
    verdict = overall([d.conformity for d in verdicts])
    counts = ", ".join(f"{sum(d.conformity == v for d in verdicts)} {v}" for v in reversed(_ORDER)
                       if any(d.conformity == v for d in verdicts))
    worst_pfa = max(d.probability_false_accept for d in verdicts)
    statement = (f"{verdict} ({spec_u.describe(unit)}; {counts} of {len(verdicts)} "
                 f"{'point' if len(verdicts) == 1 else 'points'}; largest probability of false accept "
                 f"{100 * worst_pfa:.2g} %)")
    doc["conformity"] = {"specification": spec.text, "quantity": q, "lower": spec_u.lower, "upper": spec_u.upper,
                         "unit": unit or spec.unit, "decision_rule": rule, "statement": verdict,
                         "text": statement, "no_acceptance_interval_points": undecidable}
    return statement, f"{rule}: {rule_text(rule)}"
