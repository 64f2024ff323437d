"""Heading error before/after (level turn and tilt-compensated), the lms-on-a-turn and linearisation warnings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from senscal.diagnostics import has_warning
from senscal.simulate.triaxial import simulate_magnetometer
from senscal.triaxial import calibrate
from senscal.triaxial.heading import dip_deg, heading_deg, tilt_compensate, wrap_deg

DATA = Path(__file__).resolve().parents[1] / "data"


def test_tilt_compensation_recovers_heading_and_dip():
    """A field of known heading and dip seen by a sensor tilted up to 30 deg: the level-frame heading is exact.

    Axes x forward, y right, z down; the accelerometer reads +1 g on z when level (AN4248 convention).
    """
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    dip = math.radians(60.0)
    psi = rng.uniform(0, 360, 50)
    r = Rotation.from_euler("ZYX", np.column_stack([psi, rng.uniform(-30, 30, 50), rng.uniform(-30, 30, 50)]),
                            degrees=True)
    m = r.inv().apply([math.cos(dip), 0.0, math.sin(dip)]).T
    a = r.inv().apply([0.0, 0.0, 1.0]).T
    assert np.max(np.abs(wrap_deg(heading_deg(*tilt_compensate(m, a)) - psi))) < 1e-9
    assert np.allclose(dip_deg(m, a), 60.0)


def test_simulated_level_turn_heading_error_covers_the_truth():
    """Calibrated heading vs the true heading of each reading: within the reported U (k=2) at ~95 %."""
    inside = total = 0
    for seed in range(4):
        rec, truth = simulate_magnetometer(motion="planar", n=72, seed=seed)
        res = calibrate(rec.data())
        assert res.planarity["planar"] and res.heading is not None
        # True heading in the sensor frame: the field turns by -psi as the sensor turns by psi.
        psi_sensor = -360.0 * np.arange(72) / 72
        true = heading_deg(np.cos(np.radians(psi_sensor)), np.sin(np.radians(psi_sensor)))
        err = wrap_deg(res.heading["heading_deg"] - true)
        err = err - np.mean(err)  # the sensor's X axis defines zero heading only up to the mounting angle
        u2 = res.heading["U_after_deg"]["per_reading"]
        inside += int(np.sum(np.abs(err) <= u2 * 1.0))
        total += err.size
        assert res.heading["deviation_before_deg"]["rms"] > 5 * res.heading["U_after_deg"]["rms"]
    # Readings of one turn share their parameter error, so they are not independent trials: 4 turns x 72
    # readings only support a loose floor (the per-parameter coverage is in senscal.validation.triaxial).
    assert inside / total > 0.8


def test_lms_on_the_seed_level_turn_says_so():
    rec, _ = simulate_magnetometer(motion="planar", seed=5)  # the paper's 15-reading level turn
    res = calibrate(rec.data(), field=50_000.0, method="lms")
    assert has_warning(res.warnings, "planar-data-linearised")
    w = next(x for x in res.warnings if x.startswith("planar-data-linearised"))
    assert "--model planar" in w and res.model == "offsets"


def test_linearisation_error_is_named_when_it_exceeds_the_coverage_limit():
    rec, _ = simulate_magnetometer(motion="sphere", n=300, seed=2)  # 3 % gains, 1 deg: second order >> u
    res = calibrate(rec.data(), method="linear")
    assert has_warning(res.warnings, "linearisation-error")
    assert res.linearisation_bias["max_abs_in_u"] > res.linearisation_bias["limit_in_u"]
    ml = calibrate(rec.data())
    assert not has_warning(ml.warnings, "linearisation-error")


def test_cli_tilt_compensated_heading_on_real_tumble(cli, tmp_path):
    f = DATA / "magacc_ckexplorer_tumble_dec6.csv"
    # No time column and no stated rate: --fs 1 only labels the readings (time is not used here).
    r = cli("triaxial", "calibrate", f, "--channels", "mx,my,mz", "--accel-channels", "ax,ay,az", "--fs", "1",
            "--json", "--plot", tmp_path / "ck.png")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    th = doc["tilt_heading"]
    # The dip between field and gravity is constant: calibrating both sensors shrinks its spread.
    assert th["dip_after_deg"]["std"] < 0.2 * th["dip_before_deg"]["std"]
    assert (tmp_path / "ck_heading.png").exists()
