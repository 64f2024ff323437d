"""Encoder angle handling and the Savitzky-Golay kinematics."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, strategies as st
from scipy.signal import savgol_filter

from senscal.errors import DataError, InputError
from senscal.shaft import angle_to_rad, encoder_kinematics
from senscal.shaft.angle import check_uniform, savgol, white_noise_std


@given(n=st.integers(300, 3000), half=st.integers(32, 70), deriv=st.integers(0, 2), seed=st.integers(0, 99))
def test_fft_savgol_equals_scipy(n, half, deriv, seed):
    m = 2 * half + 1
    x = np.cumsum(np.random.default_rng(seed).normal(size=n))
    want = savgol_filter(x, m, 3, deriv=deriv, delta=1e-3, mode="interp")
    got = savgol(x, m, deriv, 1e-3)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(want)))


def test_kinematics_exact_on_a_cubic_angle():
    t = np.arange(2000) * 1e-3
    theta = 1.0 + 6.0 * t + 2.5 * t**2 - 0.3 * t**3
    k = encoder_kinematics(theta, 1e-3, window=0.1)
    np.testing.assert_allclose(k.angular_velocity, 6.0 + 5.0 * t - 0.9 * t**2, atol=1e-8)
    np.testing.assert_allclose(k.angular_acceleration, 5.0 - 1.8 * t, atol=1e-6)
    assert k.window_samples == 101 and k.window == pytest.approx(0.101)


def test_quantisation_noise_estimate():
    """White angle noise of known size is found, and propagated like white noise should be."""
    rng = np.random.default_rng(4)
    t = np.arange(20000) * 1e-3
    theta = 6.0 * t + rng.normal(0, 1e-3, t.size)
    k = encoder_kinematics(theta, 1e-3, window=0.1)
    assert k.angle_noise == pytest.approx(1e-3, rel=0.03)
    e = k.edge
    assert np.std(k.angular_acceleration[e:-e]) == pytest.approx(k.u_angular_acceleration, rel=0.1)
    assert white_noise_std(np.sin(t) + rng.normal(0, 0.5, t.size), 101) == pytest.approx(0.5, rel=0.03)


def test_wrap_variants():
    true = np.linspace(-400.0, 900.0, 500)
    for wrapped in (np.mod(true, 360.0), np.mod(true + 180.0, 360.0) - 180.0):
        got = np.degrees(angle_to_rad(wrapped, "deg"))
        np.testing.assert_allclose(got - got[0], true - true[0], atol=1e-9)
    rad = angle_to_rad(np.mod(np.radians(true), 2 * np.pi), "rad")
    np.testing.assert_allclose(rad - rad[0], np.radians(true - true[0]), atol=1e-12)


def test_angle_errors():
    with pytest.raises(InputError, match="deg' or 'rad"):
        angle_to_rad([0, 1, 2], "turns")
    with pytest.raises(DataError, match="NaN"):
        angle_to_rad([0, np.nan, 2], "rad")
    with pytest.raises(DataError, match="not monotonic"):
        angle_to_rad([0.0, 1.0, 0.5, 2.0], "rad", monotonic=True)
    # Equal readings of a slow encoder are not a reversal; turning backwards throughout is fine.
    angle_to_rad([0.0, 1.0, 1.0, 2.0], "rad", monotonic=True)
    angle_to_rad([3.0, 2.0, 1.0, 1.0, 0.0], "rad", monotonic=True)
    with pytest.raises(DataError, match="irregular"):
        check_uniform(np.array([0.0, 1.0, 2.0, 3.5]))
    # a window longer than the record is refused before it becomes a sample count (issue 32: --window 1e308)
    with pytest.raises(InputError, match="longer than the record"):
        encoder_kinematics(np.arange(50.0), 1e-3, window=0.1)
