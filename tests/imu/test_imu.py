"""senscal imu calibrate / apply: recovery on a simulated session, outputs, CLI behaviour, bad input, coverage (issue 27).

The coverage test runs each scenario of senscal.validation.imu with its ``ci_seeds`` (2-3 seeds: each seed
is a full calibration of a 30-pose session, ~0.5 s) and SENSCAL_MC=full with 200 (the benchmark,
benchmarks/bench_coverage.py imu); check_coverage fails only when the 99.9 % Wilson interval of the coverage
misses 93-97 %, or a departure's warning does not fire.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.validation import check_coverage, mc_seeds
from senscal.validation.imu import SCENARIOS


@pytest.fixture(scope="module")
def session():
    from senscal.imu import calibrate_imu
    from senscal.simulate.imu import simulate_imu

    rec, truth = simulate_imu(seed=11)
    res = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s")
    return rec, truth, res


def test_recovers_truth_within_4u(session):
    from senscal.imu import ACCEL_NAMES, GYRO_ANGLES

    _, tr, r = session
    g, tg = r.gyroscope, tr["gyroscope"]
    for i, a in enumerate("xyz"):
        assert abs(g.scale[i] - tg[f"scale_{a}"]) < 4 * g.u_scale[i]
    for i, n in enumerate(GYRO_ANGLES):
        assert abs(g.angles[i] - tg[f"angle_{n}"]) < 4 * g.u_angles[i]
    ua = np.sqrt(np.diag(r.accel_covariance))
    for i, n in enumerate(ACCEL_NAMES):
        assert abs(r.accel_values[i] - tr["accelerometer"][n]) < 4 * ua[i]
    # Issue 27: 30 poses at MEMS noise give a gyro scale u below 0.1 %.
    assert np.all(g.u_scale / np.abs(g.scale) < 1e-3)
    assert r.poses.static.n_poses == 31
    # The calibrated gyro predicts the next gravity direction far better than the nominal one.
    assert np.sqrt(np.mean(r.residual_after_deg ** 2)) < 0.2 * np.sqrt(np.mean(r.residual_before_deg ** 2))
    assert r.warnings == ()


def test_no_static_poses_explained():
    from senscal.errors import InputError
    from senscal.imu import calibrate_imu

    rng = np.random.default_rng(0)
    t = np.arange(3000) / 100.0
    # Always turning: no still window anywhere.
    acc = np.stack([9.8 * np.cos(t), 9.8 * np.sin(t), np.zeros_like(t)]) + 0.02 * rng.normal(size=(3, t.size))
    gyr = np.stack([np.zeros_like(t), np.zeros_like(t), np.ones_like(t)])
    with pytest.raises(InputError, match=r"found at most \d+ still windows.*needs >= 12.*thresholds"):
        calibrate_imu(t, acc, gyr)


class _Run:
    def __init__(self, code, out, err):
        self.exit_code, self.stdout, self.output = code, out, out + err


def _cli(capsys, *args):
    """Run the command line as a user would (senscal.cli.main: errors -> one line, exit 2; --strict -> 3)."""
    from senscal.cli import main

    capsys.readouterr()
    try:
        main(list(args))
        code = 0
    except SystemExit as exc:
        code = exc.code or 0
    cap = capsys.readouterr()
    return _Run(code, cap.out, cap.err)


def test_cli_strict_unexcited(tmp_path, capsys):
    from senscal.io import write_recording
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=2, n_poses=20, exclude_axis=2)
    p = write_recording(rec, tmp_path / "imu.csv")
    res = _cli(capsys, "imu", "calibrate", str(p), "--json", "--strict")
    assert res.exit_code == 3
    assert "gyro-axis-unexcited" in res.output and "Traceback" not in res.output


def test_thirty_poses_mems_gyro_scale_u():
    """Issue 27: 30 poses at MEMS noise give a gyro scale u below 0.1 %, and it covers (SENSCAL_MC=full: 200)."""
    from senscal.validation import CoverageRow
    from senscal.validation.imu import run_mems, thirty_poses_mems

    n = mc_seeds(run_mems.full_seeds, run_mems.ci_seeds)
    rows, rel, flagged = thirty_poses_mems(n, 0)
    # Every session the job does not flag; a flagged one (seed 12 of 200: a yaw rotation inside a pose, named
    # rotation-too-fast and gyro-noise-coloured) is no clean 30-pose calibration.
    assert rel.shape == (n, 3) and (~flagged).sum() >= 0.9 * n and np.all(rel[~flagged] < 1e-3)
    if n < run_mems.full_seeds:
        # pooled as in test_coverage (the per-number rule needs the benchmark's seeds)
        tot = sum(r.n for r in rows)
        rows = [CoverageRow("imu", "mems-30-poses", "pooled", tot, sum(round(r.coverage * r.n) for r in rows) / tot,
                            math.nan)]
    check_coverage(rows)


def test_gyro_scale_temperature_round_trip(tmp_path):
    """The gyro's scale against temperature is fitted, saved and divided out by apply()."""
    import senscal
    from senscal.imu import calibrate_imu
    from senscal.jobs.imu import calibration_of
    from senscal.simulate.imu import simulate_imu
    from senscal.validation.imu import TEMPERATURE_SCALE

    rec, tr = simulate_imu(seed=5, n_poses=20, **TEMPERATURE_SCALE)
    temp = rec.data(["temp"])[0]
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s",
                      temperature=temp)
    te = r.temperature
    assert te.degree_gyro_scale >= 1 and len(te.scores_gyro_scale) == 3
    truth = np.asarray(TEMPERATURE_SCALE["gyro_scale_tc"])
    assert np.all(np.abs(te.gyro_scale[0] - truth) < 5 * te.u_gyro_scale[0] + 0.05 * np.abs(truth))
    back = senscal.load_calibration(calibration_of(r, gyro_unit="rad/s", temp_channel="temp").save(tmp_path / "c.json"))
    np.testing.assert_allclose(back.gyro_scale_tc, te.gyro_scale)
    # A rotation at another temperature: the saved calibration returns the rate the simulator put in.
    w_true = np.array([[0.5], [-1.0], [2.0]])
    mg = np.asarray(tr["gyroscope"]["matrix"])
    d_t = 40.0 - 25.0
    g = (1 + truth[:, None] * d_t) * (mg @ w_true) + np.asarray(tr["gyroscope"]["bias"])[:, None] \
        + np.asarray(TEMPERATURE_SCALE["gyro_bias_tc"])[:, None] * d_t
    _, w = back.apply(np.array([[0.0], [0.0], [9.80665]]), g, 40.0)
    assert np.allclose(w, w_true, rtol=2e-3, atol=2e-3)


