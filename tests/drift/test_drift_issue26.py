"""Issue 26 items 4 and 5: coloured sensor noise and a lagging covariate in the drift job.

Single records with fixed seeds (the Monte-Carlo coverage is in
test_coverage_drift.py): the likelihood quadrature over a bias level that
coloured noise leaves undetermined, the average over a covariate lag the record does not fix, and the
warning when the lag's likelihood piles at the longest lag the record holds.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from senscal.diagnostics import has_warning
from senscal.drift import correct_drift, covariate_setup, redundant_setup
from senscal.drift.core import _broad_bias_levels
from senscal.drift.estimate import NoiseParameter
from senscal.simulate.drift import simulate_drift_batch


def test_only_undetermined_bias_levels_of_coloured_channels_are_integrated():
    s = dataclasses.replace(redundant_setup(["a", "b", "c"], trusted=["a"]), ar_noise=("b",))
    noise = [NoiseParameter("b_bias_rate_std", 0.0, 0.002, True),        # zero within 2 u, coloured: integrated
             NoiseParameter("c_bias_rate_std", 0.0, 0.002, True),        # white-noise channel: normal approximation
             NoiseParameter("b_noise_ar_std", 0.0, 0.01, True),          # noise, not bias
             NoiseParameter("signal_rate_std", 0.0, None, True, True)]
    assert set(_broad_bias_levels(s, noise, {})) == {"b_bias_rate_std"}
    # Bounded away from zero (value > 2 u): the normal approximation holds.
    assert _broad_bias_levels(s, [NoiseParameter("b_bias_rate_std", 0.01, 0.004, True)], {}) == {}
    # At a search bound or without u: integrated, starting from a positive scale.
    q = _broad_bias_levels(s, [NoiseParameter("b_bias_rate_std", 1e-9, None, True, True)], {"b_bias_rate_std": 0.01})
    assert q["b_bias_rate_std"] >= 1e-5
    # A given level is never integrated.
    assert _broad_bias_levels(s, [NoiseParameter("b_bias_rate_std", 0.0, None, False)], {}) == {}


def test_coloured_noise_band_widens_where_the_bias_rate_is_not_resolved():
    # Seed 3: AR(1) noise rho 0.8 on s2, true bias rate 0.01; the ML rate is 0 (the record cannot tell).
    d = simulate_drift_batch(1, seed=3, n=600, noise=0.1, signal_level=0.1, bias_rate=0.01, noise_rho=0.8)
    s = dataclasses.replace(redundant_setup(["s1", "s2"], trusted=["s1"]), ar_noise=("s2",))
    a = correct_drift(s, d["y"][0], d["t"], smooth=True, compare=False)
    b = correct_drift(s, d["y"][0], d["t"], smooth=True, compare=False, level_u=False)
    rate = {p.name: p for p in a.noise}["s2_bias_rate_std"]
    assert rate.value <= 2 * rate.std  # the case the quadrature is for
    np.testing.assert_array_equal(a.bias, b.bias)  # the estimate stays the ML one
    assert np.all(a.bias_std > b.bias_std)
    truth = d["bias"][0, 1]
    cov_a = np.mean(np.abs(a.bias[0] - truth) <= 2 * a.bias_std[0])
    cov_b = np.mean(np.abs(b.bias[0] - truth) <= 2 * b.bias_std[0])
    assert cov_a > cov_b


def _lag_record(seed: int = 1, lag: float = 20.0):
    d = simulate_drift_batch(1, seed=seed, n=600, channels=("x",), trusted=(), noise=0.1, signal="gauss_markov",
                             signal_level=1.0, signal_tau=200.0, bias="none", covariate_coefficient=0.2,
                             covariate_lag=lag)
    return d, {"c": d["covariate"][0]}


def test_a_lagging_covariate_is_averaged_over_and_a_given_lag_covers():
    # Seed 1: the bias follows the covariate through a 20 s lag; lag-free, the coefficient is 2.5 u off.
    d, cov = _lag_record()
    s = covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0, covariate_reference=20.0)
    plain = correct_drift(s, d["y"][0], d["t"], cov, smooth=True, compare=False)
    v0, u0 = plain.final("x_c_coefficient")
    assert abs(v0 - 0.2) > 2 * u0  # the case the average is for
    # With the comparison on, the coefficient is averaged over the lags the record holds (the lag's
    # likelihood as weight): its u carries the lag's share and covers the truth.
    r = correct_drift(s, d["y"][0], d["t"], cov, smooth=True)
    v, u = r.final("x_c_coefficient")
    assert u > 2 * u0 and abs(v - 0.2) <= 2 * u
    assert np.all(r.bias_std[0] >= plain.bias_std[0] * (1 - 1e-9))
    np.testing.assert_allclose(r.corrected[0], d["y"][0][0] - r.bias[0])
    # The lag given (a model file's lag: 20): nothing to average or name, and the coefficient covers.
    g = dataclasses.replace(s, biases=tuple(dataclasses.replace(b, lag=20.0) for b in s.biases))
    r2 = correct_drift(g, d["y"][0], d["t"], cov, smooth=True)
    assert not has_warning(r2.warnings, "covariate-lag-uncertain")
    v, u = r2.final("x_c_coefficient")
    assert abs(v - 0.2) <= 2 * u


def test_a_lag_beyond_the_record_is_named():
    # Seed 3, lag 1000 s on a 600 s record: the likelihood rises to the longest lag tried (a third of the
    # record) and rejects lag 0, so the average over the lags the record holds is not supported: named.
    d, cov = _lag_record(seed=3, lag=1000.0)
    s = covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0, covariate_reference=20.0)
    r = correct_drift(s, d["y"][0], d["t"], cov, smooth=True)
    w = next(w for w in r.warnings if w.startswith("covariate-lag-uncertain"))
    assert "x_c_coefficient" in w and "longest lag" in w
    # Lag-free, the same record names nothing.
    d0, cov0 = _lag_record(seed=3, lag=0.0)
    r0 = correct_drift(s, d0["y"][0], d0["t"], cov0, smooth=True)
    assert not has_warning(r0.warnings, "covariate-lag-uncertain")


def test_lag_check_needs_the_comparison():
    # --no-compare: no alternative models and no lag check (the result is the model asked for, as before).
    d, cov = _lag_record()
    s = covariate_setup("x", "c", signal="gauss_markov", signal_tau=200.0, covariate_reference=20.0)
    r = correct_drift(s, d["y"][0], d["t"], cov, smooth=True, compare=False)
    assert not has_warning(r.warnings, "covariate-lag-uncertain")


def test_cli_covariate_lag_given_is_used_and_checked(cli, tmp_path):
    # senscal drift --covariate-lag: the known lag (a quantity; 0 for a sensor reading its own temperature) goes
    # into the model, so the lag check has nothing to name; bad values and a lag without a covariate: exit 2.
    import json

    from senscal.io.readers import write_recording
    from senscal.io.recording import Recording

    d, cov = _lag_record()
    f = tmp_path / "lag.csv"
    write_recording(Recording({"x": d["y"][0][0], "c": cov["c"]}, t=d["t"]), f)
    base = ["drift", f, "--preset", "covariate", "--channels", "x", "--covariate", "c", "--signal", "gauss_markov",
            "--signal-tau", "200", "--covariate-reference", "20", "--json"]
    free = cli(*base)
    assert free.code == 0, free.err
    # No lag given: the coefficient averaged over the lags the record holds covers, with a wider u.
    t_free = json.loads(free.out)["channels"]["x"]["terms"]["x_c_coefficient"]
    assert abs(t_free["value"] - 0.2) <= 2 * t_free["std"]
    given = cli(*base, "--covariate-lag", "0.333 min")
    assert given.code == 0, given.err
    doc = json.loads(given.out)
    assert "covariate-lag-uncertain" not in json.dumps(doc["warnings"])
    term = doc["channels"]["x"]["terms"]["x_c_coefficient"]
    assert abs(term["value"] - 0.2) <= 2 * term["std"]
    assert term["std"] < t_free["std"]
    for extra, words in ((["--covariate-lag", "-3"], ">= 0"), (["--covariate-lag", "3 V"], "voltage")):
        r = cli(*base, *extra)
        assert r.code == 2 and words in r.err and len(r.err.strip().splitlines()) == 1, r.err
    r = cli("drift", f, "--preset", "known", "--channels", "x", "--covariate-lag", "3")
    assert r.code == 2 and "--covariate" in r.err, r.err


def test_coloured_noise_used_is_named_and_white_noise_is_not():
    # Issue 26 item 4: with AR(1) noise (rho 0.8) the job uses the coloured-noise model, whose final-bias u
    # covered 91.5 % (200 seeds): the colour is named when the likelihood ratio rejects white noise at 5 %.
    d = simulate_drift_batch(1, seed=3, n=600, noise=0.1, signal_level=0.1, bias_rate=0.01, noise_rho=0.8)
    s = redundant_setup(["s1", "s2"], trusted=["s1"])
    r = correct_drift(s, d["y"][0], d["t"], smooth=True)
    assert r.selected == "--noise ar1"
    w = next(w for w in r.warnings if w.startswith("coloured-noise"))
    assert "likelihood ratio" in w and "4 dof" in w
    # The same record with white noise: the model asked for is kept and nothing is named.
    d = simulate_drift_batch(1, seed=3, n=600, noise=0.1, signal_level=0.1, bias_rate=0.01)
    r = correct_drift(s, d["y"][0], d["t"], smooth=True)
    assert r.selected is None and not has_warning(r.warnings, "coloured-noise")
    # Without the comparison there is no choice and no colour test.
    r = correct_drift(s, d["y"][0], d["t"], smooth=True, compare=False)
    assert not has_warning(r.warnings, "coloured-noise")
