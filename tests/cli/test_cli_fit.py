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
    assert r.code == 2 and "NaN in data row 2" in r.err


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


# --- issue 13: non-signal columns, coloured noise, phase far from t = 0 ---------------------------------------

def _scope_like(tmp_path, with_signal=True):
    rng = np.random.default_rng(6)
    n = 2000
    t = np.arange(n) / 1000.0
    df = pd.DataFrame({"Sample": np.arange(n), "t": t})
    if with_signal:
        df["CH1"] = 0.9 * np.sin(2 * math.pi * 10.0 * t + 0.3) + rng.normal(0, 0.01, n)
        df["flat"] = 1.5
    path = tmp_path / "scope.csv"
    df.to_csv(path, index=False)
    return path


def test_fit_skips_counter_and_constant_columns_and_names_them(cli, tmp_path):
    path = _scope_like(tmp_path)
    r = cli("fit", path, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert list(doc["channels"]) == ["CH1"]
    assert set(doc["not_fitted"]) == {"Sample", "flat"}
    assert "sample counter" in doc["not_fitted"]["Sample"] and "constant" in doc["not_fitted"]["flat"]
    assert "channel-not-fitted: channel 'Sample' was not fitted" in r.err
    assert "channel-not-fitted: channel 'flat'" in r.err
    assert "Traceback" not in r.err
    # The same with a known frequency (the batched path).
    r = cli("fit", path, "--freq", "10", "--json")
    assert r.code == 0 and list(json.loads(r.out)["channels"]) == ["CH1"]
    # --strict: the result is printed, then exit 3 naming the first warning.
    r = cli("fit", path, "--strict")
    assert r.code == 3 and "CH1" in r.out and "channel-not-fitted" in r.err


def test_fit_error_only_when_nothing_can_be_fitted(cli, tmp_path):
    path = _scope_like(tmp_path, with_signal=False)
    r = cli("fit", path)
    assert r.code == 2
    assert "'Sample'" in r.err and "sample counter" in r.err
    assert len(r.err.strip().splitlines()) == 1 and "Traceback" not in r.err


def test_fit_coloured_noise_reported_and_strict(cli, tmp_path):
    r = cli("simulate", "sine", "--out", tmp_path, "--seed", "2", "--channels", "2", "--noise-rho", "0.9")
    assert r.code == 0, r.err
    truth = json.loads((tmp_path / "sine_truth.json").read_text())
    assert truth["noise_rho"] == 0.9
    r = cli("fit", tmp_path / "sine.csv", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    for name, d in doc["channels"].items():
        assert d["noise_model"] == "coloured" and d["residual_lag1"] > 0.8
        assert 10 < d["dof_effective"] < d["n_samples"]
        assert abs(d["amplitude"] - truth["channels"][name]["amplitude"]) < 4 * d["u_amplitude"]
    assert any(w.startswith("coloured-noise: channel 'ch1'") for w in doc["warnings"])
    assert "coloured-noise" in r.err
    r = cli("fit", tmp_path / "sine.csv", "--strict")
    assert r.code == 3 and "coloured noise" in r.out
    r = cli("fit", tmp_path / "sine.csv", "--noise-model", "white", "--json")
    assert r.code == 0 and all(d["noise_model"] == "white" for d in json.loads(r.out)["channels"].values())
    assert "assume white noise" in r.err
    r = cli("fit", tmp_path / "sine.csv", "--noise-model", "pink")
    assert r.code == 2 and "--noise-model" in r.err


def test_simulate_noise_rho_out_of_range(cli, tmp_path):
    r = cli("simulate", "sine", "--out", tmp_path, "--noise-rho", "1")
    assert r.code == 2 and "--noise-rho" in r.err and "Traceback" not in r.err


def test_fit_phase_far_from_origin_shows_centre_phase(cli, tmp_path):
    rng = np.random.default_rng(9)
    n = 2000
    t = 1e5 + np.arange(n) / 500.0
    y = 2.0 * np.sin(2 * math.pi * 13.37 * t + 0.2) + rng.normal(0, 0.05, n)
    path = tmp_path / "far.csv"
    pd.DataFrame({"t": t, "x": y}).to_csv(path, index=False, float_format="%.17g")
    r = cli("fit", path)
    assert r.code == 0, r.err
    assert "phase centre" in r.out and "record centre" in r.out
    assert "phase-origin-far: channel 'x'" in r.err
    doc = json.loads(cli("fit", path, "--json").out)
    d = doc["channels"]["x"]
    assert d["t_phase_centre_s"] == pytest.approx(1e5 + (n - 1) / 1000.0)
    assert d["u_phase_deg"] > math.degrees(1.0) > 100 * d["u_phase_centre_deg"]


def test_fit_nan_channel_is_skipped_not_the_file(cli, tmp_path):
    t = np.arange(1000) / 1000.0
    good = np.sin(2 * math.pi * 10 * t) + np.random.default_rng(1).normal(0, 0.01, t.size)
    bad = good.copy()
    bad[5] = np.nan
    p = tmp_path / "nan2.csv"
    pd.DataFrame({"t": t, "a": good, "b": bad}).to_csv(p, index=False)
    r = cli("fit", p, "--json")
    assert r.code == 0, r.err
    assert list(json.loads(r.out)["channels"]) == ["a"]
    assert "channel-not-fitted: channel 'b' was not fitted: it has NaN in data row 6" in r.err


def test_simulate_far_origin_then_fit_names_the_phase(cli, tmp_path):
    r = cli("simulate", "sine", "--out", tmp_path, "--seed", "4", "--channels", "1", "--t0", "1e5")
    assert r.code == 0, r.err
    r = cli("fit", tmp_path / "sine.csv", "--json")
    assert r.code == 0, r.err
    d = json.loads(r.out)["channels"]["ch1"]
    assert d["t_phase_centre_s"] > 1e5 and "phase-origin-far" in r.err
    assert cli("simulate", "sine", "--out", tmp_path, "--t0", "nan").code == 2
