"""Monte-Carlo coverage of ``senscal shock``'s peak-ratio sensitivity and transfer function (issue 28).

CI runs a few seeds per scenario (three pulses each, about 0.4 s a seed), which
only catches gross miscoverage under the 99.9 % Wilson rule of
:func:`senscal.validation.check_coverage`; ``SENSCAL_MC=full`` or
``benchmarks/bench_coverage.py shock`` runs the full 200.
"""

from __future__ import annotations

import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.shock import SCENARIOS


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_coverage(case):
    run = SCENARIOS[case]
    rows = run(mc_seeds(run.full_seeds, run.ci_seeds), 20_000)
    assert [r.quantity for r in rows][0] == "sensitivity@0.05ms" and len(rows) == 15
    check_coverage(rows)
