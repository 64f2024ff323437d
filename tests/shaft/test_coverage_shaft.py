"""Monte-Carlo coverage of every number ``shaft calibrate`` / ``shaft compensate`` report with a u.

CI runs 60 seeds per scenario (a coverage of 85 % or less fails with high
probability; the 99.9 % Wilson rule of :func:`senscal.validation.check_coverage`
keeps false alarms below 0.1 % per row); ``SENSCAL_MC=full`` or
``benchmarks/bench_coverage.py shaft`` runs the full 400.
"""

from __future__ import annotations

import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.shaft import SCENARIOS

CALIBRATION = ["amplitude", "phase", "offset", "tilt", "bias"]


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_coverage(case):
    run = SCENARIOS[case]
    rows = run(mc_seeds(run.full_seeds, 60), 10_000)
    quantities = [r.quantity for r in rows]
    assert quantities[:5] == CALIBRATION
    if case == "white":
        assert quantities[5:] == ["centripetal_coefficient", "misalignment", "bias_change"]
    check_coverage(rows)
