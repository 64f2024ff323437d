"""The shaft calibration's encoder step: ``--encoder-lines N`` (in u where the record cannot show the step) and
``encoder-step-unknown`` (the same semantics as the double centrifuge's, senscal.vibration.fits.encoder_angle).

The coverage of both cases over seeds is in test_coverage_shaft.py (scenarios ``encoder-2000-on-line`` and
``encoder-2000-on-line-declared``); these pin the mechanics seed by seed.
"""

from __future__ import annotations

import json
import math

import pytest

from senscal.diagnostics import has_warning
from senscal.errors import InputError
from senscal.shaft import calibrate_gravity
from senscal.simulate.shaft import simulate_shaft
from senscal.validation.shaft import ON_LINE


def _on_line(seed=3, start=123.4):
    cal, _, truth = simulate_shaft(seed=seed, cal_duration=10.0, test_duration=0.5, start_angle_deg=start, **ON_LINE)
    return cal, truth


def test_a_step_the_record_cannot_show_is_named_until_declared():
    """2000 counts, 2 counts per sample at a steady 1 rev/s: the readings lie on a constant-speed line, every one
    off by the same fraction of a count.  Undeclared: named.  Declared: the phase's u holds the step's share,
    the 95 % half-width of a uniform +/- step / 2 (0.475 step) combined with the fit's u."""
    cal, truth = _on_line()
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    assert has_warning(m.warnings, "encoder-step-unknown"), m.warnings
    assert m.encoder_step is None and m.u_encoder_step == (0.0, 0.0, 0.0)
    d = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", encoder_lines=2000)
    assert not has_warning(d.warnings, "encoder-step-unknown"), d.warnings
    step = 2 * math.pi / 2000
    assert d.encoder_step == pytest.approx(step) and not d.encoder_step_detected
    assert math.hypot(d.u_encoder_step[1], m.u_phase) == pytest.approx(0.475 * step / 2, rel=0.05)
    assert d.u_phase == pytest.approx(math.hypot(m.u_phase, d.u_encoder_step[1]), rel=1e-6)
    # a constant angle error does not move amplitude or offset
    assert d.u_encoder_step[0] < 0.1 * d.u_amplitude and d.u_encoder_step[2] < 0.1 * d.u_offset
    # The start angle put every reading this far from the angle: the undeclared phase misses, the declared covers.
    ph_true = math.radians(truth["gravity"]["phase_deg"])
    assert abs(d.phase - ph_true) < 2 * d.u_phase
    err = abs(m.phase - ph_true)
    assert err > 2 * m.u_phase, (err, m.u_phase)


def test_a_step_the_record_shows_is_detected_and_left_to_the_residual():
    """The simulator's default run (4096 counts, 3 % ripple: 4.1 counts per sample, varying): the step is found
    in the readings; its error varies along the record, so the residual's spectrum carries it (no type B)."""
    cal, _, _ = simulate_shaft(seed=2, cal_duration=10.0, test_duration=0.5)
    m = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg")
    assert math.degrees(m.encoder_step) == pytest.approx(360 / 4096) and m.encoder_step_detected
    assert m.u_encoder_step == (0.0, 0.0, 0.0) and m.warnings == ()
    # a declared step finer than the readings' grid gives way to the grid (the readings cannot be finer)
    d = calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", encoder_lines=8192)
    assert math.degrees(d.encoder_step) == pytest.approx(360 / 4096) and d.encoder_step_detected


@pytest.mark.parametrize("bad", [2, 3.5, -1000, 0])
def test_encoder_lines_refused_unless_a_whole_number_of_counts(bad):
    cal, _ = _on_line()
    with pytest.raises(InputError, match="encoder lines"):
        calibrate_gravity(cal["accel"], cal["angle"], cal.time, angle_unit="deg", encoder_lines=bad)


def test_cli_encoder_lines(cli, tmp_path):
    """simulate shaft --start-angle; calibrate --strict exits 3 naming encoder-step-unknown, 0 with --encoder-lines,
    and the JSON states the step; a bad count is one line on stderr, exit 2."""
    out = tmp_path / "enc"
    r = cli("simulate", "shaft", "--out", out, "--seed", "4", "--cal-duration", "10", "--test-duration", "1",
            "--encoder-counts", "2000", "--ripple", "0", "--start-angle", "77.7")
    assert r.code == 0, r.err
    assert json.loads((out / "shaft_truth.json").read_text())["start_angle_deg"] == pytest.approx(77.7)
    args = ("shaft", "calibrate", out / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json", "--strict")
    r = cli(*args)
    assert r.code == 3 and "encoder-step-unknown" in r.err
    assert json.loads(r.out)["encoder_step_deg"] is None
    r = cli(*args, "--encoder-lines", "2000")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["encoder_step_deg"] == pytest.approx(0.18) and doc["encoder_step_detected"] is False
    assert doc["u_encoder_step"]["phase_deg"] > 0
    r = cli(*args, "--encoder-lines", "3")
    assert r.code == 2 and r.err.count("\n") == 1 and "--encoder-lines" in r.err
