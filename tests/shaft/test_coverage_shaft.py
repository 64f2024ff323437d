"""Monte-Carlo coverage of every number ``shaft calibrate`` / ``shaft compensate`` report with a u.

CI runs 60 seeds per scenario (a coverage of 85 % or less fails with high
probability; the 99.9 % Wilson rule of :func:`senscal.validation.check_coverage`
keeps false alarms below 0.1 % per row); ``SENSCAL_MC=full`` or
``benchmarks/bench_coverage.py shaft`` runs the full 400.  The 60-turn
scenario (0.3 s a seed) runs 20 seeds in CI, which only catches gross
miscoverage; the regressor droop it exists for is pinned in CI by a
noise-free test below.  The issue-25 scenarios (angle-locked ripple, 4 %
ripple at 0.7 Hz, eccentric disc) run 20 seeds in CI too; their cases are
pinned seed by seed in test_shaft_issue25.py.
"""

from __future__ import annotations

import math

import pytest

from senscal.shaft import calibrate_gravity
from senscal.simulate.shaft import simulate_shaft
from senscal.validation import check_coverage, mc_seeds
from senscal.validation.shaft import SCENARIOS

CALIBRATION = ["amplitude", "phase", "offset", "tilt", "bias"]


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_coverage(case):
    run = SCENARIOS[case]
    rows = run(mc_seeds(run.full_seeds, getattr(run, "ci_seeds", 60)), 10_000)
    quantities = [r.quantity for r in rows]
    assert quantities[:5] == CALIBRATION
    if case == "white":
        assert quantities[5:] == ["centripetal_coefficient", "misalignment", "bias_change"]
    check_coverage(rows)


def test_ripple_coefficient_has_no_regressor_droop():
    """Noise-free, unquantised run: the response to angular acceleration is S r cos(d) to the regressor's droop.

    A septic Savitzky-Golay second derivative over 0.13 s droops 9e-6 at the
    2.7 Hz ripple (the quintic over 0.1 s: 6.7e-4, which read the coefficient
    high by 1.2 u on 60-turn runs, 81 % coverage); 1e-4 leaves room for the 1e-5 the 5.4 Hz
    part of w^2 and the gravity sidebands move it, and fails the quintic.
    """
    cal, _, truth = simulate_shaft(seed=3, cal_duration=10.0, test_duration=0.5, noise=0.0,
                                   encoder_counts=2**40, wrap=False)
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    exact = truth["radius"] * math.cos(math.radians(truth["misalignment_deg"]))
    assert m.nuisance == ("alpha", "speed2")
    assert abs(m.ripple_coefficient / exact - 1.0) < 1e-4, m.ripple_coefficient / exact - 1.0


def test_ripple_and_centripetal_coefficients_are_diagnostics_without_u():
    """Their spectral u does not cover (quantisation bursts at the encoder's sampling resonance): no u, listed."""
    cal, _, truth = simulate_shaft(seed=4, cal_duration=10.0, test_duration=0.5)
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    assert m.centripetal_coefficient is not None and m.u_centripetal_coefficient is None
    assert math.isfinite(m.ripple_coefficient) and m.u_ripple_coefficient is None
    assert m.diagnostic == ("ripple_coefficient", "centripetal_coefficient")
    d = m.to_dict()
    assert d["u_centripetal_coefficient"] is None and d["u_ripple_coefficient"] is None
    assert d["diagnostic"] == ["ripple_coefficient", "centripetal_coefficient"]
    given = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", radius=truth["radius"])
    assert given.u_ripple_coefficient == 0.0 and given.diagnostic == ("centripetal_coefficient",)
