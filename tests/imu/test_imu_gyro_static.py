"""Issue 27: static poses checked with the gyro (a turn about the vertical inside a pose) and the rate-table
segments read through the poses' temperature model.

Coverage of the cases ``yaw-in-pose``, ``yaw-in-pose-unsplit`` and ``rate-table-temperature`` runs in
test_imu.py::test_coverage (2 seeds each in CI, 200 with SENSCAL_MC=full in benchmarks/bench_coverage.py imu).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal.diagnostics import has_warning


def _calibrate(rec, **kw):
    from senscal.imu import calibrate_imu

    return calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s",
                         **kw)


def test_turn_about_gravity_is_invisible_to_the_accelerometer_and_split_by_the_gyro():
    from senscal.imu.static import split_by_gyro
    from senscal.simulate.imu import simulate_imu
    from senscal.triaxial.static import detect_static

    rec, tr = simulate_imu(seed=3, n_poses=14, yaw_poses=2)
    a, g = rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"])
    st = detect_static(a, 100.0, window_s=1.0, min_duration_s=1.0)
    assert st.n_poses == 1 + 14  # the still start and 14 poses: the two turns are invisible to the accelerometer
    gs = split_by_gyro(a, g, st, 100.0)
    assert gs.n_split == 2 and not gs.unsplit
    assert gs.static.n_poses == 1 + 14 + 2
    # Each kept piece is still: the gyro inside it stays within its still scatter.
    for s0, s1 in zip(gs.static.starts, gs.static.stops):
        assert np.all(np.abs(g[:, s0:s1].mean(axis=1) - np.asarray(tr["gyroscope"]["bias"])) < 0.01)


def test_yaw_session_calibrates_without_warning_and_recovers_truth():
    from senscal.simulate.imu import simulate_imu
    from senscal.validation.imu import score

    rec, tr = simulate_imu(seed=4, yaw_poses=3)
    r = _calibrate(rec)
    assert r.poses.static.n_poses == 1 + 30 + 3
    assert r.warnings == ()
    z = [abs(e - t) / u for e, u, t in score(r, tr).values()]
    assert max(z) < 4.0


def test_unsplittable_turn_named_and_strict_exit_3(tmp_path, capsys):
    from senscal.cli import main
    from senscal.io import write_recording
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=4, yaw_poses=3, yaw_hold_s=0.6)
    r = _calibrate(rec)
    assert has_warning(r.warnings, "pose-rotation-unsplit")
    assert r.poses.static.n_poses == 1 + 30 - 3  # the three windows holding a turn are left out
    p = write_recording(rec, tmp_path / "imu.csv", units_in_header=True)
    with pytest.raises(SystemExit) as exc:
        main(["imu", "calibrate", str(p), "--strict"])
    assert exc.value.code == 3
    assert "pose-rotation-unsplit" in capsys.readouterr().err


def test_white_session_not_cut():
    """A still gyro's 0.1 s means stay within 5 still deviations (false cut ~1 session in 1700)."""
    from senscal.imu.static import split_by_gyro
    from senscal.simulate.imu import simulate_imu
    from senscal.triaxial.static import detect_static

    rec, _ = simulate_imu(seed=6, n_poses=0, init_s=300.0)
    a, g = rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"])
    st = detect_static(a, 100.0, window_s=1.0, min_duration_s=1.0)
    gs = split_by_gyro(a, g, st, 100.0)
    assert gs.n_split == 0 and gs.trimmed == 0 and not gs.unsplit
    assert np.allclose(gs.scale, 0.002 / math.sqrt(10), rtol=0.1)


