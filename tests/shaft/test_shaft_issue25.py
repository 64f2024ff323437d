"""Issue 25: the shaft regressions (once-per-turn ripple as a function of the angle; 4 % ripple at 0.7 Hz)
and the eccentric encoder disc, seed by seed (the coverage of the same cases is in test_coverage_shaft.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.diagnostics import has_warning
from senscal.shaft import calibrate_gravity, compensate
from senscal.simulate.shaft import angle_locked_motion, simulate_shaft
from senscal.validation.shaft import ANGLE_SYNC, RIPPLE_07


def test_angle_locked_motion_is_the_speed_of_the_angle():
    """The simulator's angle-locked speed: w(theta) holds, and alpha = dw/dt (finite differences of the angle)."""
    t = np.arange(20000) / 1000.0
    theta, omega, alpha = angle_locked_motion(t, 6 * math.pi, 0.03, 1.1)
    assert np.allclose(omega, 6 * math.pi * (1 + 0.03 * np.sin(theta + 1.1)), rtol=0, atol=1e-12)
    w_fd = np.gradient(theta, t)
    a_fd = np.gradient(omega, t)
    assert np.max(np.abs(w_fd - omega)[1:-1]) < 1e-4 * 6 * math.pi
    assert np.max(np.abs(a_fd - alpha)[1:-1]) < 1e-3 * np.max(np.abs(alpha))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_once_per_turn_ripple_of_the_angle_is_named_not_quoted(seed):
    """Item 1: 3 rev/s, w0 (1 + 0.03 sin(theta + 1.1)), r = 0.08 m, no --radius.

    The alpha and w^2 regressors are nearly collinear with sin/cos of the angle
    there (only a few per cent of second harmonic is left to fix their
    coefficients, and the encoder's quantisation pattern repeats with the
    angle): the old code kept them and quoted an amplitude 39 u off without a
    word.  They must be dropped and the run named ``synchronous-ripple``.
    """
    cal, _, truth = simulate_shaft(seed=seed, cal_duration=20.0, test_duration=0.5, **ANGLE_SYNC)
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    g = truth["gravity"]
    z = abs(m.amplitude - g["amplitude"]) / m.u_amplitude
    assert has_warning(m.warnings, "synchronous-ripple"), (z, m.nuisance, m.warnings)
    assert "alpha" not in m.nuisance
    # One warning a cause: the unmodelled ripple's own twice-per-turn term is not called an angle error.
    assert not has_warning(m.warnings, "encoder-eccentricity"), m.warnings
    assert m.synchronous_ripple == pytest.approx(0.03, rel=0.1)


def test_once_per_turn_ripple_with_other_ripple_is_still_modelled():
    """The same once-per-turn ripple on top of 3 % at 2.7 Hz: the coefficients are learnt there and cover."""
    zs = []
    for seed in range(4):
        cal, _, truth = simulate_shaft(seed=seed, speed_rps=3.0, radius=0.08, tilt_deg=25.0, sync_ripple=0.03,
                                       cal_duration=20.0, test_duration=0.5)
        m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
        assert m.nuisance == ("alpha", "speed2") and not has_warning(m.warnings, "synchronous-ripple")
        zs.append((m.amplitude - truth["gravity"]["amplitude"]) / m.u_amplitude)
    # Four normal z: all within 3.5 with probability 0.998.
    assert max(map(abs, zs)) < 3.5, zs


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ripple_at_07hz_gravity_within_u_and_compensation_at_the_noise_floor(seed):
    """Item 2: 4 % speed ripple at 0.7 Hz (not locked to the rotation).

    The bias must be within its u (the issue measured 5 u) and a later run,
    compensated, must reach the noise floor noise / (S r) = 0.375 rad/s^2
    (the issue measured 1.3x).  The per-sample error of 9000 samples has a
    relative spread of 1/sqrt(2 * 9000) = 0.75 %, and the calibration's own
    u adds (u_offset / r)^2 + (u_amplitude / r)^2 / 2, about 1e-6 of the
    floor squared: 1.04 is 5 spreads above 1, 1.3 fails.
    """
    cal, test, truth = simulate_shaft(seed=seed, cal_duration=20.0, test_duration=10.0, **RIPPLE_07)
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    g = truth["gravity"]
    assert abs(m.offset - g["offset"]) < 3.5 * m.u_offset, (m.offset, g["offset"], m.u_offset)
    assert abs(m.amplitude - g["amplitude"]) < 3.5 * m.u_amplitude
    assert not m.warnings
    res = compensate(m, test["accel"], test["angle"], test.time, radius=truth["radius"], angle_unit="deg",
                     remove_centripetal=True)
    e = slice(500, -500)
    err = float(np.sqrt(np.mean((res.angular_acceleration - truth["_test_angular_acceleration"])[e] ** 2)))
    floor = truth["angular_acceleration_noise_floor"]
    assert floor == pytest.approx(0.375)
    assert err / floor < 1.04, err / floor
    assert not res.warnings


