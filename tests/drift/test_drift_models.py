"""The drift likelihood's analytic score, coloured noise, covariate lag and model choice (issues 26 and 30)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from senscal.drift import augmented_model, correct_drift, covariate_setup, known_setup, redundant_setup
from senscal.drift.likelihood import LevelLikelihood
from senscal.drift.model import Bias, _uniform_dt, lag_filter
from senscal.errors import InputError
from senscal.kalman import log_likelihood
from senscal.simulate.drift import simulate_drift_batch


def _check_score(setup, y, t, cov, levels):
    """ln L equals the engine's; its gradient equals central differences of the engine's ln L."""
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    n = len(setup.state_names)
    x0, P0 = np.zeros(n), np.eye(n) * 10.0
    if setup.signal.kind == "known":
        P0[0, 0] = 0.0
    names = list(levels)
    ll, g = LevelLikelihood(setup, _uniform_dt(dt), y, cov, x0, P0, names)(levels)

    def ref(lv):
        return log_likelihood(augmented_model(setup, dt, lv, cov, x0=x0, P0=P0), y)

    assert ll == pytest.approx(ref(levels), rel=1e-10, abs=1e-8)
    h = 1e-5
    for i, k in enumerate(names):
        up, dn = dict(levels), dict(levels)
        up[k] *= math.exp(h)
        dn[k] *= math.exp(-h)
        # Central differences of ln L carry ~1e-6 of truncation and rounding.
        assert g[i] == pytest.approx((ref(up) - ref(dn)) / (2 * h), rel=1e-5, abs=1e-4), k


def test_score_matches_the_engine_white_and_coloured_noise_irregular_steps_and_gaps():
    d = simulate_drift_batch(1, seed=3, n=400, noise=0.1, bias_rate=0.01, noise_rho=0.8)
    s = redundant_setup(["s1", "s2"], trusted=["s1"])
    lv = {"s1_noise_std": 0.1, "s2_noise_std": 0.12, "signal_rate_std": 0.09, "s2_bias_rate_std": 0.02}
    _check_score(s, d["y"][0], d["t"], {}, lv)
    s2 = dataclasses.replace(s, ar_noise=("s2",))
    lv2 = dict(lv, s2_noise_ar_std=0.08, s2_noise_ar_tau=3.0)
    _check_score(s2, d["y"][0], d["t"], {}, lv2)
    t = np.sort(d["t"] + np.random.default_rng(0).uniform(0, 0.5, d["t"].size))
    y = d["y"][0].copy()
    y[1, 50:60] = np.nan
    y[0, 100] = np.nan
    _check_score(s2, y, t, {}, lv2)


def test_score_matches_the_engine_covariate_lag_and_ramp():
    d = simulate_drift_batch(1, seed=3, n=400, channels=("x",), trusted=(), signal="gauss_markov", signal_level=1.0,
                             signal_tau=200.0, bias="none", covariate_coefficient=0.2, covariate_lag=20.0)
    s = covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0, covariate_reference=20.0)
    s = dataclasses.replace(s, biases=(dataclasses.replace(s.biases[0], fit_lag=True),))
    lv = {"x_noise_std": 0.1, "signal_std": 1.0, "x_c_coefficient_rate_std": 1e-3, "x_c_coefficient_lag": 15.0}
    _check_score(s, d["y"][0], d["t"], {"c": d["covariate"][0] - 20.0}, lv)
    d = simulate_drift_batch(1, seed=3, n=400, channels=("g",), trusted=(), signal="known", bias="ramp")
    _check_score(known_setup(["g"], bias_dynamics="ramp"), d["y"][0], d["t"], {},
                 {"g_noise_std": 0.1, "g_bias_slope_rate_std": 1e-4})


def test_lag_filter_is_the_simulators_lag():
    d = simulate_drift_batch(1, seed=4, n=300, channels=("x",), trusted=(), bias="none", covariate_coefficient=1.0,
                             covariate_lag=12.0)
    got = lag_filter(d["covariate"][0], np.ones(1), 12.0)
    np.testing.assert_allclose(got, d["covariate_lagged"][0], rtol=0, atol=1e-12)
    # A lag that is not there returns the input; irregular steps agree with uniform ones of the same size.
    assert lag_filter(d["covariate"][0], np.ones(1), 0.0) is not None
    np.testing.assert_allclose(lag_filter(d["covariate"][0], np.ones(300), 12.0), got, rtol=0, atol=1e-12)


def test_lag_and_coloured_noise_are_checked():
    with pytest.raises(InputError, match="covariate"):
        Bias("x", fit_lag=True)
    with pytest.raises(InputError, match=">= 0"):
        Bias("x", covariate="c", lag=-1.0)
    with pytest.raises(InputError, match="not a measured channel"):
        dataclasses.replace(redundant_setup(["a", "b"], trusted=["a"]), ar_noise=("z",))


def test_coloured_noise_is_chosen_and_said():
    # Issue 26 item 4: AR(1) rho 0.8 on the drifting channel; white-noise levels absorb it silently.
    d = simulate_drift_batch(1, seed=5000, n=600, noise=0.1, bias_rate=0.01, noise_rho=0.8)
    r = correct_drift(redundant_setup(["s1", "s2"], trusted=["s1"]), d["y"][0], d["t"], smooth=True)
    assert r.selected == "--noise ar1" and r.summary()["model_selected"] == "--noise ar1"
    assert r.setup.ar_noise == ("s1", "s2")
    noise = {p.name: p.value for p in r.noise}
    assert 2.0 < noise["s2_noise_ar_tau"] < 12.0  # rho 0.8 per 1-s sample: tau 4.5 s
    # The coloured noise stays in the corrected output: only the bias is removed.
    np.testing.assert_allclose(r.corrected, d["y"][0][1:] - r.bias, rtol=0, atol=1e-12)
    # The colour itself is named (its final-bias u covered 91.5 %, below the rule), and nothing else.
    assert [w.split(":")[0] for w in r.warnings] == ["coloured-noise"]


def test_no_compare_keeps_the_model_asked_for():
    d = simulate_drift_batch(1, seed=5000, n=300, noise=0.1, bias_rate=0.01, noise_rho=0.8)
    r = correct_drift(redundant_setup(["s1", "s2"], trusted=["s1"]), d["y"][0], d["t"], compare=False)
    assert r.selected is None and r.setup.ar_noise == () and r.comparison == ()


def test_level_uncertainty_widens_the_band_only():
    d = simulate_drift_batch(1, seed=11, n=400, noise=0.1, bias_rate=0.01)
    s = redundant_setup(["s1", "s2"], trusted=["s1"])
    a = correct_drift(s, d["y"][0], d["t"], smooth=True, compare=False)
    b = correct_drift(s, d["y"][0], d["t"], smooth=True, compare=False, level_u=False)
    np.testing.assert_allclose(a.bias, b.bias, rtol=0, atol=0)
    assert np.all(a.bias_std >= b.bias_std) and np.any(a.bias_std > b.bias_std)


def test_a_new_time_constant_gives_the_numbers_of_a_fresh_build():
    """LevelLikelihood rewrites only the entries a time constant moves (issue 30): equal to building anew."""
    rng = np.random.default_rng(5)
    T = 500
    t = np.cumsum(rng.uniform(0.8, 1.2, T))
    dt = _uniform_dt(np.diff(t, prepend=t[0] - 1.0))
    y1 = rng.normal(0, 0.1, (1, T))
    c = np.cumsum(rng.normal(0, 0.1, T))
    ar = dataclasses.replace(known_setup(["g"]), ar_noise=("g",))
    lag = covariate_setup("x", "c")
    lag = dataclasses.replace(lag, biases=tuple(dataclasses.replace(b, fit_lag=True) if b.covariate else b
                                                for b in lag.biases), ar_noise=("x",))
    two = dataclasses.replace(redundant_setup(["s1", "s2"], trusted=["s1"]), ar_noise=("s2",))
    cases = [(ar, y1, {}, "g_noise_ar_tau", [("g_noise_ar_tau", 2.0), ("g_noise_ar_tau", 5.0)]),
             (lag, y1, {"c": c - c.mean()}, None, [("x_c_coefficient_lag", 3.0), ("x_noise_ar_tau", 4.0)]),
             (two, rng.normal(0, 0.1, (2, T)), {}, None, [("s2_noise_ar_tau", 2.5)])]
    for setup, y, cov, _, changes in cases:
        n = len(setup.state_names)
        x0, P0 = np.zeros(n), np.eye(n)
        if setup.signal.kind == "known":
            P0[0, 0] = 0.0
        names = setup.level_names()
        lv = {k: 0.05 for k in names}
        lv.update({k: 1.0 for k in names if k.endswith("_tau") or k.endswith("_lag")})
        kept = LevelLikelihood(setup, dt, y, cov, x0, P0, names)
        kept(lv)
        for k, v in changes:
            lv = dict(lv, **{k: v})
            ll, g = kept(lv)
            ll0, g0 = LevelLikelihood(setup, dt, y, cov, x0, P0, names)(lv)
            assert ll == ll0 and np.array_equal(g, g0), k
            assert kept(lv, False)[0] == ll0
