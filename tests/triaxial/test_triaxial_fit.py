"""Estimators against simulated truth (tolerances from the reported uncertainty and the model's order)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal.simulate.triaxial import simulate_magnetometer
from senscal.triaxial import calibrate, fit_linear, fit_lms, fit_ml

F = 50_000.0


@pytest.fixture(scope="module")
def sphere():
    return simulate_magnetometer(motion="sphere", n=500, seed=11)


def _truth_value(truth, name):
    if name in ("alpha", "beta", "gamma"):
        return math.radians(truth[f"{name}_deg"])
    if name == "field":
        return truth["field"]
    return truth[name]


@pytest.mark.parametrize("field", [F, None])
def test_full_model_recovers_every_parameter(sphere, field):
    rec, truth = sphere
    res = calibrate(rec.data(), field=field)
    assert res.model == "full" and res.method == "ml"
    assert not res.unidentifiable
    # Chosen by held-out error: every simpler model is significantly worse on these data.
    assert {e["model"] for e in res.model_evidence} == {"full", "diagonal", "offsets", "planar"}
    assert all(c.split(":")[0] in ("diagonal", "offsets", "planar") for c in res.model_choice)
    for name, p in res.parameters.items():
        tv = _truth_value(truth, name)
        if field is None and name in ("Kx", "Ky", "field"):
            continue  # relative to the estimated Kz (=1 by convention): checked below
        assert abs(p["value"] - tv) < 4 * p["u"], (name, p, tv)
    if field is None:
        # Scale arbitrary: gains are relative to Z and the field is in Z units.
        kz = truth["Kz"]
        assert abs(res.value("Kx") - truth["Kx"] / kz) < 4 * res.u("Kx")
        assert abs(res.value("field") - F * kz) < 4 * res.u("field")
        assert res.scale_note and "arbitrary" in res.scale_note
    # Norm error after correction is down to the noise: the sample std of N
    # Gaussian values is within 5 * sigma / sqrt(2N) of sigma.
    sig = truth["noise_std"]
    n = res.n_used
    assert abs(res.norm_error_after["std"] - sig) < 5 * sig / math.sqrt(2 * n)
    assert res.norm_error_before["std"] > 20 * sig
    assert abs(res.noise - sig) < 5 * sig / math.sqrt(2 * n)


def test_linearised_least_squares_is_close_to_truth(sphere):
    """The seed's model drops second-order terms: its error is O(eps^2), eps the largest error term."""
    rec, truth = sphere
    lin = fit_linear(rec.data(), field=F)
    w = truth["linear_weights"]
    eps = max(abs(w["dKx"]), abs(w["dKy"]), abs(w["alpha"]), abs(w["beta"]), abs(w["gamma"]))
    for name, v, u in zip(lin.names, lin.values, lin.uncertainties):
        scale = F if name.startswith("B") else 1.0
        assert abs(v - w[name]) < 3 * eps**2 * scale + 4 * u, (name, v, w[name])


def test_lms_converges_to_least_squares_and_is_reported(sphere):
    rec, _ = sphere
    h = rec.data()[:, :100]
    ls = fit_linear(h, field=F)
    lms = fit_lms(h, field=F, lr=0.05, epochs=3000)
    assert lms.covariance is None
    # Constant-step LMS converges to the least-squares solution up to its
    # steady-state misadjustment: weight jitter ~ sqrt(lr/2) * (noise of the
    # scaled target, sigma/F) per weight (features O(1)); allow 4 times that.
    jitter = math.sqrt(0.05 / 2) * ls.noise / F
    scale = np.array([F if n.startswith("B") else 1.0 for n in ls.names])
    assert np.all(np.abs(lms.values - ls.values) < 4 * jitter * scale)
    res = calibrate(h, field=F, method="lms")  # seed defaults: lr 0.01, 50 epochs
    cmp_ = res.lms_vs_least_squares
    assert cmp_["epochs"] == 50 and cmp_["lr"] == 0.01
    d = cmp_["difference_in_u"]
    short = fit_lms(h, field=F)
    k = short.names.index("alpha")
    assert d["alpha"] == pytest.approx((short.values[k] - ls.values[k]) / ls.uncertainties[k])
    if cmp_["max_abs_difference_in_u"] > 1:
        assert any("LMS" in w for w in res.warnings)


def test_lms_divergence_is_an_error(sphere):
    from senscal.errors import ConvergenceError

    rec, _ = sphere
    with pytest.raises(ConvergenceError, match="lower --lr"):
        fit_lms(rec.data(), field=F, lr=50.0, epochs=50)


def test_ml_uncertainty_matches_monte_carlo_spread():
    """Reported u(alpha), u(Bx) vs the spread over repeated simulations (40 runs: +-35 % at 3 sigma)."""
    est, us = [], []
    for seed in range(40):
        rec, _ = simulate_magnetometer(motion="sphere", n=150, seed=1000 + seed)
        fit = fit_ml(rec.data(), "full", field=F)
        est.append(fit.values[[3, 6]])
        us.append(fit.uncertainties[[3, 6]])
    ratio = np.std(est, axis=0, ddof=1) / np.mean(us, axis=0)
    assert np.all((ratio > 0.65) & (ratio < 1.35)), ratio


def test_ellipsoid_and_ml_agree(sphere):
    rec, _ = sphere
    a = calibrate(rec.data(), field=F, method="ellipsoid")
    m = calibrate(rec.data(), field=F, method="ml")
    for n in m.parameters:
        assert abs(a.value(n) - m.value(n)) < 2 * m.u(n)
        assert a.u(n) > 0


def test_invariances_order_and_units(sphere):
    """Reading order does not matter; data and field in other units (x c) give the same angles, offsets x c."""
    rec, _ = sphere
    h = rec.data()[:, :200]
    a = calibrate(h, field=F)
    perm = np.random.default_rng(3).permutation(h.shape[1])
    b = calibrate(h[:, perm], field=F)
    c = 1e-9  # nT -> T
    t = calibrate(h * c, field=F * c)
    for n in a.parameters:
        assert b.value(n) == pytest.approx(a.value(n), rel=1e-6, abs=1e-9 * a.u(n) + 1e-15)
        k = c if n.startswith("B") else 1.0
        assert t.value(n) == pytest.approx(a.value(n) * k, rel=1e-6, abs=1e-3 * a.u(n) * k)
        assert t.u(n) == pytest.approx(a.u(n) * k, rel=1e-4)
