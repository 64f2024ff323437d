"""Accuracy of the sine fit against the Cramér-Rao bound on simulated truth.

Tolerances: a sample variance from M trials has relative standard deviation
sqrt(2/(M-1)); with M = 4000 that is 2.2 %, so the 10 % band the issue sets is
about 4.5 standard deviations wide.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal import fit_sine

M = 4000          # Monte-Carlo trials for the known-frequency fit (batched)
M_FREQ = 1200     # trials for the four-parameter fit (one GN solve each)


def _records(rng, m, n, fs, f, amp, phase, offset, sigma, t0=0.0):
    t = t0 + np.arange(n) / fs
    y = amp * np.sin(2 * math.pi * f * t + phase) + offset + rng.normal(0.0, sigma, (m, n))
    return t, y


@pytest.mark.parametrize(
    "f, offset, t0",
    [
        (7.3, 0.5, 0.0),        # 7.3 periods: non-integer number of periods
        (11.0, 1e3, 0.0),       # offset / amplitude = 1e3
        (7.3, 0.5, 1e5),        # time stamps far from zero
    ],
)
def test_known_frequency_meets_cramer_rao(f, offset, t0):
    rng = np.random.default_rng(42)
    n, fs, amp, phase, sigma = 1000, 1000.0, 1.0, 0.7, 0.1
    t, y = _records(rng, M, n, fs, f, amp, phase, offset, sigma, t0)
    fit = fit_sine(y, t, freq=f)
    crb_amp = 2 * sigma**2 / n
    crb_phase = 2 * sigma**2 / (n * amp**2)
    var_amp = np.var(fit.amplitude, ddof=1)
    d_phase = np.angle(np.exp(1j * (fit.phase - phase)))
    var_phase = np.var(d_phase, ddof=1)
    assert var_amp == pytest.approx(crb_amp, rel=0.10)
    assert var_phase == pytest.approx(crb_phase, rel=0.10)
    # Unbiased at this SNR: the mean is within 4 standard errors of the truth.
    assert abs(np.mean(fit.amplitude) - amp) < 4 * math.sqrt(crb_amp / M)
    assert abs(np.mean(d_phase)) < 4 * math.sqrt(crb_phase / M)
    assert abs(np.mean(fit.offset) - offset) < 4 * sigma / math.sqrt(n * M)
    # Reported uncertainties agree with the empirical spread.
    assert np.mean(fit.u_amplitude) == pytest.approx(np.std(fit.amplitude, ddof=1), rel=0.10)
    assert np.mean(fit.u_phase) == pytest.approx(np.std(d_phase, ddof=1), rel=0.10)
    assert np.mean(fit.u_offset) == pytest.approx(np.std(fit.offset, ddof=1), rel=0.10)


def test_unknown_frequency_meets_cramer_rao():
    rng = np.random.default_rng(7)
    n, fs, f, amp, phase, offset, sigma = 512, 1000.0, 37.7, 1.0, -1.1, 0.3, 0.1
    t, y = _records(rng, M_FREQ, n, fs, f, amp, phase, offset, sigma)
    fits = [fit_sine(y[i], t) for i in range(M_FREQ)]
    fr = np.array([x.frequency for x in fits])
    amps = np.array([x.amplitude for x in fits])
    u_f = np.array([x.u_frequency for x in fits])
    # CRB in rad/sample^2, converted to Hz^2.
    crb_w = 24 * sigma**2 / (amp**2 * n * (n**2 - 1))
    crb_f = crb_w * (fs / (2 * math.pi)) ** 2
    tol = 4 * math.sqrt(2 / (M_FREQ - 1))   # 4 sigma of a sample variance
    assert np.var(fr, ddof=1) == pytest.approx(crb_f, rel=max(0.10, tol))
    assert np.mean(u_f) == pytest.approx(np.std(fr, ddof=1), rel=max(0.10, tol / 2))
    assert np.var(amps, ddof=1) == pytest.approx(2 * sigma**2 / n, rel=max(0.10, tol))
    assert all(x.converged for x in fits)


def test_unknown_frequency_far_time_origin_keeps_frequency_accuracy():
    rng = np.random.default_rng(3)
    n, fs, f, sigma = 2000, 500.0, 13.37, 0.05
    t = 1e5 + np.arange(n) / fs
    y = 2.0 * np.sin(2 * math.pi * f * t + 0.2) + 1e3 + rng.normal(0, sigma, n)
    fit = fit_sine(y, t)
    assert abs(fit.frequency - f) < 4 * fit.u_frequency
    assert abs(fit.amplitude - 2.0) < 4 * fit.u_amplitude
    assert abs(fit.offset - 1e3) < 4 * fit.u_offset
    # Phase at t = 0 is honest: its uncertainty includes the frequency's
    # lever arm over 1e5 s, so it is consistent with the truth.
    d = math.remainder(fit.phase - 0.2, 2 * math.pi)
    assert abs(d) < 4 * fit.u_phase or fit.u_phase > math.pi


def test_harmonics_and_thd():
    rng = np.random.default_rng(5)
    fs, n, f = 2000.0, 4000, 10.0
    t = np.arange(n) / fs
    a = [1.0, 0.1, 0.05]
    ph = [0.3, -1.0, 2.0]
    y = sum(a[k] * np.sin(2 * math.pi * (k + 1) * f * t + ph[k]) for k in range(3)) + 0.2
    y = y + rng.normal(0, 0.01, n)
    fit = fit_sine(y, t, freq=f, harmonics=3)
    assert np.all(np.abs(fit.harmonic_amplitudes - a) < 4 * fit.u_harmonic_amplitudes)
    dph = np.angle(np.exp(1j * (fit.harmonic_phases - ph)))
    assert np.all(np.abs(dph) < 4 * fit.u_harmonic_phases)
    assert fit.thd == pytest.approx(math.hypot(0.1, 0.05) / 1.0, rel=0.02)
    # Frequency estimated with harmonics too.
    fit2 = fit_sine(y, t, harmonics=3)
    assert abs(fit2.frequency - f) < 4 * fit2.u_frequency


def test_drift_term():
    rng = np.random.default_rng(9)
    fs, n, f = 1000.0, 3000, 5.0
    t = np.arange(n) / fs
    y = np.sin(2 * math.pi * f * t) + 0.5 + 0.2 * (t - t.mean()) + rng.normal(0, 0.02, n)
    fit = fit_sine(y, t, freq=f, drift=True)
    assert abs(fit.drift - 0.2) < 4 * fit.u_drift
    assert abs(fit.offset - 0.5) < 4 * fit.u_offset
    assert fit.t_ref == pytest.approx(t.mean())


def test_nonuniform_and_weighted_match_theory():
    rng = np.random.default_rng(11)
    n = 3000
    t = np.sort(rng.uniform(0, 3.0, n))
    sig = np.where(np.arange(n) % 2 == 0, 0.01, 0.1)
    y = 1.5 * np.sin(2 * math.pi * 4.0 * t - 0.4) + 0.1 + rng.normal(0, 1, n) * sig
    fit = fit_sine(y, t, freq=4.0, weights=1 / sig**2)
    assert abs(fit.amplitude - 1.5) < 4 * fit.u_amplitude
    assert abs(math.remainder(fit.phase + 0.4, 2 * math.pi)) < 4 * fit.u_phase
    fit4 = fit_sine(y, t, weights=1 / sig**2)
    assert abs(fit4.frequency - 4.0) < 4 * fit4.u_frequency


def test_fast_path_equals_general_path():
    rng = np.random.default_rng(1)
    fs, n = 800.0, 5000
    t = np.arange(n) / fs
    y = rng.normal(0, 1, (3, n)) + np.sin(2 * math.pi * 3.1 * t)
    fast = fit_sine(y, fs=fs, freq=3.1)                     # compiled path
    slow = fit_sine(y, fs=fs, freq=3.1, weights=np.ones(n))  # SVD path
    for name in ("amplitude", "phase", "offset", "u_amplitude", "u_phase", "residual_rms"):
        np.testing.assert_allclose(getattr(fast, name), getattr(slow, name), rtol=1e-9, atol=1e-12)


def test_high_snr_large_offset_residual_is_exact():
    # Residual 1e-9 of a 1e3 offset: the one-pass sum would lose it; the
    # second pass must recover it.
    fs, n = 1000.0, 2**14
    t = np.arange(n) / fs
    rng = np.random.default_rng(2)
    y = 1e3 + np.sin(2 * math.pi * 9.0 * t) + rng.normal(0, 1e-9, n)
    fit = fit_sine(y, fs=fs, freq=9.0)
    assert fit.residual_rms == pytest.approx(1e-9, rel=0.05)


def test_serial_and_parallel_kernels_have_distinct_cache_keys():
    # Numba caches by qualified name: a shared key let processes load the
    # threaded build where the serial one was asked for.
    from senscal.sinefit import _kernels as kk

    k = kk.compiled()
    pairs = [(k.project_rotated, k.project_rotated_serial), (k.project_parallel, k.project_serial),
             (k.harmonic_basis_into_parallel, k.harmonic_basis_into_serial)]
    for par, ser in pairs:
        assert par.py_func.__qualname__ != ser.py_func.__qualname__
        assert par.targetoptions.get("parallel") and not ser.targetoptions.get("parallel")
