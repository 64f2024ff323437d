"""The speed forms of the sine fit's residual tests equal their definitions (issue 28)."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.sinefit import variance as V


@pytest.mark.parametrize("n", [64, 97, 1000, 4096, 10007, 120_000])
def test_low_frequency_power_is_the_periodogram_sum(n):
    # the factored DFT against the K lowest bins of a plain FFT (any n: divisible, prime, padded)
    rng = np.random.default_rng(n)
    r = rng.normal(size=(3, n)) + np.linspace(0.0, 2.0, n)
    f = np.fft.fft(r, axis=-1)[:, 1:V.LOWFREQ_BINS + 1]
    want = np.sum(np.abs(f) ** 2, axis=-1) / n
    got = V.low_frequency_power(r)
    assert np.allclose(got, want, rtol=1e-12, atol=0.0)
    assert V.low_frequency_power(r[0]).shape == (1,)


def test_phase_variance_batch_is_the_regression():
    # Koenker's N R^2 and the coefficients against an explicit least-squares regression of r^2 on 1, cos, sin
    rng = np.random.default_rng(3)
    n = 5000
    th = rng.uniform(0, 2 * np.pi, n)
    c2, s2 = np.cos(2 * th), np.sin(2 * th)
    r = rng.normal(size=(4, n)) * (1.0 + 0.3 * np.arange(4)[:, None] * c2)
    stat, coef, xinv, s2e = V.phase_variance_batch(r, c2, s2)
    x = np.column_stack([np.ones(n), c2, s2])
    for i in range(4):
        y = r[i] ** 2
        b, *_ = np.linalg.lstsq(x, y, rcond=None)
        res = y - x @ b
        r2 = 1.0 - (res @ res) / np.sum((y - y.mean()) ** 2)
        assert np.allclose(coef[i], b, rtol=1e-9, atol=1e-12)
        assert stat[i] == pytest.approx(n * r2, rel=1e-8, abs=1e-8)
        assert s2e[i] == pytest.approx((res @ res) / (n - 3), rel=1e-9)
    assert np.allclose(xinv, np.linalg.inv(x.T @ x), rtol=1e-10)


def test_blocked_sandwich_is_the_sandwich():
    rng = np.random.default_rng(5)
    n, p = 40_000, 5
    a = rng.normal(size=(p, n)).T  # a column-major (N, p) view, as the fast path passes it
    var = rng.uniform(0.5, 2.0, n)
    g = np.linalg.inv(a.T @ a)
    want = g @ ((a * var[:, None]).T @ a) @ g * (n / (n - p))
    assert np.allclose(V.sandwich_covariance(a, g, var, p), 0.5 * (want + want.T), rtol=1e-11)
