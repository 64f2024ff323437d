"""Classic methods, noise estimate, error statistics and attitude on exact or simulated truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st

from senscal.errors import InputError
from senscal.gfimu import (attitude_error, differential_rate, error_statistics, estimate_noise_std,
                           integrate_attitude, integration_rate, sqrt_rate)
from senscal.simulate.gfimu import simulate_gfimu


def quadratic_rate(t, rng):
    """w = w0 + a t + b t^2 / 2 with alpha = a + b t: the trapezoid rule integrates it exactly."""
    w0, a, b = rng.normal(0, 3, (3, 3, 1))
    return w0 + a * t + 0.5 * b * t ** 2, a + b * t


@given(st.integers(0, 10_000))
def test_integration_exact_for_linear_alpha_nonuniform_time(seed):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.5e-3, 1.5e-3, 200))
    w, alpha = quadratic_rate(t, rng)
    np.testing.assert_allclose(integration_rate(alpha, t, w[:, 0]), w, rtol=0, atol=1e-12 * (1 + np.abs(w).max()))


def test_sqrt_takes_sign_from_reference():
    w = np.array([[1.0, -2.0, 0.0], [-0.5, 3.0, 4.0], [2.0, 2.0, -2.0]])
    ref = w + 0.1 * np.sign(w)
    np.testing.assert_allclose(sqrt_rate(w ** 2, ref), w)
    # Negative squares (noise near zero) give zero, not NaN.
    assert np.all(sqrt_rate(-np.ones((3, 2)), np.ones((3, 2))) == 0.0)


def test_differential_exact_and_rejects_flat_rate():
    rng = np.random.default_rng(4)
    t = np.arange(400) * 1e-3
    w, alpha = quadratic_rate(t, rng)
    for lag in (1, 7):
        est, u, bad = differential_rate(w ** 2, alpha, t, lag=lag, reject_factor=np.inf)
        assert np.all(bad[:, :lag]) and not np.any(bad[:, lag:] & np.isfinite(u[:, lag:]) & (alpha[:, lag:] != 0))
        ok = ~bad
        # The identity is exact for exact increments; rounding grows as 1/|D|.
        np.testing.assert_allclose(est[ok], w[ok], rtol=0, atol=1e-6)
    # A constant rate has no increment: the method is undefined and must reject every sample.
    est, _, bad = differential_rate(np.full((3, 50), 4.0), np.zeros((3, 50)), t[:50])
    assert bad.all() and np.isnan(est).all()


def test_differential_rejects_ill_conditioned_samples():
    rec, tr, _ = simulate_gfimu(fs=1000, duration=2, bias_g=0, seed=3)
    w = tr.data(["wx", "wy", "wz"])
    alpha = tr.data(["alpha_x", "alpha_y", "alpha_z"])
    noisy = w ** 2 + np.random.default_rng(0).normal(0, 0.01, w.shape)
    est, u, bad = differential_rate(noisy, alpha, rec.time, lag=20, squares_std=[0.01] * 3)
    med = np.nanmedian(np.where(np.isfinite(u), u, np.nan), axis=1, keepdims=True)
    assert np.all(bad[np.isfinite(u) & (u > 3 * med)])
    z = (est - w)[~bad] / u[~bad]
    # Kept samples: error consistent with the stated uncertainty (linearised, so allow 20 %).
    assert 0.5 < np.std(z) < 1.2


def test_noise_estimate_against_known_noise():
    rng = np.random.default_rng(8)
    t = np.arange(20000) / 1000
    sig = np.array([0.01, 0.05, 0.2])
    y = 3 * np.sin(2 * np.pi * 2 * t) + rng.normal(0, 1, (3, t.size)) * sig[:, None]
    # MAD of ~N correlated second differences: relative std ~ 1.2/sqrt(N) * 1.5 ~ 1.3 %; 4 sigma.
    np.testing.assert_allclose(estimate_noise_std(y), sig, rtol=0.05)


def test_error_statistics_known_values():
    truth = np.zeros((3, 4))
    est = np.array([[1.0, -1.0, 1.0, -1.0], [0, 0, 0, 3.0], [np.nan, 2.0, 2.0, np.nan]])
    st_ = error_statistics({"m": est}, truth)["m"]
    np.testing.assert_allclose(st_.max_abs_error, [1.0, 3.0, 2.0])
    np.testing.assert_allclose(st_.std_error, [np.std([1, -1, 1, -1], ddof=1), np.std([0, 0, 0, 3], ddof=1), 0.0])
    np.testing.assert_array_equal(st_.n_valid, [4, 4, 2])
    with pytest.raises(InputError, match="time base"):
        error_statistics({"m": est[:, :3]}, truth)


def test_attitude_exact_for_constant_rate_and_second_order():
    t = np.arange(1001) * 1e-3
    w = np.tile(np.array([[0.3], [-0.2], [0.5]]), t.size)
    q = integrate_attitude(w, t)
    ang = np.linalg.norm(w[:, 0]) * t[-1]
    axis = w[:, 0] / np.linalg.norm(w[:, 0])
    np.testing.assert_allclose(q[:, -1], np.r_[np.cos(ang / 2), np.sin(ang / 2) * axis], atol=1e-12)
    # On a three-axis motion the error must shrink ~4x per halving of the step (second order).
    errs = []
    for fs in (250.0, 500.0):
        _, tr, _ = simulate_gfimu(fs=fs, duration=4, seed=0)
        qt = tr.data(["qw", "qx", "qy", "qz"])
        qe = integrate_attitude(tr.data(["wx", "wy", "wz"]), tr.time, qt[:, 0])
        errs.append(attitude_error(qe, qt, tr.time).max_deg)
    assert 3.0 < errs[0] / errs[1] < 5.0
    with pytest.raises(InputError, match="NaN"):
        integrate_attitude(np.full((3, 5), np.nan), np.arange(5.0))
