"""Monte-Carlo coverage of the gfimu rate band (pointwise over time and seeds) and its named warnings.

Seeds: ``mc_seeds(full, ci)``; ``SENSCAL_MC=full`` runs the benchmark's 400 per scenario.  The CI counts
keep the whole file near a minute; a 99.9 % Wilson interval on 60 seeds still fails a band that covers
80 % instead of 95 %, and a warning must fire in every one of its 6-20 seeds (>= 95 %).
"""

from __future__ import annotations

import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.gfimu import SCENARIOS

CI_SEEDS = {"paper-white": 60, "three-axis-white": 100, "three-axis-smooth": 60, "paper-rest": 60, "paper-plain": 20,
            "paper-mounting": 20, "three-axis-mounting": 20, "three-axis-scale-0.05%": 10, "three-axis-scale-0.1%": 8,
            "paper-scale-0.05%": 6}


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_coverage(name):
    run = SCENARIOS[name]
    rows = run(mc_seeds(run.full_seeds, CI_SEEDS[name]), 0)
    # Every reported quantity has a row: the three rate axes, plus the rest offsets when a rest is marked.
    assert {r.quantity.split()[0] for r in rows} >= {"wx", "wy", "wz"}
    check_coverage(rows)
