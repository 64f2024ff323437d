"""The coverage statistics every honesty test relies on."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.diagnostics import has_warning, named, warning_name, warning_names
from senscal.validation import CoverageRow, check_coverage, coverage_ok, coverage_row, mc_seeds, wilson_interval


def test_wilson_contains_truth_at_stated_rate():
    # The 99.9 % interval must contain p in >= 99 % of binomial draws (it is conservative-ish).
    rng = np.random.default_rng(1)
    n, p = 400, 0.95
    hits = rng.binomial(n, p, size=4000)
    inside = [wilson_interval(int(h), n)[0] <= p <= wilson_interval(int(h), n)[1] for h in hits]
    assert np.mean(inside) >= 0.99


def test_rule_tells_90_from_95_at_400_seeds():
    rng = np.random.default_rng(2)
    truth = 0.0
    # u right: z ~ N(0,1) -> coverage 95.4 %; u 1.25x too small -> about 88 %.
    z = rng.standard_normal(400)
    assert coverage_ok(coverage_row("j", "c", "q", z, np.ones(400), truth))
    assert not coverage_ok(coverage_row("j", "c", "q", z * 1.25, np.ones(400), truth))
    # and far too pessimistic u fails too (coverage 100 %)
    assert not coverage_ok(coverage_row("j", "c", "q", z * 0.5, np.ones(400), truth))


def test_nonfinite_u_counts_as_miss_and_warn_rows():
    row = coverage_row("j", "c", "q", [0.0, 0.0], [np.nan, 1.0], 0.0)
    assert row.coverage == 0.5
    w = coverage_row("j", "c", "q", [9.0] * 10, [1.0] * 10, 0.0, warned=[True] * 10, expect="warn")
    assert w.ok
    w2 = coverage_row("j", "c", "q", [9.0] * 10, [1.0] * 10, 0.0, warned=[True] * 8 + [False] * 2, expect="warn")
    assert not w2.ok
    with pytest.raises(AssertionError, match="j/c/q"):
        check_coverage([w2])


def test_named_warnings():
    w = named("coloured-noise", "the residual is   not white")
    assert w == "coloured-noise: the residual is not white"
    assert warning_name(w) == "coloured-noise" and has_warning([w, "plain"], "coloured-noise")
    assert warning_names(["plain text", w]) == ("coloured-noise",)
    with pytest.raises(ValueError):
        named("Not Kebab", "x")


def test_mc_seeds(monkeypatch):
    monkeypatch.delenv("SENSCAL_MC", raising=False)
    assert mc_seeds(400) == 200 and mc_seeds(400, 150) == 150 and mc_seeds(100) == 100
    monkeypatch.setenv("SENSCAL_MC", "full")
    assert mc_seeds(400, 150) == 400


def test_emit_warnings_strict_and_markup(capsys):
    from senscal.cli.common import emit_warnings
    from senscal.errors import DiagnosticError

    emit_warnings(["x-y: serial [/bold] ok"], strict=False)
    assert "[/bold]" in capsys.readouterr().err
    with pytest.raises(DiagnosticError) as exc:
        emit_warnings([named("a-b", "one"), "two"], strict=True)
    assert exc.value.exit_code == 3 and "a-b: one" in str(exc.value)
