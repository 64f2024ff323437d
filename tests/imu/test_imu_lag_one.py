"""The gyro's lag-one correlation (``gyro-noise-coloured``) under a warm-up's trend within the poses (issue 27).

A gyro bias that follows the temperature moves within a pose (10 K over the 20 s still start at 2e-4 rad/s per
K is one per-sample noise); about the pose mean that trend read as colour and named ``gyro-noise-coloured`` in
~10 % of white warm-up sessions (21 of 200 seeds of the ``temperature`` case).  The estimate is taken about a
straight line per pose with the line's white-noise bias added back: thresholds are the estimator's own
N(0, 1/N) distribution for white noise.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from senscal.imu.calibrate import _lag_one

#: One 20 s still start and 30 poses of 2.8 s at 100 Hz, as the simulator's sessions.
STARTS = np.concatenate([[0], 2000 + 450 * np.arange(30)])
STOPS = np.concatenate([[2000], 2000 + 450 * np.arange(30) + 280])
N = int(np.sum(STOPS - STARTS))
Q999 = stats.norm.ppf(0.9995)


def _record(rng, noise):
    x = noise(rng, (3, int(STOPS[-1])))
    # A bias trend of one per-sample noise over the still start and a tenth of it over each pose (a warm-up).
    for a, b in zip(STARTS, STOPS):
        x[:, a:b] += np.linspace(0.0, 1.0 if a == 0 else 0.1, b - a)[None, :]
    return x


def test_white_with_trend_is_no_colour():
    rng = np.random.default_rng(5)
    r = np.array([_lag_one(_record(rng, lambda g, s: g.normal(size=s)), STARTS, STOPS) for _ in range(200)])
    # Each estimate ~ N(0, 1/N): the 99.9 % point per estimate, and the mean of 600 estimates at 99.9 %.
    assert np.max(np.abs(r)) < stats.norm.ppf(1 - 0.0005 / r.size) / math.sqrt(N)
    assert abs(float(r.mean())) < Q999 / math.sqrt(N * r.size)
    assert abs(float(r.std()) * math.sqrt(N) - 1.0) < Q999 * math.sqrt(0.5 / r.size)


def test_weak_colour_still_seen():
    from scipy.signal import lfilter

    rng = np.random.default_rng(6)
    phi = 0.2

    def ar1(g, s):
        return lfilter([math.sqrt(1 - phi ** 2)], [1.0, -phi], g.normal(size=s), axis=1)

    r = _lag_one(_record(rng, ar1), STARTS, STOPS)
    # AR(1): r1 estimates phi with sd ~ sqrt((1 - phi^2) / N).
    assert np.all(np.abs(r - phi) < Q999 * math.sqrt((1 - phi ** 2) / N))
    assert np.all(r > Q999 / math.sqrt(N))  # named