def test_rate_table_segments_use_the_gyro_scale_against_temperature():
    from senscal.simulate.imu import simulate_imu
    from senscal.simulate.imu_table import TableSpec, rate_table_of
    from senscal.validation.imu import TEMPERATURE_SCALE, score

    rec, tr = simulate_imu(seed=2, rate_table=TableSpec(temperature_end=25.0), **TEMPERATURE_SCALE)
    temp = rec.data(["temp"])[0]
    first = tr["rate_table"]["truth"]["first_sample"]
    # The option: the warm-up spans the poses, the table runs cool linearly to 25 degC.
    assert abs(temp[first - 1] - 45.0) < 0.1 and abs(temp[-1] - 25.0) < 0.1
    r = _calibrate(rec, temperature=temp, rate_table=rate_table_of(tr))
    assert not has_warning(r.warnings, "rate-table-inconsistent")
    assert r.temperature.degree_gyro_scale >= 1 and r.rate_table.scale_tc.shape == (r.temperature.degree_gyro_scale, 3)
    assert np.allclose(r.temperature.gyro_scale, r.rate_table.scale_tc)
    sc = score(r, tr)
    for k in ("gyro_scale_x", "gyro_scale_y", "gyro_scale_z", "gyro_scale_tc_x", "gyro_scale_tc_y",
              "gyro_scale_tc_z"):
        e, u, t = sc[k]
        assert abs(e - t) < 4 * u, k
    # The budget's components still add up to the combined covariance.
    tot = sum(c for _, _, c in r.rate_table.components)
    assert np.allclose(tot, r.rate_table.covariance, rtol=1e-6, atol=1e-14)


def test_combine_without_temperature_is_the_linear_solution():
    """With no temperature terms the Gauss-Newton likelihood is the closed-form linear combination."""
    from senscal.imu.ratetable import SegmentData, combine_rate_table
    from senscal.io.ratetable import RateTable

    rng = np.random.default_rng(0)
    m_true = np.diag([1.01, 0.99, 1.005]) + 1e-3 * rng.normal(size=(3, 3))
    axes = np.repeat(np.eye(3), 2, axis=0)
    rate = np.tile([1.0, -1.0], 3)
    tab = RateTable(start=np.arange(6.0), stop=np.arange(6.0) + 0.5, axis=axes, rate=rate, u_rate=np.zeros(6),
                    u_axis=np.zeros(6), source="<test>")
    var = np.full((6, 3), 1e-8)
    means = (rate[:, None] * axes) @ m_true.T + 1e-4 * rng.normal(size=(6, 3))
    seg = SegmentData(index=tuple(np.arange(10) for _ in range(6)), means=means, var_means=var)
    cp = np.eye(9) * 1e-6
    mp = m_true + 1e-3 * rng.normal(size=(3, 3))
    fit = combine_rate_table(tab, seg, np.zeros((6, 3)), np.zeros((3, 6, 6)), mp, cp)
    a = np.zeros((18, 9))
    for k in range(6):
        for i in range(3):
            a[3 * k + i, 3 * i:3 * i + 3] = rate[k] * axes[k]
    si = np.diag(1.0 / var.ravel())
    h = np.linalg.inv(np.linalg.inv(cp) + a.T @ si @ a)
    theta = h @ (np.linalg.inv(cp) @ mp.ravel() + a.T @ si @ means.ravel())
    assert np.allclose(fit.matrix.ravel(), theta, rtol=0, atol=1e-12)
    assert np.allclose(fit.covariance, h, rtol=1e-9, atol=0)


def test_rotation_tail_dropped_unnamed():
    """Short poses: a rotation's tail inside the accelerometer's window may leave too short a pose; it is left
    out like any short window, not named as a turn (that needs motion deeper than the half window)."""
    from senscal.imu.static import split_by_gyro
    from senscal.simulate.imu import simulate_imu
    from senscal.triaxial.static import detect_static

    rec, _ = simulate_imu(seed=1, pose_s=1.5)
    a, g = rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"])
    st0 = detect_static(a, 100.0, window_s=1.0, min_duration_s=1.0)
    st = detect_static(a, 100.0, window_s=1.0, min_duration_s=1.0, threshold=8 * st0.noise_variance)
    gs = split_by_gyro(a, g, st, 100.0)
    assert gs.short and not gs.unsplit
    assert gs.static.n_poses == st.n_poses - len(gs.short)


@pytest.mark.parametrize("args, text", [
    (["--yaw-poses", "99"], "--yaw-poses must lie in 0..--poses"),
    (["--yaw-poses", "2", "--yaw-deg", "nan"], "--yaw-deg be finite"),
    (["--yaw-poses", "2", "--yaw-hold", "-1"], "--yaw-hold a positive number"),
    (["--table-temperature-end", "30"], "--table-temperature-end needs --rate-table and --temperature"),
])
def test_simulator_departure_options_refused_in_one_line(cli, tmp_path, args, text):
    r = cli("simulate", "imu", "--out", tmp_path / "sim", *args)
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and text in r.err and "Traceback" not in r.err, r.err
    assert not (tmp_path / "sim").exists() or not any((tmp_path / "sim").iterdir())
