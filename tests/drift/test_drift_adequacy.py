"""Moment-based noise levels, innovation tests, collapse check, ramp bias, known value, reference warning."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.diagnostics import has_warning
from senscal.drift import (correct_drift, covariate_setup, innovation_checks, known_setup, moment_levels,
                           redundant_setup)
from senscal.drift.core import _degenerate
from senscal.drift.estimate import NoiseParameter, estimate_levels
from senscal.drift.model import augmented_model
from senscal.kalman import log_likelihood
from senscal.simulate.drift import simulate_drift_batch


def test_moment_levels_see_the_noise_under_large_quantity_steps():
    # Quantity steps 10x the noise: the spread of the increments is useless
    # for the noise, the lag-one autocovariance of the differences is not.
    d = simulate_drift_batch(1, n=20000, noise=0.1, signal_level=1.0, bias_rate=0.01, seed=3)
    mom = moment_levels(d["y"][0])
    for i in range(2):
        # within 4 standard errors (Bartlett bound) of the true variance
        assert abs(mom.noise_var[i] - 0.01) < 4 * mom.noise_var_se[i]
        assert mom.noise_var_se[i] < 0.01  # and resolved
    assert abs(mom.common_var - 1.0) < 4 * mom.noise_var_se[0]


def test_innovation_checks_accept_white_and_reject_correlated():
    rng = np.random.default_rng(1)
    # Each test rejects white noise with probability 1e-3 by construction.
    assert innovation_checks(rng.normal(size=(2, 2000))).adequate
    e = rng.normal(size=2000)
    ar = np.empty_like(e)
    ar[0] = e[0]
    for k in range(1, e.size):
        ar[k] = 0.3 * ar[k - 1] + np.sqrt(1 - 0.09) * e[k]
    # rho = 0.3 over 2000 samples: Ljung-Box Q ~ 2000 * 0.09 = 180 >> chi2(8) tail
    chk = innovation_checks(ar[None])
    assert not chk.adequate and chk.whiteness_p < 1e-10
    assert not innovation_checks(1.5 * rng.normal(size=(1, 2000))).adequate  # scale: NIS 2.25


def test_collapsed_noise_levels_are_named():
    d = simulate_drift_batch(1, n=2000, noise=0.1, seed=4)
    mom = moment_levels(d["y"][0])
    setup = redundant_setup(["s1", "s2"], trusted=["s1"])
    ok = [NoiseParameter("s1_noise_std", 0.1, 0.003, True), NoiseParameter("s2_noise_std", 0.1, 0.003, True)]
    assert _degenerate(setup, ok, mom) == []
    bad = [NoiseParameter("s1_noise_std", 7e-4, None, True, True), ok[1]]
    w = _degenerate(setup, bad, mom)
    assert len(w) == 1 and has_warning(w, "degenerate-noise-levels") and "s1" in w[0]


def test_several_starts_keep_the_most_likely():
    d = simulate_drift_batch(1, n=800, noise=0.1, seed=5)
    y, t = d["y"][0], d["t"]
    setup = redundant_setup(["s1", "s2"], trusted=["s1"])
    dt = np.full(t.size, 1.0)

    def build(lv):
        return augmented_model(setup, dt, lv, x0=np.zeros(2), P0=np.eye(2) * 100.0)

    free = {"s1_noise_std": 1e-4, "s2_noise_std": 1e-4, "signal_rate_std": 0.3, "s2_bias_rate_std": 0.3}
    good = {"s1_noise_std": 0.1, "s2_noise_std": 0.1, "signal_rate_std": 0.1, "s2_bias_rate_std": 0.01}
    one, ll1 = estimate_levels(build, y, free, {})
    both, ll2 = estimate_levels(build, y, free, {}, starts=[good])
    assert ll2 >= ll1 - 1e-6
    lv = {p.name: p.value for p in both}
    assert ll2 == pytest.approx(log_likelihood(build(lv), y), abs=1e-6)


def test_ramp_bias_follows_a_linear_drift_without_lag():
    d = simulate_drift_batch(1, n=600, noise=0.1, bias="ramp", ramp_start=200.0, ramp_slope=5e-3, seed=6)
    rw = correct_drift(redundant_setup(["s1", "s2"], trusted=["s1"]), d["y"][0], d["t"], compare=False)
    ramp = correct_drift(redundant_setup(["s1", "s2"], trusted=["s1"], bias_dynamics="ramp"), d["y"][0], d["t"],
                         compare=False)
    truth = d["bias"][0, 1, -1]
    b, u = ramp.final("s2_bias")
    assert abs(b - truth) < 3.29 * u  # 99.9 % two-sided
    slope, us = ramp.final("s2_bias_slope")
    assert abs(slope - 5e-3) < 3.29 * us
    # The random walk lags the ramp at the end of the record, the ramp does not:
    # its filtered error over the last 100 samples is smaller.
    err_rw = np.sqrt(np.mean((rw.bias[0, -100:] - d["bias"][0, 1, -100:]) ** 2))
    err_ramp = np.sqrt(np.mean((ramp.bias[0, -100:] - d["bias"][0, 1, -100:]) ** 2))
    assert err_ramp < err_rw
    assert ramp.state_names == ("signal", "s2_bias", "s2_bias_slope")


def test_known_value_preset_makes_a_single_offset_observable():
    d = simulate_drift_batch(1, n=400, channels=("g",), trusted=(), signal="known", signal_mean=2.0, seed=7)
    res = correct_drift(known_setup(["g"], 2.0), d["y"][0], d["t"], smooth=True, compare=False)
    z = (res.bias[0] - d["bias"][0, 0]) / res.bias_std[0]
    assert np.all(np.isfinite(z)) and np.mean(np.abs(z) < 2) > 0.8
    assert np.allclose(res.state[0], 2.0)  # the quantity is held at its known value
    assert np.allclose(res.corrected[0], d["y"][0, 0] - res.bias[0])


def test_defaulted_reference_warns_only_when_it_fixes_the_offset():
    d = simulate_drift_batch(1, n=300, channels=("x",), trusted=(), signal="gauss_markov", signal_level=1.0,
                             signal_tau=200.0, bias="none", covariate_coefficient=0.2, seed=8)
    y, t, cov = d["y"][0], d["t"], {"c": d["covariate"][0]}
    r = correct_drift(covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0), y, t, cov, compare=False)
    assert has_warning(r.warnings, "covariate-reference-defaulted")
    r = correct_drift(covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0, covariate_reference=20.0),
                      y, t, cov, compare=False)
    assert not has_warning(r.warnings, "covariate-reference-defaulted")
    # With an additive bias on the channel the reference only moves bias between terms.
    r = correct_drift(known_setup(["x"], 0.0, covariate="c"), y, t, cov, compare=False)
    assert not has_warning(r.warnings, "covariate-reference-defaulted")


def test_summary_carries_model_check_comparison_and_warnings():
    d = simulate_drift_batch(1, n=400, noise=0.1, bias="ramp", ramp_start=100.0, ramp_slope=5e-3, seed=9)
    r = correct_drift(redundant_setup(["s1", "s2"], trusted=["s1"]), d["y"][0], d["t"])
    doc = r.summary()
    assert doc["model_check"]["n"] > 0 and 0 <= doc["model_check"]["whiteness_p"] <= 1
    assert [c["model"] for c in doc["model_comparison"]] == ["asked", "--bias-dynamics ramp", "--noise ar1"]
    assert doc["warnings"] == list(r.warnings)
    # A 1.5-unit ramp over 300 samples, 0.1 noise: the ramp model is used (the random walk's innovations
    # are rejected) or, if they pass, named.
    assert doc["model_selected"] == "--bias-dynamics ramp" or has_warning(r.warnings, "better-model")
