"""Small simulated shaft runs shared by the shaft tests (cached: simulations are the slow part)."""

from __future__ import annotations

import functools

from senscal.simulate.shaft import simulate_shaft


@functools.lru_cache(maxsize=None)
def runs(seed: int = 1, **kw):
    """(calibration, test, truth) with a 20 deg tilt and several percent speed ripple by default."""
    args = dict(tilt_deg=20.0, ripple=0.04, cal_duration=10.0, test_duration=6.0)
    args.update(kw)
    return simulate_shaft(seed=seed, **args)


def cached(seed: int = 1, **kw):
    return runs(seed, **dict(sorted(kw.items())))
