"""Monte-Carlo coverage of the sine fit's k=2 intervals, white and coloured noise.

Each scenario runs ``mc_seeds(400, 200)`` seeds (400 with SENSCAL_MC=full);
:func:`senscal.validation.check_coverage` fails a row only when its 99.9 %
Wilson interval misses 93-97 %.
"""

from __future__ import annotations

import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.sinefit import INSTRUMENT_SCENARIOS, SCENARIOS


# The instrument departures have their own test (test_coverage_instrument.py, fewer seeds in CI).
@pytest.mark.parametrize("case", sorted(set(SCENARIOS) - set(INSTRUMENT_SCENARIOS)))
def test_sinefit_coverage(case):
    run = SCENARIOS[case]
    rows = run(mc_seeds(run.full_seeds, 200), 0)
    check_coverage(rows)
    names = {r.quantity for r in rows}
    if case in ("white", "ar1-0.5", "ar1-0.9"):
        assert names >= {"amplitude (3p)", "phase (3p)", "offset (3p)", "amplitude (4p)", "phase (4p)",
                         "offset (4p)", "frequency (4p)"}
    if case in ("ar1-0.5", "ar1-0.9"):
        # The coloured covariance is chosen by the test itself, on every seed.
        assert all(r.warned == 1.0 for r in rows)
    if case == "ar1-0.9-white-model":
        # The measurement, reproduced: the white covariance covers far too little.
        assert all(r.coverage < 0.6 for r in rows)
