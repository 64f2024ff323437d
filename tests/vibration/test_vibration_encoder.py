"""Quantised turntable encoders in the double centrifuge (issue 25 item 7).

The encoder's angle is the regressor of the fit, so its steps are an error in
the variable.  The coverage of S, S/S0 and the phase delay under 1024- to
16384-count encoders is in ``senscal.validation.vibration``
(``response-encoder-*``, run by test_coverage_vibration.py); these tests pin
the detection, the budget component, the coloured-noise sentence and the
command-line options.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.simulate.vibration import simulate_centrifuge
from senscal.vibration import response_point
from senscal.vibration.fits import angle_step, encoder_angle


@pytest.mark.parametrize("lines", [1024, 4096, 16384])
@pytest.mark.parametrize("f", [1.0, 5.0, 10.0])
def test_angle_step_found_in_counter_readings(lines, f):
    t = np.arange(1000) / 100.0
    step = 360.0 / lines
    theta = 17.3 + 360.0 * f * t
    assert angle_step(np.mod(step * np.floor(theta / step), 360.0), t) == pytest.approx(step, rel=1e-9)
    # an exact angle is not quantised, even where 10 samples a turn repeat 10 angles 36 deg apart
    assert angle_step(np.mod(theta, 360.0), t) is None


def test_angle_step_not_claimed_for_noisy_or_whole_step_increments():
    rng = np.random.default_rng(3)
    t = np.arange(1000) / 100.0
    assert angle_step(np.mod(360.0 * t + rng.normal(0, 0.01, t.size), 360.0), t) is None
    # 3.6 deg a sample is exactly 10 counts of a 1000-count encoder: the readings lie on a line, nothing to detect
    step = 0.36
    assert angle_step(np.mod(step * np.floor((5.01 + 360.0 * t) / step), 360.0), t) is None


def test_encoder_angle_uses_the_line_only_within_one_step():
    t = np.arange(2000) / 100.0
    step = 360.0 / 1024
    theta = 360.0 * t
    enc = encoder_angle(step * np.floor(theta / step), t)
    assert enc.model == "straight line" and enc.detected
    assert np.max(np.abs(enc.angle_deg - (theta - step / 2))) < 0.05 * step
    # speed ripple of 10 steps: the readings themselves, the step still known
    wobbly = theta + 10 * step * np.sin(2 * np.pi * 0.3 * t)
    enc = encoder_angle(step * np.floor(wobbly / step), t)
    assert enc.model == "readings" and enc.step_deg == pytest.approx(step)


def _point(lines, seed=2, f=10.0, **kw):
    recs, truth = simulate_centrifuge(frequencies=(f,), min_duration=10.0, encoder_lines=lines, seed=seed)
    rec, tp = recs[0], truth["points"][0]
    p = response_point(rec["output"], rec.time, input_amplitude=100.0, angle_deg=rec["angle"],
                       static_sensitivity=0.05, initial_phase=math.radians(truth["initial_phase_deg"]), **kw)
    return p, tp


def test_encoder_step_in_the_budgets_and_the_point():
    p, tp = _point(1024)
    assert p.angle_step_deg == pytest.approx(360 / 1024) and p.angle_model == "straight line"
    comp = {c.source: c.standard_uncertainty for c in p.phase_delay_budget.components}
    assert comp["encoder step"] > 0
    assert "encoder step" in {c.source for c in p.sensitivity_budget.components}
    # 10 Hz at 100 Hz sampling with 1024 counts: the steps alias onto twice the turntable frequency, the case
    # where the fit against the raw readings was 10 u off; now within U
    assert abs(math.degrees(p.phase_delay) - tp["phase_delay_deg"]) <= 2 * math.degrees(p.u_phase_delay)
    assert abs(p.sensitivity - tp["sensitivity"]) <= 2 * p.u_sensitivity
    # no encoder, no component
    q, _ = _point(0)
    assert q.angle_step_deg is None and "encoder step" not in {c.source for c in q.phase_delay_budget.components}


def test_declared_lines_and_u_angle():
    p, _ = _point(0, encoder_lines=1024, u_angle=math.radians(0.01))
    assert p.angle_step_deg == pytest.approx(360 / 1024)
    comp = {c.source: c.standard_uncertainty for c in p.phase_delay_budget.components}
    assert comp["angle reading"] == pytest.approx(math.radians(0.01))
    with pytest.raises(InputError, match="encoder lines"):
        _point(0, encoder_lines=2.5)
    recs, _ = simulate_centrifuge(frequencies=(5.0,), seed=1)
    with pytest.raises(InputError, match="angle"):
        response_point(recs[0]["output"], recs[0].time, input_amplitude=100.0, encoder_lines=1024)


def test_coloured_noise_sentence_says_what_u_assumes():
    # A correlated output residual against an exact angle (uniform steps): u uses the noise spectrum and says so.
    from senscal.simulate.sine import ar1_noise

    rng = np.random.default_rng(5)
    t = np.arange(3000) / 100.0
    theta = 40.0 + 360.0 * 1.0 * t
    y = 5.0 * np.sin(np.radians(theta) + 0.3) + ar1_noise(rng, (t.size,), 0.01, 0.9)
    exact = response_point(y, t, input_amplitude=100.0, angle_deg=np.mod(theta, 360.0))
    (we,) = [w for w in exact.warnings if w.startswith("coloured-noise")]
    assert "uses the residual's noise spectrum" in we and "time base" not in we


def test_coloured_noise_sentence_when_u_stayed_white():
    # The sine fit's own sentence speaks of a time base; against the angle (steps not uniform: a quantised or noisy
    # encoder) u stayed white, and the point's sentence must say that and not claim the spectrum.
    from types import SimpleNamespace

    from senscal.vibration.response import _angle_fit_warnings

    fit = SimpleNamespace(warnings=("coloured-noise: ... the uncertainties assume white noise (time base not "
                                    "uniform ...); resample to a uniform time base", "other-thing: x"),
                          residual_lag1=-0.7, noise_model="white")
    for step in (None, 360 / 1024):
        enc = SimpleNamespace(step_deg=step)
        out = _angle_fit_warnings(fit, enc)
        (w,) = [x for x in out if x.startswith("coloured-noise")]
        assert "assumes white noise" in w and "noise spectrum was not" not in w and "time base" not in w
        assert "uses the residual's noise spectrum" not in w and "-0.70" in w
        assert ("encoder step" in w) == (step is not None)
        assert "other-thing: x" in out


def test_cli_encoder_lines(cli, tmp_path):
    r = cli("simulate", "centrifuge", "--out", tmp_path, "--seed", "4", "--freqs", "1,10", "--encoder-lines", "1024")
    assert r.code == 0, r.err
    truth = json.loads((tmp_path / "centrifuge_truth.json").read_text())
    assert truth["encoder_lines"] == 1024
    files = sorted(str(p) for p in tmp_path.glob("centrifuge_[0-9]*.csv"))
    r = cli("response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--initial-phase-deg", str(truth["initial_phase_deg"]), "--u-angle-deg", "0.001", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    for p in doc["points"]:
        assert p["angle_step_deg"] == pytest.approx(360 / 1024) and p["angle_model"] == "straight line"
    r = cli("response", *files, "--output", "output", "--input-amplitude", "100", "--encoder-lines", "1024")
    assert r.code == 2 and "--angle" in r.err and "Traceback" not in r.err


def test_whole_counts_per_sample_is_named_or_declared():
    # 360 counts at 10 Hz and 100 Hz sampling: 36 counts a sample, the readings lie on a line one constant error
    # behind the angle; nothing in the record shows the step, so the point names it, and a declared encoder is used
    p, tp = _point(360, seed=146)
    assert p.angle_step_deg is None and "encoder-step-unknown" in " ".join(p.warnings)
    q, tq = _point(360, seed=146, encoder_lines=360)
    assert q.angle_step_deg == pytest.approx(1.0) and not any(w.startswith("encoder-step-unknown") for w in q.warnings)
    assert abs(math.degrees(q.phase_delay) - tq["phase_delay_deg"]) <= 2 * math.degrees(q.u_phase_delay)


def test_frequency_u_not_zero_for_a_nearly_exact_angle():
    # linregress's (1 - r^2) form rounds to u = 0 when the angle noise is 1e-4 deg over thousands of degrees
    from senscal.vibration.fits import cut_whole_revolutions

    rng = np.random.default_rng(314)
    t = np.arange(2000) / 100.0
    sync = cut_whole_revolutions(np.mod(33.0 + 1800.0 * t + rng.normal(0, 2e-4, t.size), 360.0), t)
    assert sync.u_frequency > 0
    assert abs(sync.frequency - 5.0) <= 4 * sync.u_frequency
