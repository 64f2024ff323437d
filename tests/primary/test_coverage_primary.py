"""Monte-Carlo coverage of ``senscal primary``'s sensitivity and phase at 10 Hz to 5 kHz (issue 28).

CI runs a few seeds per scenario (four frequency points each, ~2 s a seed), which
only catches gross miscoverage under the 99.9 % Wilson rule of
:func:`senscal.validation.check_coverage`; ``SENSCAL_MC=full`` or
``benchmarks/bench_coverage.py primary`` runs the full 200.
"""

from __future__ import annotations

import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.primary import REMOUNT_FREQ, SCENARIOS


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_coverage(case):
    run = SCENARIOS[case]
    rows = run(mc_seeds(run.full_seeds, run.ci_seeds), 10_000)
    # the remounted cases repeat one frequency (REMOUNT_FREQ); every other case starts at 10 Hz
    tag = f"{REMOUNT_FREQ:g}Hz" if case.startswith("remounted") else "10Hz"
    assert [r.quantity for r in rows][:2] == [f"sensitivity@{tag}", f"phase@{tag}"]
    check_coverage(rows)
