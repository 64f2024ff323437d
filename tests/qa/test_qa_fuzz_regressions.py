"""Cases the long fuzz run found (each was an internal error, exit 1), now one-line user errors."""

from __future__ import annotations

import numpy as np

from senscal.io import Recording, write_recording


def _one_line(r, match):
    assert r.code == 2, r.err
    assert len(r.err.splitlines()) == 1 and match in r.err, r.err


def test_shaft_calibrate_huge_accelerometer_value(cli, tmp_path):
    t = np.arange(1200) / 200.0
    angle = np.degrees(2 * np.pi * 1.0 * t)
    accel = 9.81 * np.sin(np.radians(angle))
    accel[500] = 1e308
    f = write_recording(Recording(channels={"angle": angle, "accel": accel}, t=t), tmp_path / "s.csv")
    _one_line(cli("shaft", "calibrate", f, "--angle", "angle", "--accel", "accel", "--angle-unit", "deg"),
              "too large for a least-squares fit")


def test_triaxial_huge_reading(cli, tmp_path):
    rng = np.random.default_rng(0)
    v = rng.normal(size=(200, 3))
    v = 50.0 * v / np.linalg.norm(v, axis=1)[:, None]
    v[17, 0] = 1e308
    f = write_recording(Recording(channels=dict(zip("xyz", v.T)), fs=10.0), tmp_path / "m.csv")
    _one_line(cli("triaxial", "calibrate", f, "--channels", "x,y,z"), "too large for the fit")


def test_fit_frequency_far_below_one_period(cli, tmp_path):
    t = np.arange(400) / 400.0
    f = write_recording(Recording(channels={"x": np.sin(2 * np.pi * 7 * t)}, t=t), tmp_path / "s.csv")
    _one_line(cli("fit", f, "--freq", "1e-300"), "too short")


def test_shaft_sub_micrometre_radius():
    import pytest

    from senscal.errors import InputError
    from senscal.shaft.angle import check_radius

    with pytest.raises(InputError, match="micrometre"):
        check_radius(1e-320)
    assert check_radius(0.05) == 0.05
