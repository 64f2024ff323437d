"""Model algebra and the saved calibration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from senscal.errors import FileFormatError
from senscal.triaxial import TriaxialCalibration, load_calibration, matrix_to_angles, sensor_matrix

angle = st.floats(-0.2, 0.2)
gain = st.floats(0.5, 2.0)


@given(gain, gain, gain, angle, angle, angle)
def test_sensor_matrix_round_trip(kx, ky, kz, a, b, g):
    m = sensor_matrix(kx, ky, kz, a, b, g)
    assert np.allclose(np.tril(m, -1), 0.0)  # seed convention: upper triangular
    p = matrix_to_angles(m)
    assert p["Kx"] == pytest.approx(kx) and p["Ky"] == pytest.approx(ky) and p["Kz"] == pytest.approx(kz)
    assert p["alpha"] == pytest.approx(a, abs=1e-12) and p["beta"] == pytest.approx(b, abs=1e-12)
    assert p["gamma"] == pytest.approx(g, abs=1e-12)
    # Rows of S are unit vectors (real axes); small-angle form is I + dS.
    s = m / np.array([kx, ky, kz])[:, None]
    assert np.allclose(np.linalg.norm(s, axis=1), 1.0)


@given(st.floats(0.8, 1.2), angle, angle, angle, st.floats(-1000, 1000))
def test_apply_inverts_the_forward_model(kx, a, b, g, off):
    m = sensor_matrix(kx, 1.0, 1.0, a, b, g)
    bvec = np.array([off, -off / 2, off / 3])
    cal = TriaxialCalibration(model="full", method="ml", matrix=m, offsets=bvec, field=1.0)
    h = np.random.default_rng(0).normal(size=(3, 7))
    assert np.allclose(cal.apply(m @ h + bvec[:, None]), h)
    assert np.allclose(cal.apply((m @ h + bvec[:, None])[:, 0]), h[:, 0])


def test_linearised_correction_is_first_order():
    """H = H_hat - dH_hat: the error left is second order in the small errors."""
    eps = 0.01
    m = sensor_matrix(1 + eps, 1 - eps, 1.0, eps, -eps, eps)
    lin = np.array([[1 + eps, eps, eps], [0, 1 - eps, -eps], [0, 0, 1]])
    cal = TriaxialCalibration(model="linearised", method="linear", matrix=lin, offsets=np.zeros(3), field=1.0)
    h = np.random.default_rng(1).normal(size=(3, 50))
    h /= np.linalg.norm(h, axis=0)
    err = np.abs(cal.apply(m @ h) - h).max()
    assert err < 10 * eps**2


def test_save_load_round_trip(tmp_path):
    cal = TriaxialCalibration(model="planar", method="ml", matrix=np.eye(3) * 1.1, offsets=np.array([1.0, 2, 0]),
                              field=3.0, unit="nT", channels=("a", "b", "c"), plane_axes=(0, 1))
    p = cal.save(tmp_path / "c.json", extra={"note": "x"})
    back = load_calibration(p)
    assert back.plane_axes == (0, 1) and back.unit == "nT" and back.channels == ("a", "b", "c")
    h = np.ones((3, 4))
    assert np.allclose(back.apply(h), cal.apply(h))
    assert np.allclose(back.apply(h)[2], 1.0)  # the normal axis passes through


@pytest.mark.parametrize("text", ["not json", '{"format": "other"}', '{"format": "senscal.triaxial.calibration"}'])
def test_load_rejects_bad_files(tmp_path, text):
    p = tmp_path / "x.json"
    p.write_text(text)
    with pytest.raises(FileFormatError):
        load_calibration(p)
