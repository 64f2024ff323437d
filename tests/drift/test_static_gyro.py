"""Preset ``known`` on a real static gyro (MPU6050 at rest for 10 minutes, sunsided/sensor-fusion, EUPL-1.2).

tests/data/imu_static_gyro_mpu6050_0p5s.csv holds 0.5-s bin means of the
recording, and for gx also the bin means of the even and of the odd raw
samples: two independent noise realisations of the same bias.  A gyro at
rest reads the Earth rate (< 0.005 deg/s), negligible against a bias of
4.5 deg/s, so the true value is 0.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from senscal.drift import correct_drift, known_setup

DATA = Path(__file__).parent.parent / "data" / "imu_static_gyro_mpu6050_0p5s.csv"


@pytest.fixture(scope="module")
def gyro():
    return pd.read_csv(DATA)


def test_even_and_odd_samples_give_the_same_bias_within_u(gyro):
    t = gyro["t"].to_numpy()
    ra = correct_drift(known_setup(["gx_a"], 0.0), gyro["gx_a"].to_numpy(), t, smooth=True, compare=False)
    rb = correct_drift(known_setup(["gx_b"], 0.0), gyro["gx_b"].to_numpy(), t, smooth=True, compare=False)
    # Same bias, independent noise: the difference has at most the combined u
    # (the shared bias wander is in both u, so this is conservative).  Checked
    # at ten times spread over the record, each at 99.9 % two-sided.
    idx = np.linspace(0, t.size - 1, 10).astype(int)
    d = ra.bias[0, idx] - rb.bias[0, idx]
    u = np.hypot(ra.bias_std[0, idx], rb.bias_std[0, idx])
    assert np.all(np.abs(d) < 3.29 * u)
    assert 4.3 < ra.bias[0, -1] < 4.7  # the README's "about 4.5 deg/s"


def test_static_gyro_model_is_adequate(gyro):
    t = gyro["t"].to_numpy()
    r = correct_drift(known_setup(["gx", "gy", "gz"], 0.0), gyro[["gx", "gy", "gz"]].to_numpy().T, t, compare=False)
    assert r.warnings == () and r.check.adequate
    # The white noise of the bin means is resolved (positive, with a u) and
    # below the channel's total spread, which also holds the bias wander.
    for c in ("gx", "gy", "gz"):
        p = {q.name: q for q in r.noise}[f"{c}_noise_std"]
        assert p.estimated and p.std is not None and 0 < p.value < gyro[c].std()


def test_cli_known_preset_on_the_gyro(cli, tmp_path):
    r = cli("drift", DATA, "--preset", "known", "--channels", "gx,gy,gz", "--true-value", "0", "--json", "--strict",
            "--no-compare")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert set(doc["channels"]) == {"gx", "gy", "gz"} and doc["warnings"] == []
    assert abs(doc["channels"]["gx"]["bias"] - 4.52) < 0.05
