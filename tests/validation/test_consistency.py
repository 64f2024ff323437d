"""The block-refit consistency check (senscal.consistency)."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.consistency import ALPHA, block_consistency, split_blocks
from senscal.diagnostics import warning_name
from senscal.validation import wilson_interval


def _mean_fit(y):
    def fit(idx):
        b = y[idx]
        return {"offset": (b.mean(), b.std(ddof=1) / np.sqrt(b.size)),
                "spread": (b.std(ddof=1), b.std(ddof=1) / np.sqrt(2 * (b.size - 1)))}
    return fit


def test_split_blocks():
    parts = split_blocks(10, 3)
    assert [p.tolist() for p in parts] == [[0, 1, 2], [3, 4, 5, 6], [7, 8, 9]]
    with pytest.raises(ValueError):
        split_blocks(3, 4)


def test_false_alarm_rate_is_alpha_on_a_record_that_meets_its_model():
    rng = np.random.default_rng(1)
    m = 1000
    fired = sum(not block_consistency(_mean_fit(rng.normal(0.3, 0.05, 400)), split_blocks(400, 4)).consistent
                for _ in range(m))
    lo, hi = wilson_interval(fired, m)
    # Bonferroni over two quantities: the rate is at most ALPHA (a little below it); the 99.9 % Wilson
    # interval of the observed rate must reach down to it.
    assert lo <= ALPHA


def test_a_step_is_named_with_its_birge_ratio():
    rng = np.random.default_rng(2)
    y = rng.normal(0.3, 0.05, 4000)
    y[2000:] += 0.01   # a step of 4 u of a block mean (u = 0.05 / sqrt(1000) = 0.0016)
    res = block_consistency(_mean_fit(y), split_blocks(y.size, 4))
    assert not res.consistent
    bad = {q.name: q for q in res.failing}
    assert "offset" in bad and bad["offset"].birge_ratio > 2 and bad["offset"].dof == 3
    w = res.warning("channel 'x': ")
    assert warning_name(w) == "inconsistent-blocks" and "offset" in w and "channel 'x'" in w
    assert res.to_dict()["quantities"]["offset"]["consistent"] is False


def test_phases_are_compared_on_the_circle_and_failed_blocks_left_out():
    from senscal.errors import DataError

    vals = iter([(np.pi - 0.001, 0.01), (-np.pi + 0.001, 0.01), None, (np.pi - 0.002, 0.01)])

    def fit(idx):
        v = next(vals)
        if v is None:
            raise DataError("block could not be fitted")
        return {"phase": v}

    res = block_consistency(fit, split_blocks(40, 4), circular=("phase",))
    assert res.n_blocks == 3 and res.consistent


def test_u_from_few_degrees_of_freedom_widens_the_limit():
    from scipy.stats import chi2

    vals = [(0.0, 1.0), (1.0, 1.0), (-1.0, 1.0), (0.5, 1.0)]
    known = block_consistency(lambda idx: {"x": vals[int(idx[0]) // 10]}, split_blocks(40, 4))
    few = block_consistency(lambda idx: {"x": (*vals[int(idx[0]) // 10], 10.0)}, split_blocks(40, 4))
    assert known.quantities[0].limit == pytest.approx(chi2.isf(ALPHA, 3))
    # u^2 from 10 dof: the scatter ratio is F(3, 10), whose 1 % point is 6.55 (x 3 = 19.7 > 11.3).
    assert few.quantities[0].limit == pytest.approx(3 * 6.552, rel=1e-3)
    assert few.quantities[0].chi2 == known.quantities[0].chi2
