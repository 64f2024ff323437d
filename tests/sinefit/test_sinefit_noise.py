"""Whiteness test and coloured-noise covariance of the sine fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal import fit_sine
from senscal.diagnostics import has_warning
from senscal.simulate.sine import ar1_noise
from senscal.sinefit.noise import WHITE_Z
from senscal.validation import wilson_interval


def _sine(rng, m, n, fs=1000.0, f=12.5, rho=0.0, sigma=0.05, t0=0.0):
    t = t0 + np.arange(n) / fs
    return t, 1.3 * np.sin(2 * math.pi * f * t + 0.4) + 0.2 + ar1_noise(rng, (m, n), sigma, rho)


@pytest.mark.parametrize("harmonics, drift", [(1, False), (2, False), (1, True), (3, True)])
def test_one_pass_lag1_equals_explicit_residual(harmonics, drift):
    # The compiled path gets r1 from sums of its single pass; the general
    # path (time stamps given) from the residual itself.
    rng = np.random.default_rng(3)
    t, y = _sine(rng, 4, 3001, rho=0.6)
    fast = fit_sine(y, fs=1000.0, freq=12.5, harmonics=harmonics, drift=drift)
    slow = fit_sine(y, t, freq=12.5, harmonics=harmonics, drift=drift, weights=np.ones(t.size))
    np.testing.assert_allclose(fast.residual_lag1, slow.residual_lag1, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fast.u_amplitude, slow.u_amplitude, rtol=1e-9)
    assert list(fast.noise_model) == list(slow.noise_model) == ["coloured"] * 4


def test_one_pass_lag1_exact_at_high_snr():
    # Residual 1e-9 of a 1e3 offset: the second pass recomputes r1 exactly.
    rng = np.random.default_rng(2)
    n = 2**14
    t = np.arange(n) / 1000.0
    y = 1e3 + np.sin(2 * math.pi * 9.0 * t) + ar1_noise(rng, (2, n), 1e-9, 0.5)
    fit = fit_sine(y, fs=1000.0, freq=9.0)
    r = y - fit.evaluate(t)
    expect = np.sum(r[:, 1:] * r[:, :-1], axis=1) / np.sum(r * r, axis=1)
    # Both sides round each sample at ulp(1e3) / 1e-9 = 1e-4 of the noise, which
    # moves r1 by about 1e-4 * sqrt(2 / N) = 1e-6: 10x that is the tolerance.
    np.testing.assert_allclose(fit.residual_lag1, expect, atol=1e-5)


def test_false_alarm_rate_on_white_noise_and_cost_of_a_false_alarm():
    # 4000 white records: the test fires on 1 % by design (two-sided 1 %
    # normal quantile); the 99.9 % Wilson interval of the observed rate must
    # hold 1 %.
    rng = np.random.default_rng(11)
    m, n = 4000, 2000
    t, y = _sine(rng, m, n)
    auto = fit_sine(y, fs=1000.0, freq=12.5)
    white = fit_sine(y, fs=1000.0, freq=12.5, noise_model="white")
    fired = np.asarray(auto.noise_model) == "coloured"
    lo, hi = wilson_interval(int(fired.sum()), m)
    assert lo <= 0.01 <= hi
    # Where it fires, the AR model sees only the sampling fluctuation of r1
    # (|r1| about 3/sqrt(N) = 0.07): u changes by about that, never by more
    # than 2 |r1| (the AR(1) density ratio (1+r1)/(1-r1) at most, square-rooted).
    ratio = auto.u_amplitude[fired] / white.u_amplitude[fired]
    assert np.all(np.abs(ratio - 1) <= 2 * np.abs(auto.residual_lag1[fired]) + 0.01)
    # Over all records the error of u against the true sigma's u grows by a
    # few percent of itself at most (it is 1.6 % rms here, 1/sqrt(2 dof)).
    u_true = math.sqrt(2 * 0.05**2 / n)
    err_auto = np.sqrt(np.mean((auto.u_amplitude / u_true - 1) ** 2))
    err_white = np.sqrt(np.mean((white.u_amplitude / u_true - 1) ** 2))
    assert err_auto <= 1.1 * err_white
    # The variance-against-phase test (jitter) fires on 1 % of white records too, and only where the
    # whiteness test did not.
    het = np.asarray(auto.noise_model) == "phase-dependent"
    lo, hi = wilson_interval(int(het.sum()), m)
    assert lo <= 0.01 <= hi
    # Where neither fires the result is the white-noise (Cramer-Rao) one, bit for bit.
    plain = ~fired & ~het
    np.testing.assert_array_equal(auto.u_amplitude[plain], white.u_amplitude[plain])
    assert np.all(auto.dof_effective[plain] == n - 3)


def test_white_model_forced_on_coloured_noise_is_named():
    # The case: white covariance on AR(1) rho 0.9 covers 35-43 %.
    rng = np.random.default_rng(5)
    t, y = _sine(rng, 300, 2000, rho=0.9)
    fit = fit_sine(y, fs=1000.0, freq=12.5, noise_model="white")
    cover = np.mean(np.abs(fit.amplitude - 1.3) <= 2 * fit.u_amplitude)
    assert cover < 0.6
    assert has_warning(fit.warnings, "coloured-noise") and "assume white noise" in fit.warnings[0]
    auto = fit_sine(y, fs=1000.0, freq=12.5)
    assert np.mean(np.abs(auto.amplitude - 1.3) <= 2 * auto.u_amplitude) > 0.88
    assert "noise spectrum at the fitted frequency" in auto.warnings[0]
    assert "channels 0, 1, 2" in auto.warnings[0] and "(300 of 300)" in auto.warnings[0]
    one = auto.channel(7)
    assert one.noise_model == "coloured" and has_warning(one.warnings, "coloured-noise")
    assert "channel" not in one.warnings[0].split(":", 1)[1][:10]


def test_nonuniform_time_keeps_white_but_warns():
    rng = np.random.default_rng(8)
    n = 2000
    t = np.sort(rng.uniform(0, 2.0, n))
    y = np.sin(2 * math.pi * 5 * t) + ar1_noise(rng, (n,), 0.05, 0.9)
    fit = fit_sine(y, t, freq=5.0)
    assert fit.noise_model == "white"
    assert has_warning(fit.warnings, "coloured-noise") and "not uniform" in fit.warnings[0]


def test_effective_dof_of_ar1_matches_delta_method():
    # AR(1), offset at 0 Hz: var(log S(0)) = (4 (1+rho)/(1-rho) + 2) / N.
    rng = np.random.default_rng(4)
    n, rho = 4000, 0.9
    t, y = _sine(rng, 50, n, rho=rho)
    fit = fit_sine(y, fs=1000.0, freq=12.5)
    nu0 = 2 * n / (4 * (1 + rho) / (1 - rho) + 2)
    assert np.median(fit.dof_effective) == pytest.approx(nu0, rel=0.25)


def test_phase_at_centre_and_far_origin_warning():
    rng = np.random.default_rng(1)
    n, fs, f = 2000, 500.0, 13.37
    t = 1e5 + np.arange(n) / fs
    y = 2.0 * np.sin(2 * math.pi * f * t + 0.2) + rng.normal(0, 0.05, n)
    fit = fit_sine(y, t)
    assert fit.u_phase > 1.0
    assert has_warning(fit.warnings, "phase-origin-far")
    assert fit.t_ref == pytest.approx(0.5 * (t[0] + t[-1]))
    truth_c = 0.2 + 2 * math.pi * f * fit.t_ref
    assert abs(math.remainder(fit.phase_centre - truth_c, 2 * math.pi)) < 4 * fit.u_phase_centre
    # At the centre the frequency adds nothing: the three-parameter phase u.
    assert fit.u_phase_centre == pytest.approx(math.sqrt(2 / n) * 0.05 / 2.0, rel=0.1)
    d = fit.to_dict()
    assert "phase_centre_deg" in d and d["warnings"]
    # A given frequency: phase at t = 0 is exact in f, no warning.
    known = fit_sine(y, t, freq=f)
    assert not has_warning(known.warnings, "phase-origin-far")
    assert known.u_phase == pytest.approx(known.u_phase_centre)


def test_noise_model_argument_checked():
    from senscal.errors import InputError

    with pytest.raises(InputError, match="noise_model"):
        fit_sine(np.zeros(10), fs=1.0, noise_model="pink")


def test_white_z_is_the_one_percent_quantile():
    from scipy.stats import norm

    assert WHITE_Z == pytest.approx(norm.ppf(0.995), abs=1e-3)


def test_coloured_covariance_with_harmonics_and_drift():
    # The sandwich propagates the AR spectrum through every column: the
    # second harmonic (at 25 Hz), the offset and the drift (near 0 Hz).
    # Over M = 300 records the z-score spread has a sampling sd of
    # 1/sqrt(2 M) = 0.041; 4 of those, plus 2 % for u's own dof (about 50:
    # Student t sd 1.02), is the band.
    rng = np.random.default_rng(5)
    m, n = 300, 2000
    t = np.arange(n) / 1000.0
    y = (np.sin(2 * math.pi * 12.5 * t + 0.3) + 0.1 * np.sin(2 * math.pi * 25 * t - 0.5) + 0.3
         + 0.2 * (t - t.mean()) + ar1_noise(rng, (m, n), 0.05, 0.9))
    fit = fit_sine(y, fs=1000.0, freq=12.5, harmonics=2, drift=True)
    band = 4 / math.sqrt(2 * m) + 0.02
    for est, u, truth in ((fit.drift, fit.u_drift, 0.2), (fit.offset, fit.u_offset, 0.3),
                          (fit.amplitude, fit.u_amplitude, 1.0),
                          (fit.harmonic_amplitudes[:, 1], fit.u_harmonic_amplitudes[:, 1], 0.1)):
        assert abs(np.std((est - truth) / u) - 1) < band


def test_phase_centre_is_the_phase_at_t_ref():
    rng = np.random.default_rng(12)
    for t0 in (0.0, 3.7, 1e4):
        t, y = _sine(rng, 1, 1500, f=7.3, t0=t0)
        fit = fit_sine(y[0], t)
        assert abs(math.remainder(fit.phase_centre - (fit.phase + 2 * math.pi * fit.frequency * fit.t_ref),
                                  2 * math.pi)) < 1e-6 * max(1.0, t0)
        assert fit.u_phase_centre <= fit.u_phase * (1 + 1e-9)