def test_eccentric_disc_is_estimated_removed_and_named():
    """Item 8: a 0.05 deg once-per-turn angle error moves offset and amplitude by several u.

    It is estimated from its twice-per-turn trace (amplitude A e / 2) and removed, its noise in u; the
    term is named (a nonlinear sensor's would be removed wrongly).  A declared accuracy is the estimate's
    prior: consistent with the data, no warning, and u no larger than without it.
    """
    cal, _, truth = simulate_shaft(seed=5, cal_duration=10.0, test_duration=0.5, eccentricity_deg=0.05)
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    assert has_warning(m.warnings, "encoder-eccentricity"), m.warnings
    e = math.radians(0.05)
    assert m.twice_per_turn == pytest.approx(truth["gravity"]["amplitude"] * e / 2, abs=4 * m.u_twice_per_turn)
    assert m.angle_error == pytest.approx(e, abs=4 * m.u_angle_error)
    g = truth["gravity"]
    # Uncorrected, this seed's offset is several u off (issue 25 item 8); corrected within 3 u.
    assert abs(m.offset - g["offset"]) < 3 * m.u_offset and abs(m.amplitude - g["amplitude"]) < 3 * m.u_amplitude
    d = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", u_angle=e / math.sqrt(2))
    assert not has_warning(d.warnings, "encoder-eccentricity")
    assert d.u_offset <= m.u_offset * (1 + 1e-9) and d.u_amplitude <= m.u_amplitude * (1 + 1e-9)
    assert abs(d.offset - g["offset"]) < 3 * d.u_offset and abs(d.amplitude - g["amplitude"]) < 3 * d.u_amplitude
    # A declared accuracy the data contradict (0.001 deg against 0.05) is named: the prior would hold the
    # estimate short of the error.
    tight = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", u_angle=math.radians(0.001))
    assert has_warning(tight.warnings, "encoder-eccentricity")


def test_eccentricity_below_its_detection_is_still_covered():
    """0.01 deg: the twice-per-turn term is about 1.4 sigma, too weak to name, but the offset moves by up to
    A e / 2 = 8e-4 (about 4 u before the correction).  The correction's u covers it seed by seed: the
    uncorrected offset (a prior of ~0) misses in some of these seeds, the corrected one is within 2.5 u in all."""
    zc, zu = [], []
    for seed in range(8):
        cal, _, truth = simulate_shaft(seed=seed, cal_duration=10.0, test_duration=0.5, eccentricity_deg=0.01)
        g = truth["gravity"]
        m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
        u = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", u_angle=1e-12)
        zc.append((m.offset - g["offset"]) / m.u_offset)
        zu.append((u.offset - g["offset"]) / u.u_offset)
    assert max(map(abs, zc)) < 2.5, zc
    assert max(map(abs, zu)) > 2.0, zu


def test_once_per_turn_ripple_is_told_from_an_eccentric_disc():
    """1 % once-per-turn ripple with 3 % at 2.7 Hz: the encoder's once-per-turn deviation (0.57 deg) could be
    ripple or disc, but only a disc leaves a twice-per-turn term in the accelerometer: none here, nothing
    named, and the ripple is removed rightly, with or without a declared accuracy."""
    cal, _, truth = simulate_shaft(seed=7, cal_duration=10.0, test_duration=0.5, sync_ripple=0.01)
    g = truth["gravity"]
    for u_angle in (0.0, math.radians(0.01)):
        m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", u_angle=u_angle)
        assert m.warnings == ()
        assert math.degrees(m.once_per_turn_angle) == pytest.approx(math.degrees(0.01), rel=0.1)
        assert abs(m.amplitude - g["amplitude"]) < 3 * m.u_amplitude and abs(m.offset - g["offset"]) < 3 * m.u_offset


def test_no_angle_error_warning_on_a_clean_run():
    """The angle-error tests keep quiet on the simulator's default run (false alarm 1e-3 each)."""
    for seed in range(3):
        cal, _, _ = simulate_shaft(seed=seed, cal_duration=10.0, test_duration=0.5)
        m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
        assert m.warnings == (), m.warnings
        assert m.u_angle == 0.0


def test_u_angle_refused_when_negative():
    from senscal.errors import InputError

    cal, _, _ = simulate_shaft(seed=1, cal_duration=2.0, test_duration=0.5)
    with pytest.raises(InputError, match="u_angle"):
        calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", u_angle=-1e-3)


def test_cli_eccentric_disc_strict_exit_3_and_declared_accuracy(cli, tmp_path):
    """senscal simulate shaft --eccentricity; calibrate --strict exits 3 naming it; --u-angle-deg carries it."""
    out = tmp_path / "ecc"
    r = cli("simulate", "shaft", "--out", out, "--seed", "2", "--cal-duration", "10", "--test-duration", "1",
            "--eccentricity", "0.05")
    assert r.code == 0, r.err
    truth = json.loads((out / "shaft_truth.json").read_text())
    assert truth["eccentricity_deg"] == 0.05
    args = ("shaft", "calibrate", out / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json")
    r = cli(*args, "--strict")
    assert r.code == 3 and "encoder-eccentricity" in r.err
    doc = json.loads(r.out)
    assert doc["twice_per_turn"] > 4 * doc["u_twice_per_turn"] and doc["u_angle_deg"] == 0.0
    r = cli(*args, "--strict", "--u-angle-deg", "0.04")
    assert r.code == 0, r.err
    assert json.loads(r.out)["u_angle_deg"] == pytest.approx(0.04)
    r = cli(*args, "--u-angle-deg", "-0.01")
    assert r.code == 2 and r.err.count("\n") == 1 and "--u-angle-deg" in r.err


def test_cli_angle_locked_ripple_is_named(cli, tmp_path):
    """Item 1 from the command line: --angle-ripple 0.03 at 3 rev/s, r = 0.08 m: synchronous-ripple, exit 3."""
    out = tmp_path / "sync"
    r = cli("simulate", "shaft", "--out", out, "--seed", "1", "--speed", "3", "--radius", "0.08", "--tilt", "25",
            "--angle-ripple", "0.03", "--angle-ripple-phase", str(math.degrees(1.1)), "--cal-duration", "10",
            "--test-duration", "1")
    assert r.code == 0, r.err
    r = cli("shaft", "calibrate", out / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--strict", "--json")
    assert r.code == 3 and "synchronous-ripple" in r.err
    assert json.loads(r.out)["synchronous_ripple"] == pytest.approx(0.03, rel=0.1)
