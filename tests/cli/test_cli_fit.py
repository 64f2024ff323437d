"""``senscal fit`` on files written by other programs, and its errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest


@pytest.fixture
def csv_file(tmp_path):
    rng = np.random.default_rng(4)
    fs = 1000.0
    t = np.arange(3000) / fs
    truth = {"p": (1.2, 0.4, -0.3, 12.0), "q": (0.4, -2.0, 5.0, 12.0)}
    df = pd.DataFrame({"t": t})
    for name, (a, ph, c, f) in truth.items():
        df[name] = a * np.sin(2 * math.pi * f * t + ph) + c + rng.normal(0, 0.02, t.size)
    path = tmp_path / "daq.csv"
    df.to_csv(path, index=False)  # written by pandas, not by senscal
    return path, truth


def test_fit_json_within_uncertainty(cli, csv_file):
    path, truth = csv_file
    r = cli("fit", path, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["file"] == str(path)
    for name, (a, ph, c, f) in truth.items():
        d = doc["channels"][name]
        assert set(d) >= {"frequency_hz", "amplitude", "phase_deg", "offset", "u_frequency_hz", "u_amplitude",
                          "u_phase_deg", "u_offset", "residual_rms", "snr_db", "n_samples"}
        assert abs(d["amplitude"] - a) < 4 * d["u_amplitude"]
        assert abs(d["offset"] - c) < 4 * d["u_offset"]
        assert abs(d["frequency_hz"] - f) < 4 * d["u_frequency_hz"]
        dph = math.remainder(math.radians(d["phase_deg"]) - ph, 2 * math.pi)
        assert abs(math.degrees(dph)) < 4 * d["u_phase_deg"]


def test_fit_known_frequency_channel_and_harmonics(cli, csv_file):
    path, _ = csv_file
    r = cli("fit", path, "--channel", "q", "--freq", "12", "--harmonics", "2", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert list(doc["channels"]) == ["q"]
    assert doc["channels"]["q"]["u_frequency_hz"] == 0.0
    assert "thd_percent" in doc["channels"]["q"]


def test_fit_table_shows_expanded(cli, csv_file):
    path, _ = csv_file
    r = cli("fit", path, "--freq", "12")
    assert r.code == 0
    assert "k=2" in r.out and "p" in r.out


@pytest.mark.parametrize(
    "args, pattern",
    [
        (["fit", "missing.csv"], "file not found"),
        (["fit", "{f}", "--channel", "zz"], "no channel 'zz'"),
        (["fit", "{f}", "--freq", "900"], "Nyquist"),
        (["fit", "{f}", "--time-column", "time"], "no time column 'time'"),
    ],
)
def test_fit_user_errors_one_line_exit_2(cli, csv_file, args, pattern):
    path, _ = csv_file
    r = cli(*[a.format(f=path) for a in args])
    assert r.code == 2
    assert pattern in r.err
    assert len(r.err.strip().splitlines()) == 1
    assert "Traceback" not in r.err


def test_nan_file(cli, tmp_path):
    p = tmp_path / "n.csv"
    p.write_text("t,x\n0,1\n0.1,NaN\n0.2,1\n0.3,0\n0.4,1\n0.5,0\n")
    r = cli("fit", str(p))
    assert r.code == 2 and "NaN at sample 1" in r.err


def test_simulate_then_fit(cli, tmp_path):
    r = cli("simulate", "sine", "--out", tmp_path, "--seed", "3")
    assert r.code == 0, r.err
    truth = json.loads((tmp_path / "sine_truth.json").read_text())
    doc = json.loads(cli("fit", tmp_path / "sine.csv", "--json").out)
    for name, tr in truth["channels"].items():
        d = doc["channels"][name]
        assert abs(d["amplitude"] - tr["amplitude"]) < 4 * d["u_amplitude"]


def test_console_script_runs_as_subprocess(tmp_path):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "senscal", "fit", str(tmp_path / "none.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().startswith("senscal: error: file not found")


def test_demo_sinefit_only(cli, tmp_path):
    r = cli("demo", "--out", tmp_path, "--only", "sinefit")
    assert r.code == 0, r.err
    assert (tmp_path / "index.html").exists()
    html = (tmp_path / "index.html").read_text()
    assert "Sine fit" in html and "data:image/png;base64" in html


@pytest.mark.parametrize("args", [["fit"], ["fit", "x.csv", "--bogus"], ["nosuch"], ["fit", "x.csv", "--freq", "abc"]])
def test_usage_errors_exit_2_without_traceback(cli, args):
    r = cli(*args)
    assert r.code == 2
    assert "Traceback" not in r.err


def test_demo_unknown_job(cli, tmp_path):
    r = cli("demo", "--out", tmp_path, "--only", "nope")
    assert r.code == 2 and "no demo job 'nope'" in r.err and "sinefit" in r.err
