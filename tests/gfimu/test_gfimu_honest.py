"""Issue 14 (gyro-free part): honest default u, lock-out recovery and its warnings, rest segment,
absolute rejection of the differential method, and the simulator's new options."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.diagnostics import warning_names
from senscal.errors import InputError
from senscal.gfimu import angular_velocity, kalman_rate, paper_layout, solve_kinematics
from senscal.simulate.gfimu import G0, simulate_gfimu


def test_default_filter_has_constant_error_states_and_no_warning():
    rec, tr, _ = simulate_gfimu(fs=1000, duration=5, seed=11)
    est = angular_velocity(rec.data(), rec.time, paper_layout())
    assert est.filter.offsets is not None and est.warnings == ()
    plain = angular_velocity(rec.data(), rec.time, paper_layout(), plain=True)
    assert plain.filter.offsets is None
    assert warning_names(plain.warnings) == ("constant-errors-ignored",)
    # The sqrt and differential observations have no constant-error states: they say so too.
    sq = angular_velocity(rec.data(), rec.time, paper_layout(), observation="sqrt")
    assert "constant-errors-ignored" in warning_names(sq.warnings)
    with pytest.raises(InputError, match="plain"):
        angular_velocity(rec.data(), rec.time, paper_layout(), plain=True, bias_std=0.01)


def _quadratic_terms(w):
    a, b, c = w
    return np.stack([-(b * b + c * c), -(a * a + c * c), -(a * a + b * b), a * b, a * c, b * c])


def test_lock_out_recovers_by_widening_the_covariance():
    # A filter that starts 2 rad/s off with a tiny stated u gates every sample of a clean record: the
    # paper's behaviour (reset_after=0) integrates on with that error; the reset re-acquires.
    fs, n = 1000.0, 4000
    t = np.arange(n) / fs
    w = np.stack([np.zeros(n), np.zeros(n), 3.0 + np.sin(2 * math.pi * t)])
    alpha = np.gradient(w, t, axis=1)
    x = np.concatenate([np.zeros((3, n)), alpha, _quadratic_terms(w)])
    lay = paper_layout()
    kin0 = solve_kinematics(np.zeros((12, n)), lay)
    from dataclasses import replace

    kin = replace(kin0, x=x)
    locked = kalman_rate(kin, t, 1e-6, initial=(0, 0, 1.0), initial_std=1e-3, reset_after=0)
    assert locked.n_gated == n and abs(locked.omega[2, -1] - w[2, -1]) > 1.5
    freed = kalman_rate(kin, t, 1e-6, initial=(0, 0, 1.0), initial_std=1e-3)
    assert freed.n_gated < 100
    np.testing.assert_allclose(freed.omega[:, 200:], w[:, 200:], atol=1e-3)


def test_mounting_errors_warn_and_strict_exits_3(cli, tmp_path):
    r = cli("simulate", "gfimu", "--out", tmp_path, "--paper", "--fs", "1000", "--duration", "20",
            "--position-error", "5e-4", "--direction-error-deg", "0.5", "--seed", "2")
    assert r.code == 0, r.err
    r = cli("gfimu", tmp_path / "gfimu.csv", "--truth", tmp_path / "gfimu_truth.csv", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert "filter-gated" in warning_names(doc["warnings"]) and "warning: filter-gated:" in r.err
    assert doc["noise_scale"] > 1
    # Before: 20000 of 20000 gated, errors 1-80 rad/s.  The re-acquired, rescaled filter stays within the
    # size of the mismatch (~1 (rad/s)^2 in W over |w| ~ 6 rad/s: a fraction of a rad/s, well under 5).
    assert max(doc["errors"]["kalman"][ax]["max_abs_error"] for ax in ("wx", "wy", "wz")) < 5
    r = cli("gfimu", tmp_path / "gfimu.csv", "--strict")
    assert r.code == 3 and "filter-gated" in r.err


def test_rest_segment_measures_the_constant_errors(cli, tmp_path):
    r = cli("simulate", "gfimu", "--out", tmp_path, "--paper", "--fs", "2000", "--duration", "3",
            "--rest", "2", "--bias-g", "1e-3", "--seed", "5")
    assert r.code == 0, r.err
    info = json.loads((tmp_path / "gfimu_truth.json").read_text())
    assert info["rest_s"] == 2
    r = cli("gfimu", tmp_path / "gfimu.csv", "--rest", "0:2", "--json", "--strict")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    lay = paper_layout()
    bias = np.array([info["bias_m_s2"][n] for n in lay.names])
    truth = solve_kinematics(np.zeros((12, 1)), lay).sensitivity[3:12] @ bias
    got = doc["rest"]["offsets"]
    z = [(o["value"] - c) / o["u"] for o, c in zip(got.values(), truth)]
    # Nine standard normals: all within 4.4 sigma with probability 1 - 9e-5.
    assert np.all(np.abs(z) < 4.4), z
    assert doc["rest"]["n_samples"] == 4000 and doc["warnings"] == []
    # A "rest" that runs into the motion is named.
    r = cli("gfimu", tmp_path / "gfimu.csv", "--rest", "0:2.5", "--json", "--strict")
    assert r.code == 3 and "rest-not-at-rest" in r.err
    for bad in ("2:1", "x:2", "0:2:3", "40:50"):
        r = cli("gfimu", tmp_path / "gfimu.csv", "--rest", bad)
        assert r.code == 2 and "rest" in r.err and "Traceback" not in r.err, (bad, r.err)
    assert cli("gfimu", tmp_path / "gfimu.csv", "--rest", "0:2", "--plain").code == 2
    assert cli("gfimu", tmp_path / "gfimu.csv", "--rest", "0:2", "--bias-std", "0.01").code == 2
    assert cli("gfimu", tmp_path / "gfimu.csv", "--rest", "0:2", "--observation", "sqrt").code == 2


def test_differential_absolute_threshold():
    # The paper's motion turns about z only: on x and y the increment D is noise, so the relative
    # 3x-median rule passes gross errors; the absolute threshold removes every sample whose u exceeds it.
    rec, tr, _ = simulate_gfimu(paper=True, fs=2000, duration=4, seed=1)
    w = tr.data(["wx", "wy", "wz"])
    # A 10 ms span (lag 20) so that the turning axis has increments well above the noise.
    rel = angular_velocity(rec.data(), rec.time, paper_layout(), methods=("differential",), lag=20)
    assert np.nanmax(np.abs(rel.omega["differential"][:2] - w[:2])) > 1e3
    u_max = 1.0
    ab = angular_velocity(rec.data(), rec.time, paper_layout(), methods=("differential",), lag=20,
                          differential_max_u=u_max)
    e = ab.omega["differential"] - w
    assert np.isfinite(e[2]).mean() > 0.5
    # Accepted samples have u <= 1 rad/s; 6 u bounds the error of 8000 x 3 Gaussian draws (p ~ 5e-5)
    # plus the biases' share (1e-4 g / D, far below u here).
    assert np.nanmax(np.abs(e)) < 6 * u_max
    assert ab.differential_rejected > rel.differential_rejected
    with pytest.raises(InputError):
        angular_velocity(rec.data(), rec.time, paper_layout(), methods=("differential",), differential_max_u=-1)


def test_differential_max_u_on_the_cli(cli, tmp_path):
    rec, _, _ = simulate_gfimu(paper=True, fs=1000, duration=2, seed=1)
    from senscal.io import write_recording

    f = write_recording(rec, tmp_path / "g.csv")
    r = cli("gfimu", f, "--method", "differential", "--differential-max-u", "1", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["differential_max_u_rad_s"] == 1
    for bad in ("0", "-1", "inf", "nan"):
        r = cli("gfimu", f, "--method", "differential", "--differential-max-u", bad)
        assert r.code == 2 and "--differential-max-u" in r.err


def test_simulator_rest_motion_and_offset_options(cli, tmp_path):
    rec, tr, info = simulate_gfimu(fs=500, duration=1, rest_s=0.5, amplitudes_deg=(5, 0, 20),
                                   freqs_hz=(3, 1, 1.5), offset_m=(0, 0.2, 0), linear_amplitude=1.0, seed=0)
    t = tr.time
    rest = t < 0.5
    for c in ("wx", "wy", "wz", "alpha_x", "alpha_y", "alpha_z"):
        assert np.all(np.abs(tr[c][rest]) < 1e-12)  # cos(-pi/2) is 6e-17, not 0
    # At rest the array reads gravity plus bias and noise only.
    np.testing.assert_allclose(np.linalg.norm(tr.data(["f_x", "f_y", "f_z"])[:, rest], axis=0), G0, rtol=1e-12)
    assert info["rest_s"] == 0.5 and info["offset_m"] == [0, 0.2, 0] and info["freqs_hz"] == [3, 1, 1.5]
    assert rec.n_samples == 750
    # The motion after the rest is the motion without rest, shifted.
    _, tr0, _ = simulate_gfimu(fs=500, duration=1, amplitudes_deg=(5, 0, 20), freqs_hz=(3, 1, 1.5),
                               offset_m=(0, 0.2, 0), linear_amplitude=1.0, seed=0)
    np.testing.assert_allclose(tr.data(["wx", "wy", "wz"])[:, ~rest], tr0.data(["wx", "wy", "wz"]), atol=1e-12)
    r = cli("simulate", "gfimu", "--out", tmp_path, "--fs", "200", "--duration", "1", "--rest", "0.5",
            "--amplitudes", "5,0,20", "--freqs", "3,1,1.5", "--offset", "0,0.2,0", "--linear-amplitude", "1",
            "--direction-error-deg", "0.5", "--seed", "1")
    assert r.code == 0, r.err
    info = json.loads((tmp_path / "gfimu_truth.json").read_text())
    assert info["amplitudes_deg"] == [5, 0, 20] and info["direction_error_rad"] == pytest.approx(math.radians(0.5))
    for args in (("--amplitudes", "1,2"), ("--freqs", "1,2,nan"), ("--rest", "-1"), ("--offset", "a,b,c"),
                 ("--direction-error", "0.01", "--direction-error-deg", "1")):
        r = cli("simulate", "gfimu", "--out", tmp_path, *args)
        assert r.code == 2 and "Traceback" not in r.err, (args, r.err)


@pytest.mark.parametrize("paper,seeds", [(False, range(8)), (True, range(3))])
def test_no_warning_when_the_model_holds(paper, seeds):
    # Each check has a false-alarm probability of 1e-6: on clean records (white noise, biases) any warning
    # at all is a failure of the check, not bad luck.
    for s in seeds:
        rec, _, _ = simulate_gfimu(paper=paper, fs=2000 if paper else 1000, duration=5, seed=100 + s)
        est = angular_velocity(rec.data(), rec.time, paper_layout())
        assert est.warnings == () and est.noise_scale == 1.0, (s, est.warnings)


def test_readme_example_with_all_methods_raises_no_warning(cli, tmp_path):
    # The differential method's gross errors on the non-turning axes (1e5 rad/s) are the method's own,
    # not a wrong time unit; the default filter has no departure to report on the simulator's data.
    r = cli("simulate", "gfimu", "--out", tmp_path, "--paper", "--fs", "2000", "--duration", "3", "--seed", "0")
    assert r.code == 0, r.err
    r = cli("gfimu", tmp_path / "gfimu.csv", "--method", "all", "--truth", tmp_path / "gfimu_truth.csv",
            "--strict", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["warnings"] == []
