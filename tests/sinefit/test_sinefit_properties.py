"""Invariants of the sine fit (hypothesis)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from senscal import fit_sine
from senscal.sinefit import wrap_phase

FS, N = 500.0, 600
T = np.arange(N) / FS

amp = st.floats(0.1, 10.0)
phase = st.floats(-math.pi, math.pi)
offset = st.floats(-100.0, 100.0)
freq = st.floats(2.0, 60.0)
seed = st.integers(0, 2**31 - 1)


def _make(a, p, c, f, s, noise=0.05):
    rng = np.random.default_rng(s)
    return a * np.sin(2 * math.pi * f * T + p) + c + rng.normal(0, noise, N)


@given(a=amp, p=phase, c=offset, f=freq, s=seed, k=st.floats(-1e3, 1e3).filter(lambda v: abs(v) > 1e-3))
def test_scaling_scales_amplitude_and_offset(a, p, c, f, s, k):
    y = _make(a, p, c, f, s)
    f1 = fit_sine(y, T, freq=f)
    f2 = fit_sine(k * y, T, freq=f)
    assert f2.amplitude == pytest.approx(abs(k) * f1.amplitude, rel=1e-9)
    assert f2.offset == pytest.approx(k * f1.offset, rel=1e-9, abs=1e-9 * abs(k))
    assert f2.u_amplitude == pytest.approx(abs(k) * f1.u_amplitude, rel=1e-7)
    expected = f1.phase + (math.pi if k < 0 else 0.0)
    assert math.remainder(f2.phase - expected, 2 * math.pi) == pytest.approx(0, abs=1e-9)


@given(a=amp, p=phase, c=offset, f=freq, s=seed, shift=st.floats(-1e4, 1e4))
def test_time_shift_changes_only_phase(a, p, c, f, s, shift):
    y = _make(a, p, c, f, s)
    f1 = fit_sine(y, T, freq=f)
    f2 = fit_sine(y, T + shift, freq=f)
    assert f2.amplitude == pytest.approx(f1.amplitude, rel=1e-8)
    assert f2.offset == pytest.approx(f1.offset, rel=1e-8, abs=1e-8)
    assert f2.u_phase == pytest.approx(f1.u_phase, rel=1e-6)
    d = math.remainder(f2.phase - (f1.phase - 2 * math.pi * f * shift), 2 * math.pi)
    assert d == pytest.approx(0, abs=1e-6)


@given(s=seed, perm_seed=seed)
def test_channel_permutation_permutes_results(s, perm_seed):
    rng = np.random.default_rng(s)
    y = np.stack([_make(rng.uniform(0.5, 3), rng.uniform(-3, 3), rng.uniform(-5, 5), 7.0, s + i) for i in range(5)])
    perm = np.random.default_rng(perm_seed).permutation(5)
    a = fit_sine(y, T, freq=7.0)
    b = fit_sine(y[perm], T, freq=7.0)
    for name in ("amplitude", "phase", "offset", "u_amplitude", "residual_rms"):
        np.testing.assert_allclose(getattr(b, name), np.asarray(getattr(a, name))[perm], rtol=1e-12, atol=1e-14)


@given(a=amp, p=phase, c=offset, f=freq, s=seed)
def test_batch_equals_single(a, p, c, f, s):
    y = np.stack([_make(a, p, c, f, s), _make(a * 2, -p, c, f, s + 1)])
    batch = fit_sine(y, T, freq=f)
    for i in range(2):
        single = fit_sine(y[i], T, freq=f)
        one = batch.channel(i)
        for name in ("amplitude", "phase", "offset", "u_amplitude", "u_phase", "u_offset", "snr_db"):
            assert getattr(one, name) == pytest.approx(getattr(single, name), rel=1e-10, abs=1e-12)


@given(x=st.floats(-1e6, 1e6))
def test_phase_wrap_interval(x):
    w = wrap_phase(x)
    assert -math.pi < w <= math.pi
    assert math.remainder(w - x, 2 * math.pi) == pytest.approx(0, abs=1e-9 * max(1, abs(x)))


def test_wrap_maps_minus_pi_to_pi():
    assert wrap_phase(-math.pi) == pytest.approx(math.pi)
    assert wrap_phase(np.array([-math.pi, 3 * math.pi]))[0] == pytest.approx(math.pi)


@given(p=phase, s=seed)
def test_reported_phase_in_interval(p, s):
    y = _make(1.0, p, 0.0, 5.0, s)
    fit = fit_sine(y, T)
    assert -math.pi < fit.phase <= math.pi
