"""Drift fit and due date against simulated histories with known truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from senscal.errors import DataError, TooFewSamplesError
from senscal.registry import due_time, fit_drift


def _history(rng, n, drift, u_rel=1e-3, v0=1.0, years=6.0):
    """Calibrations at irregular dates with stated standard uncertainties and matching noise."""
    t = np.sort(rng.uniform(0.0, years, n))
    t[0] = 0.0
    u = v0 * u_rel * rng.uniform(0.5, 2.0, n)
    y = v0 + drift * t + rng.normal(0.0, u)
    return t, y, u


def test_known_drift_is_recovered_with_honest_uncertainty():
    rng = np.random.default_rng(11)
    drift, n_mc = 2.0e-3, 2000
    est, u_rep, u_theory, z = [], [], [], []
    for _ in range(n_mc):
        t, y, u = _history(rng, 6, drift)
        f = fit_drift(t, y, u)
        a = np.column_stack([np.ones_like(t), t]) / u[:, None]
        u_th = math.sqrt(np.linalg.inv(a.T @ a)[1, 1])  # GUM H.3 with stated uncertainties
        est.append(f.drift_per_year)
        u_rep.append(f.u_drift_per_year)
        u_theory.append(u_th)
        z.append((f.drift_per_year - drift) / u_th)
    est, u_rep, z = np.array(est), np.array(u_rep), np.array(z)
    # Unbiased: the mean of 2000 estimates is within 4 standard errors of the truth.
    assert abs(est.mean() - drift) < 4 * np.mean(u_theory) / math.sqrt(n_mc)
    # The normalised errors are standard normal: their spread is 1 within 4 of its standard errors.
    assert abs(z.std() - 1.0) < 4 / math.sqrt(2 * n_mc)
    # Birge scaling only ever widens the stated uncertainty: coverage of ±2u is at least 95 % minus sampling.
    coverage = np.mean(np.abs(est - drift) < 2 * u_rep)
    assert coverage > 0.9545 - 4 * math.sqrt(0.9545 * 0.0455 / n_mc)


def test_no_drift_false_alarm_rate_is_alpha():
    rng = np.random.default_rng(12)
    n_mc = 2000
    flags = [fit_drift(*_history(rng, 5, 0.0)).significant for _ in range(n_mc)]
    rate = np.mean(flags)
    assert abs(rate - 0.05) < 4 * math.sqrt(0.05 * 0.95 / n_mc)


def test_exactly_flat_history_is_not_significant():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    y = 1.0 + 1e-3 * np.array([1.0, -1.0, -1.0, 1.0])  # residual pattern orthogonal to t: slope exactly 0
    f = fit_drift(t, y, np.full(4, 1e-3))
    assert f.drift_per_year == pytest.approx(0.0, abs=1e-15)
    assert not f.significant and f.p_value == pytest.approx(1.0)


@pytest.mark.parametrize("seed", range(8))
def test_matches_numpy_polyfit(seed):
    rng = np.random.default_rng(seed)
    t, y, u = _history(rng, 7, 1e-3, u_rel=float(rng.choice([1e-4, 1e-3, 1e-2])))
    f = fit_drift(t, y, u)
    coef, cov_unscaled = np.polyfit(t, y, 1, w=1 / u, cov="unscaled")
    _, cov_scaled = np.polyfit(t, y, 1, w=1 / u, cov=True)
    assert f.drift_per_year == pytest.approx(coef[0], rel=1e-9, abs=1e-15)
    assert f.value_at_epoch == pytest.approx(coef[1], rel=1e-12)
    expected = cov_scaled if f.scaled else cov_unscaled
    assert f.u_drift_per_year == pytest.approx(math.sqrt(expected[0, 0]), rel=1e-8)
    from scipy import stats

    p = 2 * (stats.t.sf(abs(f.z), f.dof) if f.scaled else stats.norm.sf(abs(f.z)))
    assert f.p_value == pytest.approx(p, rel=1e-9)


def test_refuses_fewer_than_two_records_and_single_date():
    with pytest.raises(TooFewSamplesError, match="at least two"):
        fit_drift([0.0], [1.0], [0.1])
    with pytest.raises(DataError, match="same date"):
        fit_drift([1.0, 1.0], [1.0, 1.1], [0.1, 0.1])
    with pytest.raises(DataError, match="positive"):
        fit_drift([0.0, 1.0], [1.0, 1.1], [0.1, 0.0])


def test_due_date_is_where_bound_meets_tolerance():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    y = 1.0 + 4e-3 * t
    f = fit_drift(t, y, np.full(4, 5e-4))
    due = due_time(f, t_last=3.0, reference=1.0, tolerance=0.02, k=2.0)
    value, u = f.predict(due.t_due)
    assert abs(value - 1.0) + 2 * u == pytest.approx(0.02, abs=1e-8)
    # The uncertainty makes the due date come before the noiseless crossing tol / drift = 5 years.
    assert 3.0 < due.t_due < 5.0 and not due.overdue
    # Already beyond the tolerance at the last record: overdue now.
    late = due_time(f, t_last=3.0, reference=1.0, tolerance=0.01)
    assert late.overdue and late.t_due == 3.0


def test_due_date_is_conservative_against_truth():
    """The k=2 bound reaches the tolerance before the true line does in about 97.7 % of histories."""
    rng = np.random.default_rng(13)
    drift, tol, n_mc = 2e-3, 0.02, 1000
    t_true = tol / drift
    early = []
    for _ in range(n_mc):
        t, y, u = _history(rng, 5, drift, years=4.0)
        f = fit_drift(t, y, u)
        d = due_time(f, t_last=float(t.max()), reference=1.0, tolerance=tol)
        early.append(d.t_due is not None and d.t_due <= t_true)
    assert np.mean(early) > 0.95


@given(scale=st.floats(1e-6, 1e6), shift=st.floats(-50, 50), seed=st.integers(0, 10_000))
def test_invariants_scale_and_epoch(scale, shift, seed):
    rng = np.random.default_rng(seed)
    t, y, u = _history(rng, 5, 1e-3)
    f = fit_drift(t, y, u)
    g = fit_drift(t + shift, scale * y, scale * u)
    assert g.drift_per_year == pytest.approx(scale * f.drift_per_year, rel=1e-6, abs=1e-9 * scale)
    assert g.u_drift_per_year == pytest.approx(scale * f.u_drift_per_year, rel=1e-6)
    assert g.z == pytest.approx(f.z, rel=1e-5, abs=1e-6)


def test_overdispersed_history_scales_uncertainty_like_polyfit():
    """Scatter 5x the stated uncertainties: the covariance is scaled (numpy's cov=True)."""
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 6.0, 12)
    u = np.full(12, 1e-3)
    y = 1.0 + 1e-3 * t + rng.normal(0.0, 5e-3, 12)
    f = fit_drift(t, y, u)
    _, cov_scaled = np.polyfit(t, y, 1, w=1 / u, cov=True)
    assert f.scaled and f.birge_ratio > 2
    from scipy import stats

    assert f.p_value == pytest.approx(2 * stats.t.sf(abs(f.z), 10), rel=1e-9)
    assert f.u_drift_per_year == pytest.approx(math.sqrt(cov_scaled[0, 0]), rel=1e-8)
