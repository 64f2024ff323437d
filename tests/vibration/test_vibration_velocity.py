"""Velocity-sensor sensitivity against a position reference (hydraulic rig)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.simulate.vibration import simulate_hydraulic
from senscal.vibration import velocity_calibration, velocity_point


def _points(seed, **kw):
    recs, truth = simulate_hydraulic(seed=seed, **kw)
    return [velocity_point(r["position"], r["velocity"], r.time) for r in recs], truth


def test_mean_sensitivity_matches_truth_within_its_uncertainty():
    pts, truth = _points(seed=21)
    cal = velocity_calibration(pts)
    assert abs(cal.sensitivity - truth["sensitivity"]) < 2 * cal.u_sensitivity  # within U (k=2)
    for p, tr in zip(pts, truth["points"]):
        assert abs(p.sensitivity - tr["sensitivity"]) < 2 * p.u_sensitivity
        assert abs(math.degrees(p.phase) - tr["phase_deg"]) < 2 * math.degrees(p.u_phase)
        assert p.frequency == pytest.approx(tr["frequency_hz"], abs=4 * p.u_frequency)
    # the spread over points is what the fits predict (same noise): within a factor 2
    rms_u = math.sqrt(np.mean([p.budget.component("sine fits").standard_uncertainty ** 2 for p in pts]))
    assert 0.5 < cal.sensitivity_std / rms_u < 2.0


def test_point_uncertainties_match_monte_carlo_spread():
    n_mc = 30
    freqs = [1.0, 3.5]
    est = np.empty((n_mc, 2, 2))
    rep = np.empty((n_mc, 2, 2))
    for k in range(n_mc):
        pts, _ = _points(seed=500 + k, frequencies=freqs, periods=4.3, min_duration=1.0)
        est[k] = [[p.sensitivity, p.phase] for p in pts]
        rep[k] = [[p.u_sensitivity, p.u_phase] for p in pts]
    ratio = rep.mean(axis=0) / est.std(axis=0, ddof=1)
    assert np.all(ratio > 0.5) and np.all(ratio < 2.0), ratio


def test_given_frequency_matches_estimated_frequency():
    recs, truth = simulate_hydraulic(frequencies=[2.0], seed=3)
    r = recs[0]
    a = velocity_point(r["position"], r["velocity"], r.time)
    b = velocity_point(r["position"], r["velocity"], r.time, freq=2.0)
    assert b.u_frequency == 0.0
    assert abs(a.sensitivity - b.sensitivity) < 2 * a.u_sensitivity
    assert abs(a.phase - b.phase) < 2 * a.u_phase


def test_offset_drift_is_needed_for_an_unbiased_sensitivity():
    # A strong drift on a record of non-whole periods biases the fit without
    # the drift term; with it (the default) the truth is recovered.
    recs, truth = simulate_hydraulic(frequencies=[1.0], seed=4, drift=0.02, periods=2.3, min_duration=0.0)
    r = recs[0]
    good = velocity_point(r["position"], r["velocity"], r.time)
    bad = velocity_point(r["position"], r["velocity"], r.time, drift=False)
    assert abs(good.sensitivity - truth["sensitivity"]) < 2 * good.u_sensitivity
    # without the drift term the estimate is biased beyond its u, or the fit names the non-white residual
    from senscal.diagnostics import has_warning

    assert (abs(bad.sensitivity - truth["sensitivity"]) > 4 * bad.u_sensitivity
            or has_warning(bad.warnings, "coloured-noise"))
    assert not has_warning(good.warnings, "coloured-noise")


def test_type_b_position_component_and_scaling():
    recs, _ = simulate_hydraulic(frequencies=[1.5, 2.5], seed=5)
    pts = [velocity_point(r["position"], r["velocity"], r.time, u_position=0.001) for r in recs]
    p = pts[0]
    ua = p.budget.component("sine fits").standard_uncertainty
    assert p.u_sensitivity == pytest.approx(math.hypot(ua, 0.001 * p.sensitivity), rel=1e-12)
    # scaling the sensor output scales S and u by the same factor, phase unchanged
    r = recs[0]
    q = velocity_point(r["position"], 3.0 * r["velocity"], r.time)
    p0 = velocity_point(r["position"], r["velocity"], r.time)
    assert q.sensitivity == pytest.approx(3 * p0.sensitivity, rel=1e-9)
    assert q.u_sensitivity == pytest.approx(3 * p0.u_sensitivity, rel=1e-6)
    assert q.phase == pytest.approx(p0.phase, abs=1e-9)
    with pytest.raises(InputError):
        velocity_calibration([])


def test_distorted_motion_with_harmonics_fitted():
    # 3 % third harmonic in the cylinder motion, short records of non-whole periods:
    # fitting the harmonics recovers the fundamental's sensitivity within U, and
    # the harmonic no longer counts as noise (its velocity is 9 % of the fundamental's,
    # far above the 0.3 mV noise), so u shrinks.
    recs, truth = simulate_hydraulic(frequencies=[1.0, 2.0, 3.0], seed=12, distortion=0.03, periods=2.4, min_duration=0.0)
    for r, tr in zip(recs, truth["points"]):
        p = velocity_point(r["position"], r["velocity"], r.time, harmonics=3)
        assert abs(p.sensitivity - tr["sensitivity"]) < 2 * p.u_sensitivity
        assert p.u_sensitivity < velocity_point(r["position"], r["velocity"], r.time).u_sensitivity
        assert abs(math.degrees(p.phase) - tr["phase_deg"]) < 2 * math.degrees(p.u_phase)
