"""The quadratic EKF with the array's constant errors as states: oracle, observability, honesty."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from senscal.errors import InputError
from senscal.gfimu import METHODS, angular_velocity, error_statistics, kalman_rate, paper_layout, solve_kinematics
from senscal.gfimu.filter import channel_covariance
from senscal.gfimu.methods import rate_increments
from senscal.simulate.gfimu import G0, simulate_gfimu

SIG = 1e-3 * G0
BIAS = 1e-4 * G0


def _hx(x):
    a, b, c = x[:3]
    return np.array([-(b * b + c * c), -(a * a + c * c), -(a * a + b * b), a * b, a * c, b * c]) + x[6:]


def _jac(x):
    a, b, c = x[:3]
    H = np.zeros((6, 12))
    H[:, :3] = [[0, -2 * b, -2 * c], [-2 * a, 0, -2 * c], [-2 * a, -2 * b, 0], [b, a, 0], [c, 0, a], [0, c, b]]
    H[:, 6:] = np.eye(6)
    return H


def _true_offsets(kin, info):
    b = np.array([info["bias_m_s2"][n] for n in paper_layout().names])
    return (kin.sensitivity @ b)[3:12]


def test_offsets_ekf_matches_filterpy():
    rec, _, _ = simulate_gfimu(fs=1000, duration=0.4, seed=11)
    kin = solve_kinematics(rec.data(), paper_layout())
    t = rec.time
    res = kalman_rate(kin, t, SIG, initial=(0, 0, 0), initial_std=1e-2, gate_probability=0, bias_std=BIAS)
    C = channel_covariance(kin, SIG)
    dt = t[1] - t[0]
    ekf = ExtendedKalmanFilter(dim_x=12, dim_z=6, dim_u=3)
    ekf.x = np.zeros(12)
    ekf.P = np.zeros((12, 12))
    ekf.P[:3, :3] = np.eye(3) * 1e-4
    ekf.P[3:, 3:] = channel_covariance(kin, BIAS)[3:12, 3:12]
    ekf.F = np.eye(12)
    ekf.F[:3, 3:6] = -dt * np.eye(3)
    ekf.B = np.zeros((12, 3))
    ekf.B[:3] = np.eye(3)
    ekf.Q = np.zeros((12, 12))
    ekf.Q[:3, :3] = dt ** 2 * C[3:6, 3:6]
    ekf.R = C[6:12, 6:12]
    inc = rate_increments(kin.angular_acceleration, t)
    out = np.empty((12, t.size))
    for k in range(t.size):
        if k:
            ekf.predict(u=inc[:, k])
        ekf.update(kin.W[:, k], _jac, _hx)
        out[:, k] = ekf.x
    np.testing.assert_allclose(res.omega, out[:3], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.offsets, out[3:, -1], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(res.u_offsets, np.sqrt(np.diag(ekf.P)[3:]), rtol=1e-7)


@pytest.mark.parametrize("paper", [True, False])
def test_offsets_are_observable_and_found(paper):
    # Single-axis (paper) and three-axis motion: the nine constant errors are all observable
    # (alpha offsets through the drift they cause in the cross products, W offsets as constants).
    rec, _, info = simulate_gfimu(paper=paper, fs=1000, duration=5, seed=3)
    kin = solve_kinematics(rec.data(), paper_layout())
    res = kalman_rate(kin, rec.time, SIG, initial=(0, 0, 0), bias_std=BIAS)
    truth = _true_offsets(kin, info)
    prior = np.sqrt(np.diag(channel_covariance(kin, BIAS)))[3:12]
    assert np.all(np.abs(res.offsets - truth) < 4 * res.u_offsets)
    # Learned, not just the prior: the data shrank every uncertainty well below it.
    assert np.all(res.u_offsets < prior / 3)


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_offsets_filter_uncertainty_is_honest_with_biases(seed):
    # With constant sensor errors on, the stated u(w) must still describe the error: seeds 1 and 3
    # have biases that cancel in alpha_z, seed 0 has not.
    rec, tr, _ = simulate_gfimu(paper=True, fs=2000, duration=4, seed=seed)
    est = angular_velocity(rec.data(), rec.time, paper_layout(), methods=("kalman",), bias_std=BIAS)
    z = ((est.omega["kalman"] - tr.data(["wx", "wy", "wz"])) / est.u_omega)[2]
    # Errors are autocorrelated (~100 independent values): sample std within ~15 %, 3 sigma -> 0.55..1.45,
    # and the mean of ~100 unit values within 0.6 (6 sigma: allows the autocorrelation's slack).
    assert 0.55 < z.std() < 1.45
    assert abs(z.mean()) < 0.6


def test_offsets_remove_alpha_bias_drift_on_paper_motion():
    # Seed 0: the biases leave a constant error in alpha_z; the plain EKF fights the drift and is
    # floored by the constant errors of W, the offsets filter reaches its white-noise level.
    rec, tr, _ = simulate_gfimu(paper=True, fs=2000, duration=4, seed=0)
    w = tr.data(["wx", "wy", "wz"])
    plain = angular_velocity(rec.data(), rec.time, paper_layout(), methods=METHODS)
    aug = angular_velocity(rec.data(), rec.time, paper_layout(), methods=("kalman",), bias_std=BIAS)
    sp = error_statistics(plain.omega, w)
    sa = error_statistics(aug.omega, w)["kalman"]
    for m in ("integration", "sqrt", "differential"):
        assert sa.max_abs_error[2] < sp[m].max_abs_error[2] / 10
        assert sa.std_error[2] < sp[m].std_error[2] / 10
    # White-noise level: the error's rms is the stated u (within the 3-sigma band above).
    rms = np.sqrt(np.mean((aug.omega["kalman"][2] - w[2]) ** 2))
    assert rms < 1.45 * np.sqrt(np.mean(aug.u_omega[2] ** 2))


def test_offsets_bad_arguments():
    rec, _, _ = simulate_gfimu(fs=1000, duration=0.1, seed=0)
    with pytest.raises(InputError, match="quadratic"):
        angular_velocity(rec.data(), rec.time, paper_layout(), observation="sqrt", bias_std=BIAS)
    with pytest.raises(InputError, match="bias_std"):
        angular_velocity(rec.data(), rec.time, paper_layout(), bias_std=-1.0)


@pytest.mark.parametrize("seed", range(6))
def test_paper_claim_over_seeds_with_offsets(seed):
    # The paper's set-up at 10 kHz, 3 s. The honest claim: >= 10x better than sqrt and differential on
    # every seed; >= 10x better than integration where the constant errors reach alpha_z. There the
    # drift is at least (b / L) T = 0.074 rad/s (error std >= drift / sqrt(12) = 0.021) against the
    # filter's white-noise floor ~1e-3 rad/s (std), a margin of ~2. Where they cancel, integration is
    # only a random walk and no causal filter gains 10x over it in 3 s (docs/gfimu.md); there the
    # filter must still sit at its stated uncertainty.
    rec, tr, info = simulate_gfimu(paper=True, duration=3, seed=seed)
    b = info["bias_m_s2"]
    reaches = abs(b["a2y"] - b["a1y"] - b["a3x"] + b["a1x"]) > 1e-12
    w = tr.data(["wx", "wy", "wz"])
    est = angular_velocity(rec.data(), rec.time, paper_layout(), methods=METHODS, bias_std=BIAS)
    st = error_statistics(est.omega, w)
    k = st["kalman"]
    for m in ("sqrt", "differential") + (("integration",) if reaches else ()):
        assert k.max_abs_error[2] < st[m].max_abs_error[2] / 10, m
        assert k.std_error[2] < st[m].std_error[2] / 10, m
    z = (est.omega["kalman"][2] - w[2]) / est.u_omega[2]
    assert 0.55 < z.std() < 1.45 and abs(z.mean()) < 0.6
