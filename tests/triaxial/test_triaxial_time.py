"""Slow changes during a session (issue 26 item 1): the simulator's ordered tumble, offset drift and field step;
the drift and step terms chosen by evidence; time-confounded and inconsistent-blocks; --strict exit 3.

The coverage of every parameter under these departures over many seeds is in test_coverage_triaxial.py
(scenarios tumble-*, random-*); here single seeds check the mechanics."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.diagnostics import has_warning
from senscal.errors import DiagnosticError
from senscal.simulate.triaxial import simulate_magnetometer
from senscal.triaxial import calibrate
from senscal.validation.triaxial import truth_full

DRIFT = (30.0, -20.0, 25.0)


def test_simulator_tumble_drift_and_step_options():
    rec, t = simulate_magnetometer(motion="sphere", n=300, order="tumble", seed=1)
    z = rec.data()[2]
    # Z up first (the field points down, so the Z reading is negative), Z down last.
    assert np.corrcoef(np.arange(z.size), z)[0, 1] > 0.8
    rec_d, t_d = simulate_magnetometer(motion="sphere", n=300, order="tumble", drift=DRIFT, seed=1)
    d = rec_d.data() - rec.data()
    np.testing.assert_allclose(d[:, -1] - d[:, 0], DRIFT, rtol=1e-9)
    np.testing.assert_allclose(d.mean(axis=1), 0.0, atol=1e-9)  # the truth's offsets are session averages
    assert t_d["drift_linear"] == pytest.approx(list(DRIFT))
    rec_s, t_s = simulate_magnetometer(motion="sphere", n=300, field_step=100.0, noise=0.0, gains=(1, 1, 1),
                                       alpha_deg=0, beta_deg=0, gamma_deg=0, offsets=(0, 0, 0), seed=2)
    nrm = np.linalg.norm(rec_s.data(), axis=0)
    assert nrm[:150] == pytest.approx(50_000.0) and nrm[150:] == pytest.approx(50_100.0)
    assert t_s["field"] == pytest.approx(50_050.0) and t_s["field_before"] == 50_000.0
    with pytest.raises(Exception, match="sphere"):
        simulate_magnetometer(motion="planar", order="tumble")


def test_a_sensor_that_changes_halfway_is_inconsistent_blocks():
    # Two sessions glued together: the non-orthogonality changes by 0.5 deg halfway (a knock, a temperature
    # change). No drift or step term can follow that; the halves refit names it.
    a, t = simulate_magnetometer(motion="sphere", n=300, seed=7)
    b, _ = simulate_magnetometer(motion="sphere", n=300, seed=8, alpha_deg=0.8 + 0.5)
    res = calibrate(np.hstack([a.data(), b.data()]))
    assert has_warning(res.warnings, "inconsistent-blocks")
    c = res.time_terms["consistency"]
    assert not c["consistent"] and c["quantities"]["alpha"]["p_value"] < 1e-6
    # One session alone is consistent.
    res = calibrate(a.data())
    assert res.time_terms["consistency"]["consistent"] and not res.warnings


def _z(res, t):
    tv = truth_full(t)
    return {n: (p["value"] - tv[n]) / p["u"] for n, p in res.parameters.items() if p["value"] is not None}


def test_random_order_drift_is_found_modelled_and_covered():
    rec, t = simulate_magnetometer(motion="sphere", n=300, drift=DRIFT, seed=4)
    res = calibrate(rec.data())
    tt = res.time_terms
    assert tt["drift"]["adopted"] and tt["drift"]["p_value"] < 1e-4 and not tt["step"]["adopted"]
    for k, n in enumerate(("dBx", "dBy", "dBz")):
        assert abs(tt["terms"][n]["value"] - DRIFT[k]) < 3 * tt["terms"][n]["u"]
    assert max(abs(v) for v in _z(res, t).values()) < 3
    assert not has_warning(res.warnings, "time-confounded") and not has_warning(res.warnings, "inconsistent-blocks")
    # Without the term the same data are biased: the drift is what the fit found, not noise.
    assert "offsets are mid-session values" in tt["note"]


def test_random_order_field_step_is_found_at_its_time():
    rec, t = simulate_magnetometer(motion="sphere", n=300, field_step=100.0, seed=5)
    res = calibrate(rec.data())
    tt = res.time_terms
    assert tt["step"]["adopted"] and abs(tt["step"]["at_fraction"] - 0.5) <= 0.05
    assert abs(tt["terms"]["dF"]["value"] - 100.0) < 3 * tt["terms"]["dF"]["u"]
    assert abs(_z(res, t)["field"]) < 3  # the session-average field


def test_tumble_order_is_named_and_strict_refuses():
    rec, _ = simulate_magnetometer(motion="sphere", n=300, order="tumble", drift=(10.0, -7.0, 8.0), seed=6)
    res = calibrate(rec.data())
    assert has_warning(res.warnings, "time-confounded")
    w = next(x for x in res.warnings if x.startswith("time-confounded"))
    assert "random order" in w
    assert res.time_terms["bias_bound"]["drift"]["bias_in_u"] > res.time_terms["bias_limit_in_u"]
    with pytest.raises(DiagnosticError, match="time-confounded"):
        calibrate(rec.data(), strict=True)
    # The same readings shuffled: the design no longer ties a drift to the parameters.
    order = np.random.default_rng(0).permutation(300)
    res2 = calibrate(rec.data()[:, order])
    assert res2.time_terms["bias_bound"]["drift"]["bias_in_u"] < res2.time_terms["bias_limit_in_u"]


def test_white_random_session_has_no_time_warning_and_terms_can_be_switched_off():
    rec, _ = simulate_magnetometer(motion="sphere", n=300, seed=0)
    res = calibrate(rec.data())
    assert not res.time_terms["terms"] and not res.warnings
    assert calibrate(rec.data(), time_terms=False).time_terms is None


def test_cli_strict_exit_3_on_a_tumble_with_drift(cli, tmp_path):
    r = cli("simulate", "magnetometer", "--out", tmp_path, "--order", "tumble", "--drift", "30,-20,25", "--n", "300",
            "--seed", "2")
    assert r.code == 0, r.err
    f = tmp_path / "magnetometer.csv"
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert "drift" in doc["time_terms"] and any(w.startswith("time-confounded") for w in doc["warnings"])
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--strict")
    assert r.code == 3 and "time-confounded" in r.err
