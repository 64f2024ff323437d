"""The offline RTS smoother option of the array's Kalman filters: oracle, gain over the filter, honesty."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import rts_smoother as fp_rts

from senscal.gfimu import angular_velocity, error_statistics, kalman_rate, paper_layout, solve_kinematics
from senscal.gfimu.filter import channel_covariance
from senscal.gfimu.methods import rate_increments
from senscal.simulate.gfimu import G0, simulate_gfimu

SIG = 1e-3 * G0
BIAS = 1e-4 * G0


@pytest.mark.parametrize("observation", ["quadratic", "sqrt"])
def test_smoother_matches_filterpy_rts(observation, monkeypatch):
    # filterpy's RTS has no control input; in the coordinates x - (integrated increments) the process is a
    # plain random walk with the same covariances, so its smoother is the oracle after shifting back.
    from senscal.gfimu import filter as flt

    rec, _, _ = simulate_gfimu(fs=1000, duration=0.5, seed=4)
    kin = solve_kinematics(rec.data(), paper_layout())
    t = rec.time
    kw = dict(initial=(0, 0, 0), initial_std=1e-2, gate_probability=0, passes=1, observation=observation)
    f = kalman_rate(kin, t, SIG, **kw)
    seen = {}
    orig = flt._smooth

    def spy(x, P, u, Q, x0, P0):  # the filtered covariances the smoother receives
        seen["P"] = P.copy()
        return orig(x, P, u, Q, x0, P0)

    monkeypatch.setattr(flt, "_smooth", spy)
    s = kalman_rate(kin, t, SIG, smooth=True, **kw)
    assert s.smoothed and not f.smoothed
    np.testing.assert_allclose(np.sqrt(np.einsum("iik->ik", seen["P"])), f.u_omega, rtol=1e-12)
    Q = np.median(np.diff(t)) ** 2 * channel_covariance(kin, SIG)[3:6, 3:6]
    U = np.cumsum(rate_increments(kin.angular_acceleration, t), axis=1)
    xs, Ps, _, _ = fp_rts((f.omega - U).T, np.moveaxis(seen["P"], -1, 0), Fs=[np.eye(3)] * t.size,
                          Qs=[Q] * t.size)
    np.testing.assert_allclose(s.omega, xs.T + U, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(s.u_omega, np.sqrt(np.einsum("kii->ik", Ps)), rtol=1e-8)


@pytest.mark.parametrize("seed", [0, 3])
def test_smoother_gains_sqrt2_and_stays_honest(seed):
    # Random walk (increment noise s_q) observed in white noise (s_r >> s_q): the steady smoother variance
    # is half the filter's, so u falls by ~1/sqrt(2) and so must the actual error; normalised errors stay
    # ~N(0, 1) (band as in test_gfimu_offsets: ~100 independent values -> 0.55..1.45).
    rec, tr, _ = simulate_gfimu(paper=True, fs=5000, duration=3, seed=seed)
    w = tr.data(["wx", "wy", "wz"])
    f = angular_velocity(rec.data(), rec.time, paper_layout(), bias_std=BIAS)
    s = angular_velocity(rec.data(), rec.time, paper_layout(), bias_std=BIAS, smooth=True)
    assert s.filter.smoothed
    mid = slice(rec.time.size // 10, -rec.time.size // 10)  # away from both ends, where the smoother is steady
    ratio_u = np.median(s.u_omega[2, mid]) / np.median(f.u_omega[2, mid])
    assert 0.6 < ratio_u < 0.8
    ef = error_statistics(f.omega, w)["kalman"].std_error[2]
    es = error_statistics(s.omega, w)["kalman"].std_error[2]
    assert es < 0.85 * ef
    z = (s.omega["kalman"][2] - w[2]) / s.u_omega[2]
    assert 0.55 < z.std() < 1.45 and abs(z.mean()) < 0.6
    np.testing.assert_array_equal(s.filter.offsets, f.filter.offsets)
