"""Gravity compensation and the encoder check against simulated truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from senscal.errors import FileFormatError, InputError
from senscal.shaft import GravityModel, angle_to_rad, calibrate_gravity, compensate, load_model

from ._shaft_sim import cached


def _setup(seed=1, **kw):
    cal, test, truth = cached(seed, **kw)
    model = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    return model, test, truth


def _rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def test_compensated_alpha_at_the_noise_floor_uncompensated_off_by_g_cos_tilt_over_r():
    model, test, truth = _setup(1, misalignment_deg=0.0)
    res = compensate(model, test["accel"], test["angle"], test.time, radius=truth["radius"], angle_unit="deg")
    al = truth["_test_angular_acceleration"]
    n = al.size
    floor = truth["angular_acceleration_noise_floor"]  # noise / (S r), no smoothing
    # The model's own error adds sqrt(u_A^2/2 + u_C^2 + (A u_phi)^2/2) / (S r) in quadrature (negligible here).
    model_err = math.sqrt(model.u_amplitude**2 / 2 + model.u_offset**2
                          + (model.amplitude * model.u_phase) ** 2 / 2) / truth["radius"]
    expected = math.hypot(floor, model_err)
    # RMS of N white samples: relative spread 1/sqrt(2N).
    assert _rms(res.angular_acceleration - al) == pytest.approx(expected, rel=4 / math.sqrt(2 * n))
    # Smoothed with the stated Savitzky-Golay window: noise floor * |h0|; the samples are correlated over a
    # window, so only n / window_samples of them are independent.
    m = int(round(res.window * truth["fs"]))
    e = m // 2
    sm = _rms((res.angular_acceleration_smoothed - al)[e:-e])
    assert sm == pytest.approx(floor * np.sqrt(np.sum(_h0(m) ** 2)), rel=4 / math.sqrt(2 * n / m))
    # Uncompensated: off by the gravity sinusoid, amplitude g cos(tilt) / r, RMS that over sqrt(2),
    # with the bias / r in quadrature.
    unc = _rms(res.uncompensated_angular_acceleration - al)
    want = math.hypot(truth["uncompensated_error_amplitude"] / math.sqrt(2), truth["bias"] / truth["radius"])
    assert unc == pytest.approx(want, rel=0.01)
    assert res.uncompensated_rms_difference > 100 * res.rms_difference
    assert res.correlation > 0.999
    assert res.warnings == ()


def _h0(m):
    from scipy.signal import savgol_coeffs

    return savgol_coeffs(m, 3)


def test_centripetal_leakage_of_a_misaligned_axis_is_found_and_removed():
    model, test, truth = _setup(2, misalignment_deg=0.5)
    al = truth["_test_angular_acceleration"]
    floor = truth["angular_acceleration_noise_floor"]
    plain = compensate(model, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg")
    fixed = compensate(model, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg",
                       remove_centripetal=True)
    assert _rms(plain.angular_acceleration - al) > 3 * floor
    assert any("centripetal" in w for w in plain.warnings)
    assert _rms(fixed.angular_acceleration - al) == pytest.approx(floor, rel=0.05)
    assert abs(fixed.centripetal_coefficient - truth["centripetal_leakage_coefficient_m"]) < 4 * fixed.u_centripetal_coefficient
    assert abs(math.degrees(fixed.misalignment) - 0.5) < 4 * math.degrees(fixed.u_misalignment)
    # The bias did not change since calibration.
    assert abs(fixed.bias_change) < 4 * fixed.u_bias_change
    assert fixed.warnings == ()


def test_validation_statistics_are_what_noise_explains():
    model, test, truth = _setup(3)
    res = compensate(model, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg",
                     remove_centripetal=True)
    # The expected difference uses a white-noise model of the quantisation: within a factor of two.
    assert 0.5 < res.rms_difference / res.expected_rms_difference < 2.0
    assert res.noise_floor == pytest.approx(truth["angular_acceleration_noise_floor"], rel=0.05)
    assert res.residual_gravity_amplitude < 0.01 * model.amplitude


def test_another_sensor_or_remounted_is_reported():
    model, test, truth = _setup(1)
    other, _, _ = cached(9, tilt_deg=20.0, phase_deg=120.0)
    res = compensate(model, other["accel"], other["angle"], other.time, radius=0.1, angle_unit="deg")
    assert any("remounted" in w for w in res.warnings)


def test_radius_must_be_positive():
    model, test, _ = _setup(1)
    for r in (0.0, -0.1, float("nan")):
        with pytest.raises(InputError, match="radius"):
            compensate(model, test["accel"], test["angle"], test.time, radius=r, angle_unit="deg")


def test_unit_mismatch_is_refused():
    model, test, _ = _setup(1)
    m = GravityModel.from_dict({**model.to_dict(), "output_unit": "V"})
    with pytest.raises(InputError, match="calibrated in 'V'"):
        compensate(m, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg", accel_unit="m/s^2")


def test_reversing_shaft_is_compensated():
    """An oscillating shaft reverses: compensation must still work (no monotonic requirement)."""
    model, _, truth = _setup(1, misalignment_deg=0.0)
    fs = 1000.0
    t = np.arange(4000) / fs
    theta = 3.0 * np.sin(2 * np.pi * 0.5 * t)
    alpha = -3.0 * (2 * np.pi * 0.5) ** 2 * np.sin(2 * np.pi * 0.5 * t)
    rng = np.random.default_rng(0)
    accel = 0.1 * alpha + model.gravity(theta) + rng.normal(0, 0.02, t.size)
    res = compensate(model, accel, theta, t, radius=0.1)
    assert _rms(res.angular_acceleration - alpha) == pytest.approx(0.2, rel=0.1)


def test_model_round_trip(tmp_path):
    model, test, _ = _setup(1)
    p = model.save(tmp_path / "m.json")
    back = load_model(p)
    assert back.to_dict() == model.to_dict()
    assert back.amplitude == model.amplitude and back.phase == model.phase
    np.testing.assert_array_equal(back.covariance, model.covariance)
    a = compensate(model, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg")
    b = compensate(back, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg")
    np.testing.assert_array_equal(a.angular_acceleration, b.angular_acceleration)


def test_model_file_checks(tmp_path):
    model, _, _ = _setup(1)
    d = model.to_dict()
    bad = tmp_path / "bad.json"
    for doc, msg in [({**d, "kind": "imucal.Ferraris"}, "not a senscal shaft gravity model"),
                     ({**d, "format_version": 99}, "format version"),
                     ({k: v for k, v in d.items() if k != "amplitude"}, "lacks the field"),
                     ({**d, "amplitude": "x"}, "non-numeric")]:
        import json

        bad.write_text(json.dumps(doc))
        with pytest.raises(FileFormatError, match=msg):
            load_model(bad)
    bad.write_text("{not json")
    with pytest.raises(FileFormatError, match="JSON"):
        load_model(bad)
    with pytest.raises(FileFormatError, match="does not exist"):
        load_model(tmp_path / "missing.json")


def test_gravity_uncertainty_matches_covariance():
    model, _, _ = _setup(1)
    th = np.linspace(0, 2 * np.pi, 7)
    u = model.u_gravity(th)
    # At sin(theta + phase) = 0 the amplitude does not matter; the offset and phase do.
    assert np.all(u >= model.u_offset * 0.5)
    assert np.all(u <= model.u_amplitude + model.amplitude * model.u_phase + model.u_offset)


@given(steps=st.lists(st.floats(0.0, 170.0), min_size=2, max_size=200), start=st.floats(-720, 720))
def test_unwrap_recovers_any_motion_slower_than_half_a_turn_per_sample(steps, start):
    true = start + np.concatenate([[0.0], np.cumsum(steps)])
    wrapped = np.mod(true, 360.0)
    got = np.degrees(angle_to_rad(wrapped, "deg", monotonic=True))
    np.testing.assert_allclose(got - got[0], true - true[0], atol=1e-9)


@given(shift=st.floats(-400.0, 400.0), scale=st.floats(0.1, 10.0))
def test_encoder_zero_and_output_scale(shift, scale):
    """Moving the encoder zero shifts only the phase; scaling the output scales amplitude and offset."""
    cal, _, _ = cached(1, cal_duration=2.0, test_duration=1.0)
    base = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    m = calibrate_gravity(scale * cal["accel"], cal["angle"] + shift, cal.time, angle_unit="deg")
    assert m.amplitude == pytest.approx(scale * base.amplitude, rel=1e-9)
    # Invariant up to rounding in the instrumental-variable solve (1e-6 relative): far below the uncertainty.
    assert m.offset == pytest.approx(scale * base.offset, rel=1e-6, abs=1e-2 * scale * base.u_offset)
    d = math.remainder(m.phase - (base.phase - math.radians(shift)), 2 * math.pi)
    assert abs(d) < 1e-2 * base.u_phase


def test_large_misalignment_scales_the_tangential_reading_by_cos():
    """5 deg: cos(d) = 0.9962, i.e. 0.05 rad/s^2 RMS on this profile, as large as the noise floor here."""
    model, test, truth = _setup(11, misalignment_deg=5.0, noise=0.005)
    al = truth["_test_angular_acceleration"]
    res = compensate(model, test["accel"], test["angle"], test.time, radius=0.1, angle_unit="deg",
                     remove_centripetal=True)
    assert abs(math.degrees(res.misalignment) - 5.0) < 4 * math.degrees(res.u_misalignment)
    floor = truth["angular_acceleration_noise_floor"]
    assert _rms(res.angular_acceleration - al) == pytest.approx(floor, rel=0.05)
    # Without the cos(d) the error would be sqrt(floor^2 + ((1 - cos d) * rms(alpha))^2).
    assert (1 - math.cos(math.radians(5.0))) * _rms(al) > 0.9 * floor
