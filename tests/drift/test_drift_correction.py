"""Drift correction against simulated truth (tolerances from the reported uncertainties)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from senscal.drift import (Bias, DriftSetup, SignalModel, augmented_model, check_observable, correct_drift,
                           covariate_setup, redundant_setup)
from senscal.drift.detect import cusum_threshold
from senscal.errors import DataError, InputError, UnobservableError
from senscal.simulate.drift import simulate_drift

CH = ["ref", "drift", "thermal"]


@pytest.fixture(scope="module")
def scenario():
    rec, truth = simulate_drift(days=8.0, dt=600.0, seed=11)
    setup = redundant_setup(CH, trusted=["ref"], covariate="temperature")
    res = correct_drift(setup, rec.data(CH), rec.time, {"temperature": rec["temperature"]}, compare=False)
    return rec, truth, res


def test_corrected_drifting_channel_rms_close_to_its_noise(scenario):
    rec, truth, res = scenario
    i = res.channels.index("drift")
    err = res.corrected[i] - truth["signal"]
    N = err.size
    sigma = truth["noise_std"]
    # E[err^2] = sigma^2 + E[(b - b_hat)^2]; the noise part within 4 sd of a
    # chi-square mean, the bias part bounded by 4x its reported variance.
    bound = sigma**2 * (1 + 4 * np.sqrt(2 / N)) + 4 * np.mean(res.bias_std[i] ** 2)
    assert np.mean(err**2) < bound
    raw_err = rec["drift"] - truth["signal"]
    assert np.sqrt(np.mean(raw_err**2)) > 5 * sigma  # the correction did something


def test_final_biases_within_reported_uncertainty(scenario):
    rec, truth, res = scenario
    for c in ("drift", "thermal"):
        i = res.channels.index(c)
        assert abs(res.bias[i, -1] - truth[f"bias_{c}"][-1]) < 4 * res.bias_std[i, -1]


def test_temperature_coefficient_recovered(scenario):
    rec, truth, res = scenario
    alpha, u = res.final("thermal_temperature_coefficient")
    assert abs(alpha - truth["temperature_coefficient"]) < 4 * u
    assert u < 0.1 * truth["temperature_coefficient"]


def test_ramp_onset_detected_within_stated_delay(scenario):
    rec, truth, res = scenario
    dt = truth["dt_s"]
    h = res.cusum_threshold
    k = 0.5
    # Innovation shift per sample of a ramp seen by the constant-bias model:
    # the shared signal estimate takes at most half of it (two other sensors).
    s = 0.5 * truth["ramp_rate_per_s"] * dt / truth["noise_std"]
    delay = (k + np.sqrt(k**2 + 2 * s * h)) / s * dt  # CUSUM crossing of the mean path
    t_on = truth["ramp_start_s"]
    assert res.alarm_t["drift"] is not None
    assert t_on < res.alarm_t["drift"] <= t_on + delay
    assert abs(res.onset_t["drift"] - t_on) <= delay
    # The thermal channel does not drift: an alarm has probability
    # rate * duration = 1e-4/h * 192 h ~ 2 %.
    assert res.onset_t["thermal"] is None


def test_noise_levels_estimated_with_uncertainties(scenario):
    rec, truth, res = scenario
    noise = {p.name: p for p in res.noise}
    for c in CH:
        p = noise[f"{c}_noise_std"]
        assert p.estimated and p.std is not None
        assert abs(p.value - truth["noise_std"]) < 4 * p.std
    assert noise["drift_bias_rate_std"].value > 10 * noise["thermal_bias_rate_std"].value


def test_covariate_preset_recovers_coefficient():
    rec, truth = simulate_drift(days=6.0, dt=600.0, seed=5)
    res = correct_drift(covariate_setup("thermal", "temperature", covariate_reference=20.0),
                        rec.data(["thermal"]), rec.time, {"temperature": rec["temperature"]})
    alpha, u = res.final("thermal_temperature_coefficient")
    assert abs(alpha - truth["temperature_coefficient"]) < 4 * u


def _model_data(setup, levels, dt, T, rng, cov=None):
    model = augmented_model(setup, np.full(T, dt), levels, cov)
    n, m = model.n_states, model.n_measurements
    # Diagonal Q and R in these set-ups: independent normal draws.
    w = rng.standard_normal((T, n)) * np.sqrt(np.diag(model.Q))
    v = rng.standard_normal((T, m)) * np.sqrt(np.diag(model.R))
    x = np.zeros(n)
    x[0] = 10.0
    x[1:] = rng.normal(0, 0.5, n - 1)
    truth = np.empty((n, T))
    y = np.empty((m, T))
    for t in range(T):
        if t > 0:
            x = model.F @ x + w[t]
        truth[:, t] = x
        H = model.H if model.H.ndim == 2 else model.H[t]
        y[:, t] = H @ x + v[t]
    return y, truth


def _two_sensors():
    """Trusted a and drifting b, every level given (no estimation)."""
    setup = DriftSetup(("a", "b"), SignalModel(level=0.05), (Bias("b", level=0.01),),
                       noise_std={"a": 0.1, "b": 0.1}, trusted=("a",))
    return setup, {"signal_rate_std": 0.05, "b_bias_rate_std": 0.01, "a_noise_std": 0.1, "b_noise_std": 0.1}


def test_reported_bias_std_matches_monte_carlo_spread():
    rng = np.random.default_rng(21)
    levels = {"signal_rate_std": 0.05, "b_bias_rate_std": 0.01, "c_bias_rate_std": 0.02}
    setup = DriftSetup(("a", "b", "c"), SignalModel(level=0.05), (Bias("b", level=0.01), Bias("c", level=0.02)),
                       noise_std={"a": 0.1, "b": 0.1, "c": 0.2}, trusted=("a",))
    M, T = 40, 150
    z2 = []
    for _ in range(M):
        y, x = _model_data(setup, {**levels, "a_noise_std": 0.1, "b_noise_std": 0.1, "c_noise_std": 0.2}, 1.0, T, rng)
        res = correct_drift(setup, y, np.arange(T, dtype=float), estimate=False)
        for j, name in ((1, "b"), (2, "c")):
            i = res.channels.index(name)
            z2.append((res.bias[i, -1] - x[j, -1]) / res.bias_std[i, -1])
    z2 = np.square(z2)
    # Mean of 2M squared standard normals; b and c share the signal error,
    # so take the 99.9% chi-square interval of M (not 2M) degrees of freedom.
    lo, hi = chi2.ppf([0.0005, 0.9995], M) / M
    assert lo < z2.mean() < hi


def test_window_and_smoother_trade_latency_for_variance():
    rng = np.random.default_rng(22)
    setup, levels = _two_sensors()
    y, x = _model_data(setup, levels, 1.0, 400, rng)
    t = np.arange(400.0)
    f = correct_drift(setup, y, t, estimate=False)
    w = correct_drift(setup, y, t, window=20, estimate=False)
    s = correct_drift(setup, y, t, smooth=True, estimate=False)
    assert w.method == "window" and w.window == 20 and s.method == "smoother"
    sl = slice(10, 380)
    assert np.all(w.bias_std[0, sl] <= f.bias_std[0, sl] * (1 + 1e-9))
    assert np.all(s.bias_std[0, sl] <= w.bias_std[0, sl] * (1 + 1e-9))
    assert np.mean(s.bias_std[0, sl]) < 0.8 * np.mean(f.bias_std[0, sl])
    # Smoothed errors are consistent with their (smaller) reported std.
    e = (s.bias[0, sl] - x[1, sl]) / s.bias_std[0, sl]
    assert np.sqrt(np.mean(e**2)) < 2.0


def test_missing_samples_are_skipped():
    rng = np.random.default_rng(23)
    setup, levels = _two_sensors()
    y, x = _model_data(setup, levels, 1.0, 300, rng)
    y[1, 100:150] = np.nan
    res = correct_drift(setup, y, np.arange(300.0), estimate=False)
    assert np.all(np.isnan(res.corrected[0, 100:150])) and np.all(np.isfinite(res.bias[0]))
    # Without measurements of b the bias uncertainty grows like a random walk.
    assert res.bias_std[0, 149] > res.bias_std[0, 99]


def test_unobservable_redundant_set_is_refused_with_names_and_remedies():
    setup = redundant_setup(["a", "b", "c"])
    with pytest.raises(UnobservableError) as exc:
        check_observable(setup, np.ones(100))
    msg = str(exc.value)
    for name in ("a_bias", "b_bias", "c_bias", "trusted", "model of the signal", "covariate"):
        assert name in msg
    # Each remedy makes it observable.
    check_observable(redundant_setup(["a", "b", "c"], trusted=["a"]), np.ones(100))
    check_observable(redundant_setup(["a", "b", "c"], signal="gauss_markov", signal_tau=50.0), np.ones(100))
    t = np.arange(500.0)
    check_observable(covariate_setup("a", "temp"), np.ones(500), {"temp": np.sin(t / 20)})
    with pytest.raises(UnobservableError, match="temp"):
        check_observable(covariate_setup("a", "temp"), np.ones(500), {"temp": np.zeros(500)})


def test_bad_inputs_raise_one_line_errors():
    setup, _ = _two_sensors()
    y = np.zeros((2, 50))
    t = np.arange(50.0)
    with pytest.raises(InputError, match="shape"):
        correct_drift(setup, np.zeros((3, 50)), t)
    with pytest.raises(DataError, match="increasing"):
        correct_drift(setup, y, t[::-1])
    with pytest.raises(InputError, match="either"):
        correct_drift(setup, y, t, window=5, smooth=True)
    with pytest.raises(InputError, match="not measured"):
        DriftSetup(("a",), biases=(Bias("z"),))
    with pytest.raises(InputError, match="tau"):
        Bias("a", dynamics="gauss_markov")
    with pytest.raises(InputError, match="covariate temp"):
        correct_drift(covariate_setup("a", "temp"), y[:1], t)


def test_detector_threshold_monotone_in_false_alarm_rate():
    assert cusum_threshold(1e6) > cusum_threshold(1e4) > cusum_threshold(1e2)


def test_channel_order_does_not_matter():
    rng = np.random.default_rng(24)
    setup = DriftSetup(("a", "b", "c"), SignalModel(level=0.05), (Bias("b", level=0.01), Bias("c", level=0.02)),
                       noise_std={"a": 0.1, "b": 0.1, "c": 0.2}, trusted=("a",))
    y, _ = _model_data(setup, {"signal_rate_std": 0.05, "b_bias_rate_std": 0.01, "c_bias_rate_std": 0.02,
                               "a_noise_std": 0.1, "b_noise_std": 0.1, "c_noise_std": 0.2}, 1.0, 200, rng)
    t = np.arange(200.0)
    perm = DriftSetup(("c", "a", "b"), setup.signal, setup.biases[::-1], setup.noise_std, setup.trusted)
    r1 = correct_drift(setup, y, t, estimate=False)
    r2 = correct_drift(perm, y[[2, 0, 1]], t, estimate=False)
    for c in ("b", "c"):
        i, j = r1.channels.index(c), r2.channels.index(c)
        assert np.allclose(r1.bias[i], r2.bias[j], rtol=1e-9, atol=1e-12)
        assert np.allclose(r1.bias_std[i], r2.bias_std[j], rtol=1e-9, atol=1e-12)


def test_gauss_markov_bias_and_signal():
    rng = np.random.default_rng(25)
    setup = DriftSetup(("a", "b"), SignalModel(kind="gauss_markov", tau=50.0, level=1.0, mean=5.0),
                       (Bias("a", dynamics="gauss_markov", tau=400.0, level=0.5),
                        Bias("b", dynamics="gauss_markov", tau=400.0, level=0.5)),
                       noise_std={"a": 0.1, "b": 0.1})
    levels = {"signal_std": 1.0, "a_bias_std": 0.5, "b_bias_std": 0.5, "a_noise_std": 0.1, "b_noise_std": 0.1}
    # No trusted sensor: the known signal model (mean 5, tau 50 s) makes the biases observable.
    z = []
    for _ in range(20):
        y, x = _model_data(setup, levels, 1.0, 600, rng)
        y = y + 5.0  # the model: mean 5 plus the Gauss-Markov deviation
        res = correct_drift(setup, y, np.arange(600.0), estimate=False)
        z += [(res.bias[i, -1] - x[1 + i, -1]) / res.bias_std[i, -1] for i in range(2)]
    z2 = np.square(z)
    lo, hi = chi2.ppf([0.0005, 0.9995], 20) / 20
    assert lo < z2.mean() < hi
