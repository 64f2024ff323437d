"""The array simulator's truth is self-consistent and its readings obey the rigid-body equation."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.gfimu import paper_layout, solve_kinematics
from senscal.simulate.gfimu import simulate_gfimu


def _qmul(a, b):
    return np.stack([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


@pytest.mark.parametrize("paper", [False, True])
def test_truth_is_consistent(paper):
    fs = 20000.0
    rec, tr, info = simulate_gfimu(paper=paper, fs=fs, duration=1.0, bias_g=0, noise_g=0, seed=1)
    w, al, f, q = (tr.data(n) for n in (["wx", "wy", "wz"], ["alpha_x", "alpha_y", "alpha_z"],
                                        ["f_x", "f_y", "f_z"], ["qw", "qx", "qy", "qz"]))
    # Central differences have error h^2/6 * third derivative (~(2 pi 2 Hz)^2 * alpha): relative ~1e-7 here.
    scale = np.abs(al).max()
    np.testing.assert_allclose(np.gradient(w, 1 / fs, axis=1)[:, 2:-2], al[:, 2:-2], atol=1e-5 * scale)
    dq = np.gradient(q, 1 / fs, axis=1)
    np.testing.assert_allclose(dq[:, 2:-2], 0.5 * _qmul(q, np.vstack([np.zeros_like(w[0]), w]))[:, 2:-2],
                               atol=1e-5 * np.abs(w).max())
    sol = solve_kinematics(rec.data(), paper_layout())
    np.testing.assert_allclose(sol.specific_force, f, atol=1e-9)
    np.testing.assert_allclose(sol.angular_acceleration, al, atol=1e-9)
    # At rest the array reads gravity: |f| = g when the body does not turn or translate.
    _, tr0, _ = simulate_gfimu(amplitudes_deg=(0, 0, 0), linear_amplitude=0.0, fs=100, duration=0.1, seed=0)
    np.testing.assert_allclose(np.linalg.norm(tr0.data(["f_x", "f_y", "f_z"]), axis=0), 9.80665, rtol=1e-12)


def test_bias_noise_and_mounting_errors():
    kw = dict(fs=1000, duration=5, seed=4)
    rec, tr, info = simulate_gfimu(noise_g=0, **kw)
    clean, _, _ = simulate_gfimu(noise_g=0, bias_g=0, **kw)
    np.testing.assert_allclose((rec.data() - clean.data())[:, 0], list(info["bias_m_s2"].values()), atol=1e-12)
    assert np.allclose(np.abs(list(info["bias_m_s2"].values())), 1e-4 * 9.80665)
    noisy, _, _ = simulate_gfimu(bias_g=0, **kw)
    r = noisy.data() - clean.data()
    # Sample std of 5000 draws: relative std 1 %; 5 sigma.
    np.testing.assert_allclose(r.std(axis=1), 1e-3 * 9.80665, rtol=0.05)
    mis, _, mi = simulate_gfimu(noise_g=0, bias_g=0, position_error_m=1e-3, direction_error_rad=1e-2, **kw)
    tilt = np.degrees(np.arccos(np.sum(np.array(mi["actual_directions"]) * paper_layout().directions, axis=1)))
    assert 0 < tilt.max() < 5 and np.abs(mis.data() - clean.data()).max() > 1e-3
    with pytest.raises(InputError):
        simulate_gfimu(fs=-1)