@pytest.mark.parametrize("case", sorted(set(SCENARIOS) - {"mems-30-poses"}))
def test_coverage(case):
    from senscal.validation import CoverageRow

    run = SCENARIOS[case]
    n = mc_seeds(run.full_seeds, run.ci_seeds)
    rows = run(n, 0)
    assert rows and all(r.n > 0 for r in rows)
    if n < run.full_seeds:
        # With 2-3 seeds the per-number rule fails an honest u when 2 of 3 seeds miss (p = 3 * 0.05^2 = 0.7 %
        # per number, ~20 % over a case's ~30 numbers): CI pools a case's numbers (60-90 trials; a coverage
        # of 80 % still fails), the benchmark (SENSCAL_MC=full, 200 seeds) checks each number.
        cover = [r for r in rows if r.expect == "cover"]
        if cover:
            tot = sum(r.n for r in cover)
            hits = sum(round(r.coverage * r.n) for r in cover)
            rows = [r for r in rows if r.expect != "cover"] + [
                CoverageRow("imu", case, f"{len(cover)} numbers pooled", tot, hits / tot, math.nan, math.nan,
                            "cover", "")]
    check_coverage(rows)


def test_calibration_file_round_trip_and_apply(session, tmp_path):
    """The saved calibration (JSON and HDF5) loads through senscal.load_calibration and corrects both triads."""
    import senscal
    from senscal.imu.model import ImuCalibration
    from senscal.jobs.imu import calibration_of

    rec, tr, r = session
    cal = calibration_of(r, accel_unit="m/s^2", gyro_unit="rad/s")
    for name in ("cal.json", "cal.h5"):
        p = cal.save(tmp_path / name)
        back = senscal.load_calibration(p)
        assert isinstance(back, ImuCalibration)
        np.testing.assert_allclose(back.gyro_matrix, cal.gyro_matrix)
        np.testing.assert_allclose(back.accel_bias, cal.accel_bias)
    st = r.poses.static
    a, b = int(st.starts[3]), int(st.stops[3])
    f, w = back.apply(rec.data(["ax", "ay", "az"])[:, a:b], rec.data(["gx", "gy", "gz"])[:, a:b])
    # Still: |f| = g within the mean's noise (0.02 m/s^2 per sample), rate zero within the gyro's.
    n = b - a
    assert abs(np.linalg.norm(f.mean(axis=1)) - tr["gravity"]) < 5 * 0.02 / math.sqrt(n) + 5e-4
    assert np.all(np.abs(w.mean(axis=1)) < 5 * 0.002 / math.sqrt(n) + 3 * np.max(r.gyroscope.u_bias))


