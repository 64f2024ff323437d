"""Monte-Carlo coverage of the drift job (issue 14, drift items 1-5).

Seed counts: each record needs its own maximum-likelihood search (0.1-1.6 s
of CPU per record), so CI runs 20-40 seeds per scenario and the benchmark
(``SENSCAL_MC=full``, ``benchmarks/bench_coverage.py drift``) 200.  The
scenarios that compare models (three or more extra searches per record) and
the warn-only ones get the fewest: a warning that must fire in >= 95 % of
seeds fails on 20 seeds as soon as two miss.
"""

from __future__ import annotations

import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.drift import SCENARIOS

CI_SEEDS = {"white": 30, "gm-signal+ramp": 30, "ramp-rw-model": 20, "known": 40, "covariate": 40,
            "reference-defaulted": 20, "wrong-tau": 20,
            # Issue 26 departures: every record fits five or six models (2-4 s of CPU); the benchmark runs 200.
            # The lag cases must cover (the lag is averaged into u).
            "ar1-noise": 16, "covariate-lag-3": 6, "covariate-lag-20": 8, "covariate-lag-60": 6,
            # False alarms where the model asked for is true (a "no warning" row judged by the coverage rule:
            # 16 seeds fail a check that names half of them).
            "white-compare": 16, "covariate-lag-0": 16,
            # The tau asserted (no average over tau): must cover with the tighter u.
            "known-tau": 16}


def test_every_scenario_has_a_ci_seed_count():
    assert set(CI_SEEDS) == set(SCENARIOS)


#: Departures the job neither covers nor names in >= 95 % of records yet, and false alarms above the rule:
#: none since issue 26 item 5 (a covariate lag the record does not fix is averaged into u; the lag-free
#: one-sensor records, where the former lag check named two thirds, are named in about 6 %).  A Gauss-Markov
#: tau not asserted is averaged over too (issue 26): wrong-tau is judged by the coverage rule.
OPEN: set[str] = set()


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(
    reason="open departure", run=False))
    if n in OPEN else n for n in sorted(SCENARIOS)])
def test_coverage(name):
    run = SCENARIOS[name]
    rows = run(mc_seeds(run.full_seeds, CI_SEEDS[name]), 1000)
    assert rows and all(r.job == "drift" for r in rows)
    check_coverage(rows)
