"""The sort-free input checks of calibrate_point decide as their sorted definitions do (issue 28)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal.primary.core import _largest_gap, _quantile_above


def _gap_sorted(ang):
    a = np.sort(ang)
    return float(np.max(np.diff(np.concatenate([a, a[:1] + 2 * math.pi]))))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("arc_deg", [30, 80, 89.5, 90.5, 100, 200, 359])
def test_largest_gap_decides_as_the_sorted_gap(seed, arc_deg):
    # angles covering a random arc (noise-free and noisy): the check (gap > pi/2) is the sorted one's
    rng = np.random.default_rng(seed)
    start = rng.uniform(-math.pi, math.pi)
    ang = start + np.radians(arc_deg) * rng.uniform(0, 1, 20_000)
    ang = (ang + math.pi) % (2 * math.pi) - math.pi
    exact = _gap_sorted(ang)
    got = _largest_gap(ang)
    assert (got > math.pi / 2) == (exact > math.pi / 2)
    if got > math.pi / 2:
        assert got == exact  # the message's value is the sorted one
    else:
        assert got >= exact  # an upper bound below the quarter turn


@pytest.mark.parametrize("seed", range(5))
def test_quantile_above_is_numpy_quantile(seed):
    rng = np.random.default_rng(seed)
    v = np.abs(rng.normal(size=rng.integers(5, 3000)))
    for q in (0.5, 0.9, 0.999, 1.0):
        for lim in np.concatenate([np.quantile(v, [0.3, 0.5, 0.9, 0.999, 1.0]), v[:20], [0.0, 10.0]]):
            assert _quantile_above(v, q, float(lim)) == bool(np.quantile(v, q) > lim)
