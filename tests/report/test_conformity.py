"""Decision rules (ILAC-G8:09/2019): the specification parser, the verdicts, and the probability of a false
accept against a Monte Carlo of the decision with simulated truth."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.report.conformity import (Specification, apply_to_document, dcc_conformity, decide, overall,
                                       parse_specification, probability_conforming)


@pytest.mark.parametrize("text, lo, hi, unit", [
    ("sensitivity=0.05+-2%", 0.049, 0.051, ""),
    ("sensitivity = 0.05 +- 0.001", 0.049, 0.051, ""),
    ("sensitivity=50 mV/(m/s^2)+-1 mV/(m/s^2)", 49.0, 51.0, "mV/(m/s^2)"),
    ("sensitivity=50 mV/(m/s^2)+-0.001 V/(m/s^2)", 49.0, 51.0, "mV/(m/s^2)"),
    ("sensitivity=0.049..0.051", 0.049, 0.051, ""),
    ("phase_delay_deg<=5", None, 5.0, ""),
    ("sensitivity>=0.049", 0.049, None, ""),
    ("normalized_sensitivity=1±1%", 0.99, 1.01, ""),
])
def test_parse(text, lo, hi, unit):
    s = parse_specification(text)
    assert (s.lower is None) == (lo is None) and (s.upper is None) == (hi is None)
    if lo is not None:
        assert s.lower == pytest.approx(lo)
    if hi is not None:
        assert s.upper == pytest.approx(hi)
    assert s.unit == unit


@pytest.mark.parametrize("text", ["sensitivity", "sensitivity=0.05", "sensitivity=0.05+-", "=0.05+-1%",
                                  "sensitivity=abc+-1%", "sensitivity=0.05+--1", "sensitivity=0+-1%",
                                  "sensitivity=0.06..0.05", "sensitivity<=5%", "sensitivity=0.05+-0",
                                  "sensitivity=1 V+-1 m", "sensitivity=1 bogon+-1%", "sensitivity=nan+-1"])
def test_parse_refuses(text):
    with pytest.raises(InputError):
        parse_specification(text)


SPEC = Specification("x", -1.0, 1.0)


@pytest.mark.parametrize("value, simple, guard, nonbin", [
    (0.0, "pass", "pass", "pass"),
    (0.85, "pass", "fail", "conditional pass"),     # within U = 0.2 of the upper limit
    (1.15, "fail", "fail", "conditional fail"),     # outside, within U
    (1.25, "fail", "fail", "fail"),
    (-0.85, "pass", "fail", "conditional pass"),
])
def test_rules(value, simple, guard, nonbin):
    assert decide(value, 0.1, SPEC, "simple").conformity == simple
    assert decide(value, 0.1, SPEC, "guard-band").conformity == guard
    assert decide(value, 0.1, SPEC, "non-binary").conformity == nonbin
    assert decide(value, 0.1, SPEC, "guard-band").guard_band == pytest.approx(0.2)


def test_probabilities():
    # at a limit the simple rule accepts with a 50 % probability of false accept
    d = decide(1.0, 0.1, SPEC, "simple")
    assert d.conformity == "pass" and d.probability_false_accept == pytest.approx(0.5, abs=1e-12)
    # at the guard-band limit (U = 2u from the tolerance limit) it is Phi(-2)
    d = decide(0.8, 0.1, SPEC, "guard-band")
    assert d.probability_false_accept == pytest.approx(0.5 * math.erfc(2 / math.sqrt(2)), rel=1e-9)
    # rejected: no false accept, a false-reject probability
    d = decide(1.1, 0.1, SPEC, "simple")
    assert d.probability_false_accept == 0 and d.probability_false_reject == pytest.approx(0.5 * math.erfc(1 / math.sqrt(2)))
    assert probability_conforming(0.5, 0.0, SPEC) == 1.0 and probability_conforming(2.0, 0.0, SPEC) == 0.0
    assert probability_conforming(100.0, 1.0, Specification("x", None, 101.0)) == pytest.approx(0.8413447, rel=1e-6)


def test_overall_and_dcc_enum():
    assert overall(["pass", "conditional pass", "pass"]) == "conditional pass"
    assert overall(["pass", "conditional fail", "conditional pass"]) == "conditional fail"
    assert overall(["fail", "conditional fail"]) == "fail"
    assert dcc_conformity("conditional pass (0.049 <= sensitivity ...)") == "conditionalPass"
    assert dcc_conformity("pass") == "pass"
    assert dcc_conformity("The sensitivity deviates by less than 2 %") == ""


def test_refuses_bad_rule_and_value():
    with pytest.raises(InputError):
        decide(0.0, 0.1, SPEC, "lenient")
    with pytest.raises(InputError):
        decide(float("nan"), 0.1, SPEC)


def test_document_points_units_and_statement():
    doc = {"unit": "V/(m/s^2)", "points": [
        {"sensitivity": 0.0500, "u_sensitivity": 0.0001, "U_sensitivity": 0.0002},
        {"sensitivity": 0.0509, "u_sensitivity": 0.0001, "U_sensitivity": 0.0002},
        {"sensitivity": 0.0512, "u_sensitivity": 0.0001, "U_sensitivity": 0.0002}]}
    statement, rule = apply_to_document(doc, parse_specification("sensitivity=50 mV/(m/s^2)+-2%"), "non-binary")
    assert [p["conformity"] for p in doc["points"]] == ["pass", "conditional pass", "conditional fail"]
    assert statement.startswith("conditional fail (") and "ILAC-G8" in rule
    assert doc["conformity"]["lower"] == pytest.approx(0.049) and doc["conformity"]["unit"] == "V/(m/s^2)"
    assert 0 < doc["points"][1]["probability_false_accept"] < 0.5
    with pytest.raises(InputError, match="no quantity 'gain'"):
        apply_to_document(doc, parse_specification("gain=1+-1%"), "simple")
    with pytest.raises(InputError):  # a length is not a sensitivity
        apply_to_document(doc, parse_specification("sensitivity=1 m+-1%"), "simple")


# --------------------------------------------------------------------------------------------------------------
# Monte Carlo: simulated truth, measured value y = truth + u e, the decision on y.  With the truth spread flat
# far beyond the tolerance (a flat prior), the probability that the truth is out of tolerance given y is the
# normal one the module states; so the rate of (accepted and truly out of tolerance) equals the mean stated
# probability of false accept, overall and in bins of it.  The difference of the indicator and its stated
# probability has variance E[p (1 - p)] (p the stated probability), which sets the tolerance (z = 3.89, two-sided
# 1e-4, over the few comparisons made).

Z = 3.89


def _simulate(spec, rule, n, seed, u=0.1, u_stated=None):
    rng = np.random.default_rng(seed)
    lo = spec.lower if spec.lower is not None else spec.upper - 2.0
    hi = spec.upper if spec.upper is not None else spec.lower + 2.0
    truth = rng.uniform(lo - 10 * u, hi + 10 * u, n)
    y = truth + u * rng.standard_normal(n)
    keep = (y > lo - 4 * u) & (y < hi + 4 * u)    # far from the prior's edges (5 u and more): flat there
    truth, y = truth[keep], y[keep]
    pfa = np.empty(y.size)
    accepted = np.empty(y.size, dtype=bool)
    for i, v in enumerate(y):
        d = decide(float(v), u if u_stated is None else u_stated, spec, rule)
        pfa[i], accepted[i] = d.probability_false_accept, d.accepted
    t_lo = -np.inf if spec.lower is None else spec.lower
    t_hi = np.inf if spec.upper is None else spec.upper
    false_accept = accepted & ((truth < t_lo) | (truth > t_hi))
    return pfa, false_accept.astype(float)


def _agrees(pfa, hit):
    var = np.mean(pfa * (1 - pfa))
    return abs(hit.mean() - pfa.mean()) <= Z * math.sqrt(var / pfa.size) + 1e-12


@pytest.mark.parametrize("spec", [Specification("x", -1.0, 1.0), Specification("x", None, 1.0),
                                  Specification("x", -1.0, None), Specification("x", -0.15, 0.15)],
                         ids=["two-sided", "upper", "lower", "narrow"])
@pytest.mark.parametrize("rule", ["simple", "guard-band", "non-binary"])
def test_probability_false_accept_monte_carlo(spec, rule):
    pfa, hit = _simulate(spec, rule, 6000, seed=zlib.crc32(f"{rule}{spec}".encode()))
    assert _agrees(pfa, hit), (hit.mean(), pfa.mean())
    # calibrated in bins of the stated probability too
    for a, b in ((1e-6, 0.05), (0.05, 0.25), (0.25, 1.0)):
        sel = (pfa >= a) & (pfa < b)
        if sel.sum() >= 100:
            assert _agrees(pfa[sel], hit[sel]), (a, b, hit[sel].mean(), pfa[sel].mean())
    if rule == "guard-band":
        assert pfa.max() <= 0.5 * math.erfc(2 / math.sqrt(2)) + 1e-12   # w = U bounds the specific risk


def test_monte_carlo_detects_a_wrong_probability():
    """The check has power: a probability stated with half the true u is refused."""
    pfa, hit = _simulate(Specification("x", -1.0, 1.0), "simple", 6000, seed=7, u_stated=0.05)
    assert not _agrees(pfa, hit)
