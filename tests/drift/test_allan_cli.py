"""``senscal allan`` end to end, on the real static MPU6050 gyro excerpt and on bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

GYRO = Path(__file__).parents[1] / "data" / "imu_static_gyro_mpu6050_0p5s.csv"


def test_real_gyro_json_table_plot(cli, tmp_path):
    out, png = tmp_path / "allan.csv", tmp_path / "allan.png"
    r = cli("allan", GYRO, "--channel", "gx", "--json", "--out", out, "--plot", png)
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert abs(doc["fs_hz"] - 2.0) < 0.01  # 0.5-s bins
    rows = doc["rows"]
    assert len(rows) >= 6 and all(x["lower"] < x["dev"] < x["upper"] for x in rows)
    nl = doc["noise_levels"]
    # White noise dominates the short taus: the deviation at the first tau is close to N / sqrt(tau).
    assert 0 < nl["u_N"] < 0.1 * nl["N"]
    assert abs(rows[0]["dev"] * np.sqrt(rows[0]["tau_s"]) - nl["N"]) < 0.1 * nl["N"]
    assert nl["B"] * 0.664 <= min(x["dev"] for x in rows) * 1.001
    tab = pd.read_csv(out)
    assert list(tab.columns[:4]) == ["tau_s", "dev", "lower", "upper"] and len(tab) == len(rows)
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert "allan-irregular-sampling" in r.err  # the host time stamps jitter


def test_text_output_and_two_halves_agree(cli):
    r = cli("allan", GYRO, "--channel", "gx", "--fs", "2")
    assert r.code == 0, r.err
    assert "N white" in r.out and "B bias instability" in r.out
    a = json.loads(cli("allan", GYRO, "-c", "gx_a", "--fs", "2", "--json").out)["noise_levels"]
    b = json.loads(cli("allan", GYRO, "-c", "gx_b", "--fs", "2", "--json").out)["noise_levels"]
    # Two independent halves of the same gyro: N agrees within the combined expanded uncertainty.
    assert abs(a["N"] - b["N"]) <= 2 * np.hypot(a["u_N"], b["u_N"])


def test_bad_input_one_line_exit_2(cli, tmp_path):
    short = tmp_path / "short.csv"
    pd.DataFrame({"t": [0.0, 1.0], "g": [1.0, 2.0]}).to_csv(short, index=False)
    for args in (("allan", short, "--channel", "g"),
                 ("allan", GYRO, "--channel", "nope"),
                 ("allan", GYRO, "--channel", "gx", "--taus", "400"),
                 ("allan", GYRO, "--channel", "gx", "--taus", "x"),
                 ("allan", GYRO, "--channel", "gx", "--confidence", "1.5"),
                 ("allan", GYRO, "--channel", "gx", "--out", tmp_path / "t.txt")):
        r = cli(*args)
        assert r.code == 2, (args, r.out, r.err)
        assert r.err.strip().count("\n") == 0 and "Traceback" not in r.err, r.err