def test_cli_outputs_apply_and_save(tmp_path, capsys):
    """--out, --plot, --noise-yaml and --save from one run; 'imu apply' corrects a new recording with the file."""
    from senscal.io import read_recording, write_recording
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=7, n_poses=15)
    p = write_recording(rec, tmp_path / "imu.csv")
    new, _ = simulate_imu(seed=8, n_poses=2)
    q = write_recording(new, tmp_path / "new.csv")
    cal, png, yml, db = (tmp_path / n for n in ("cal.json", "cal.png", "imu.yaml", "reg.db"))
    res = _cli(capsys, "imu", "calibrate", str(p), "--out", str(cal), "--plot", str(png), "--noise-yaml", str(yml),
               "--save", "--sensor", "IMU-1", "--db", str(db), "--create-sensor", "imu", "--json")
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    for sec in ("accelerometer", "gyroscope"):
        for k in ("scale", "u_scale", "bias", "u_bias", "misalignment_deg"):
            assert k in doc[sec]
    assert len(doc["gravity_direction_residual_deg"]["after"]) == doc["static"]["n_poses"] - 1
    assert png.stat().st_size > 10_000 and "saved calibration" in res.output
    text = yml.read_text()
    for key in ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                "gyroscope_random_walk", "update_rate"):
        assert key in text
    # The simulator's white noise: 0.02 m/s^2 and 0.002 rad/s per sample at 100 Hz -> density sigma / sqrt(fs).
    nz = doc["noise"]
    assert np.allclose(nz["accel_noise_density"], 0.002, rtol=0.25)
    assert np.allclose(nz["gyro_noise_density"], 0.0002, rtol=0.25)
    assert len(nz["ros"]["angular_velocity_covariance"]) == 9
    saved = json.loads(cal.read_text())
    assert saved["type"] == "senscal.imu.ImuCalibration" and saved["format_version"] >= 2
    out = tmp_path / "new_cal.csv"
    app = _cli(capsys, "imu", "apply", str(q), "--params", str(cal), "--out", str(out), "--json")
    assert app.exit_code == 0, app.output
    corr = read_recording(out)
    st = np.linalg.norm(corr.data(["ax", "ay", "az"])[:, :1500].mean(axis=1))  # the 20 s still start
    assert abs(st - 9.80665) < 0.01
    assert np.all(np.abs(corr.data(["gx", "gy", "gz"])[:, :1500].mean(axis=1)) < 5e-4)
    same = _cli(capsys, "imu", "apply", str(q), "--params", str(cal), "--out", str(q))
    assert same.exit_code == 2 and "Traceback" not in same.output
    bad = _cli(capsys, "imu", "calibrate", str(p), "--gyro-channels", "gx,gy,nope")
    assert bad.exit_code == 2 and "nope" in bad.output and "Traceback" not in bad.output
    two = _cli(capsys, "imu", "calibrate", str(p), "--gyro-channels", "gx,gy")
    assert two.exit_code == 2 and "three" in two.output


def test_bad_input_one_line(tmp_path, capsys):
    """One pose, a constant temperature channel: one line, exit 2; fast rotations: a named warning."""
    from senscal.imu import calibrate_imu
    from senscal.io import write_recording
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=1, n_poses=1)
    p = write_recording(rec, tmp_path / "one.csv")
    one = _cli(capsys, "imu", "calibrate", str(p))
    assert one.exit_code == 2 and "needs >= 12" in one.output and "Traceback" not in one.output
    assert len(one.output.strip().splitlines()) == 1
    rec, _ = simulate_imu(seed=1, n_poses=14, temperature=(25.0, 25.0), temp_noise=0.0)
    p = write_recording(rec, tmp_path / "flat.csv")
    flat = _cli(capsys, "imu", "calibrate", str(p), "--temperature-channel", "temp")
    assert flat.exit_code == 2 and "temperature" in flat.output and "Traceback" not in flat.output
    rec, _ = simulate_imu(seed=2, n_poses=14, rotation_s=0.12, fs=50.0, angle_deg=(150.0, 170.0))
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), rec.data(["gx", "gy", "gz"]), gyro_unit="rad/s")
    assert any(w.startswith("rotation-too-fast") for w in r.warnings)


def test_saturated_gyro_named(session):
    from senscal.imu import calibrate_imu

    rec, _, clean = session
    gyr = rec.data(["gx", "gy", "gz"])
    clipped = np.clip(gyr, -1.0, 1.0)  # rotations reach ~2 rad/s: a +/-1 rad/s range clips them
    r = calibrate_imu(rec.time, rec.data(["ax", "ay", "az"]), clipped, gyro_unit="rad/s")
    assert any(w.startswith("gyro-saturated") for w in r.warnings)
    assert not any(w.startswith("gyro-saturated") for w in clean.warnings)
