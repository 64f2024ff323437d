"""Allan deviation against closed-form theory (senscal.drift.allan)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binom

from senscal.drift.allan import FLICKER_FACTOR, allan_deviation, identify_noise
from senscal.errors import TooFewSamplesError

FS = 10.0
N_SAMPLES = 4096


def _white(rng, n, sigma=1.0):
    return rng.normal(0.0, sigma, n)


def _rw(rng, n, k=1.0):
    """Discrete random walk of rate: steps of variance K^2 / fs."""
    return np.cumsum(rng.normal(0.0, k / math.sqrt(FS), n))


def _flicker(rng, n, h=1.0):
    """One-sided PSD h/f by a 1/sqrt(f) filter on white noise in the frequency domain (DC removed)."""
    f = np.fft.rfftfreq(n, 1 / FS)
    w = np.fft.rfft(rng.normal(0.0, 1.0, n))
    g = np.zeros_like(f)
    g[1:] = np.sqrt(h / f[1:] * FS / 2)  # white N(0,1) has one-sided PSD 2/fs
    return np.fft.irfft(w * g, n)


def _flicker_theory(n, m, h=1.0):
    """Exact expected ADEV of _flicker: sum over bins of its variance times the discrete Allan filter."""
    f = np.fft.rfftfreq(n, 1 / FS)[1:]
    var_k = h / f * FS / n  # variance per bin of the one-sided spectrum (x2 for the two sides, /2 per rfft bin)
    var_k[-1] /= 2 if n % 2 == 0 else 1
    x = np.pi * f * m / FS
    h2 = (np.sin(x) / (m * np.sin(np.pi * f / FS))) ** 2 * 4 * np.sin(x) ** 2
    return math.sqrt(0.5 * np.sum(var_k * h2))


THEORY = {
    "white": (_white, lambda m: 1.0 / math.sqrt(m)),                       # sigma / sqrt(tau fs)
    "rw": (_rw, lambda m: math.sqrt((2 * m * m + 1) / (6 * m) / FS)),      # K^2 tau/3 for large m (discrete exact)
    "flicker": (_flicker, lambda m: _flicker_theory(N_SAMPLES, m)),
}


def test_flicker_floor_constant():
    """Flicker FM of one-sided PSD h/f is flat at sqrt(2 ln 2 h): 0.664 B for a two-sided S = B^2/(2 pi f)."""
    n = 2 ** 16
    for m in (16, 64):
        assert _flicker_theory(n, m) == pytest.approx(math.sqrt(2 * math.log(2)), rel=0.05)
    assert FLICKER_FACTOR == pytest.approx(0.6643, abs=1e-4)


@pytest.mark.parametrize("noise", ["white", "rw", "flicker"])
def test_theory_inside_ci_binomial(noise):
    """Independent records, one tau each (cycling): inside-CI count consistent with a 68.3 % level."""
    gen, theory = THEORY[noise]
    rng = np.random.default_rng({"white": 1, "rw": 2, "flicker": 3}[noise])
    reps = 150
    inside = 0
    for r in range(reps):
        res = allan_deviation(gen(rng, N_SAMPLES), FS, noise=noise)
        i = r % (res.taus.size - 2)  # the last two octaves have too few degrees of freedom for the simple edf
        th = theory(int(res.m[i]))
        inside += res.lower[i] <= th <= res.upper[i]
    p = 0.683
    lo, hi = binom.ppf(0.0005, reps, p), binom.ppf(0.9995, reps, p)
    assert lo <= inside <= hi, (inside, lo, hi)


def test_auto_noise_types_follow_slope():
    rng = np.random.default_rng(5)
    assert set(allan_deviation(_white(rng, 8192), FS).noise[:8]) == {"white"}
    assert set(allan_deviation(_rw(rng, 8192), FS).noise[:8]) == {"rw"}


def test_identify_n_and_k():
    rng = np.random.default_rng(7)
    n = 200_000
    sigma, k = 0.5, 2e-2
    y = _white(rng, n, sigma) + _rw(rng, n, k)
    res = allan_deviation(y, FS)
    lev = identify_noise(res)
    n_true = sigma / math.sqrt(FS)
    assert abs(lev.N - n_true) <= 2 * lev.u_N, (lev.N, n_true, lev.u_N)
    assert lev.K is not None and abs(lev.K - k) <= 2 * lev.u_K, (lev.K, k, lev.u_K)
    assert lev.B > 0 and lev.u_B > 0


def _slow_oadev(y, fs, m):
    """Direct overlapping ADEV from cluster means (IEEE 952 definition)."""
    means = np.array([y[i:i + m].mean() for i in range(len(y) - m + 1)])
    d = means[m:] - means[:-m]
    return math.sqrt(0.5 * np.mean(d ** 2))


def _slow_mdev(y, fs, m):
    tau0 = 1 / fs
    x = np.concatenate(([0.0], np.cumsum(y))) * tau0
    npts, tot, cnt = len(x), 0.0, 0
    for j in range(npts - 3 * m + 1):
        s = sum(x[i + 2 * m] - 2 * x[i + m] + x[i] for i in range(j, j + m))
        tot += s * s
        cnt += 1
    return math.sqrt(tot / (2 * m * m * (m * tau0) ** 2 * cnt))


def test_fast_equals_slow_direct_formula():
    rng = np.random.default_rng(11)
    y = 3.0 + rng.normal(size=200) + np.cumsum(rng.normal(scale=0.1, size=200))
    res = allan_deviation(y, 2.0)
    mres = allan_deviation(y, 2.0, kind="modified")
    for i, m in enumerate(res.m):
        assert res.dev[i] == pytest.approx(_slow_oadev(y, 2.0, int(m)), rel=1e-10)
    for i, m in enumerate(mres.m):
        assert mres.dev[i] == pytest.approx(_slow_mdev(y, 2.0, int(m)), rel=1e-10)
    assert mres.dev[0] == pytest.approx(res.dev[0], rel=1e-12)  # identical at m = 1


def test_user_taus_and_too_short():
    rng = np.random.default_rng(0)
    res = allan_deviation(rng.normal(size=100), 10.0, taus=[0.1, 1.0, 5.0])
    assert list(res.m) == [1, 10] and res.warnings
    with pytest.raises(TooFewSamplesError):
        allan_deviation(rng.normal(size=100), 10.0, taus=[4.0])
    with pytest.raises(TooFewSamplesError):
        allan_deviation([1.0, 2.0], 10.0)
