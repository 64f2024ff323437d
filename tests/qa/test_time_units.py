"""QA: a time column in milliseconds under a bare ``t`` header is named, not silently used (issue 20 item 2).

Each job's simulator writes seconds; the tests rewrite the time column in
milliseconds under the same bare header, as a careless logger would, and
check that the command names ``time-unit-suspect`` (``--strict``: exit 3),
that ``--time-unit ms`` or a ``t [ms]`` header gives the right answer with
no such warning, and that the seconds originals raise nothing.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from senscal.io.plausibility import (check_angular_rate, check_epoch_ms, check_known_frequency, check_logger_interval,
                                     check_sample_rate, check_span, check_time, dominant_frequency)

NAME = "time-unit-suspect"


def _to_ms(src: Path, dst: Path, header: str = "t") -> Path:
    """Copy a CSV with its ``t`` column (s) rewritten in ms under ``header``."""
    with open(src, newline="") as f:
        rows = list(csv.reader(f))
    i = rows[0].index("t")
    rows[0][i] = header
    for r in rows[1:]:
        r[i] = repr(round(float(r[i]) * 1000.0, 9))
    dst.parent.mkdir(parents=True, exist_ok=True)
    with open(dst, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return dst


def _warns(r) -> list[str]:
    return [w for w in json.loads(r.out)["warnings"] if w.startswith(NAME)]


# --- pure checks ---------------------------------------------------------------

def test_known_frequency_factor_is_named_with_its_unit():
    fs, f = 10_000.0, 80.0
    t = np.arange(4000) / fs
    y = np.sin(2 * np.pi * f * t) + 0.1 * np.random.default_rng(1).standard_normal(t.size)
    # Seconds: the periodogram peak is within a bin (2.5 Hz) of 80 Hz, nothing fires.
    assert abs(dominant_frequency(y, t) - f) < fs / t.size
    assert check_known_frequency(dominant_frequency(y, t), f) == ()
    for unit, scale in (("ms", 1e3), ("us", 1e6), ("min", 1 / 60)):
        (w,) = check_known_frequency(dominant_frequency(y, t * scale), f)
        assert w.startswith(NAME) and f"--time-unit {unit}" in w
    # A factor 2 (a wrong --freq, not a wrong unit) is not a time-unit suspicion.
    assert check_known_frequency(dominant_frequency(y, t), 2 * f) == ()


def test_time_stamp_checks_fire_on_ms_and_not_on_seconds():
    t_s = np.arange(1000) / 1000.0
    assert check_sample_rate(t_s, "velocity") == () and check_sample_rate(t_s * 1000, "velocity") != ()
    assert "whole-number time stamps" in check_sample_rate(t_s * 1000, "gfimu")[0]
    assert "whole-number" not in check_sample_rate(t_s * 1000 + 0.5, "gfimu")[0]
    assert check_sample_rate(t_s * 1000, "drift") == ()            # slow sampling is normal for drift
    epoch_s = 1.7e9 + np.arange(10.0)
    assert check_epoch_ms(epoch_s) == () and check_epoch_ms(epoch_s * 1000) != ()
    logger = np.arange(100) * 300.0
    assert check_logger_interval(logger) == () and check_logger_interval(logger * 1000) != ()
    assert check_logger_interval(np.arange(100) * 86400.0) == ()   # daily, in seconds
    ten_days = np.arange(0, 10 * 86400.0, 300.0)
    assert check_span(ten_days, "drift") == () and check_span(ten_days * 1000, "drift") != ()
    assert len(check_time(ten_days * 1000, "drift")) == 1          # one warning, however many checks fire


def test_angular_rate_against_the_array_readings():
    # The paper's array (L = 0.04 m) turning at up to 7 rad/s reads some 20 m/s^2; in ms the
    # integrated rates reach 7000 rad/s, a centripetal load of 2e6 m/s^2 no channel shows.
    assert check_angular_rate(7.0, 20.0, 0.04) == ()
    (w,) = check_angular_rate(7000.0, 20.0, 0.04)
    assert w.startswith(NAME) and "--time-unit ms" in w
    # A fast turbine rig (1000 rad/s at 0.1 m) reads its 1e5 m/s^2: plausible.
    assert check_angular_rate(1000.0, 1.2e5, 0.1) == ()


# --- commands ------------------------------------------------------------------

@pytest.fixture(scope="module")
def sims(tmp_path_factory):
    from senscal.cli import main

    root = tmp_path_factory.mktemp("sims")

    def sim(*args):
        with pytest.raises(SystemExit) as exc:
            main(["simulate", *map(str, args)])
        assert exc.value.code == 0

    sim("hydraulic", "--out", root / "h", "--seed", 1)
    sim("centrifuge", "--out", root / "c", "--seed", 1)
    sim("gfimu", "--out", root / "g", "--seed", 1, "--fs", 1000, "--duration", 4)
    sim("drift", "--out", root / "d", "--seed", 1, "--days", 2)
    return root


def test_velocity_in_ms(cli, sims, tmp_path):
    files = sorted((sims / "h").glob("hydraulic_0[1-3].csv"))
    truth = json.loads((sims / "h" / "hydraulic_truth.json").read_text())
    ms = [_to_ms(f, tmp_path / f.name) for f in files]
    args = ["--position", "position", "--velocity", "velocity", "--json"]
    r = cli("velocity", *ms, *args)
    assert r.code == 0, r.err
    assert len(_warns(r)) == 1 and NAME in r.err
    assert json.loads(r.out)["sensitivity"] > 100 * truth["sensitivity"]     # the 1000x wrong answer, now named
    assert cli("velocity", *ms, *args, "--strict").code == 3
    for r in (cli("velocity", *ms, *args, "--time-unit", "ms"),
              cli("velocity", *[_to_ms(f, tmp_path / "hdr" / f.name, "t [ms]") for f in files], *args),
              cli("velocity", *files, *args)):
        assert r.code == 0, r.err
        doc = json.loads(r.out)
        assert _warns(r) == []
        assert abs(doc["sensitivity"] - truth["sensitivity"]) < 3 * doc["U_sensitivity"]


def test_velocity_true_frequency_on_ms_data_is_never_silent(cli, sims, tmp_path):
    f = sorted((sims / "h").glob("hydraulic_*.csv"))[-1]
    freq = next(p["frequency_hz"] for p in json.loads((sims / "h" / "hydraulic_truth.json").read_text())["points"]
                if p["file"] == f.name)
    ms = _to_ms(f, tmp_path / f.name)
    # The true --freq on ms data read as s: a one-line refusal (above the Nyquist frequency of the
    # misread rate) or the named warning, never a silent result.
    r = cli("velocity", ms, "--position", "position", "--velocity", "velocity", "--freq", freq, "--json")
    if r.code == 0:
        assert _warns(r), r.out
    else:
        assert r.code == 2 and len(r.err.strip().splitlines()) == 1, r.err


def test_response_in_ms(cli, sims, tmp_path):
    files = sorted((sims / "c").glob("centrifuge_0[1-2].csv"))
    ms = [_to_ms(f, tmp_path / f.name) for f in files]
    args = ["--output", "output", "--input-amplitude", "100", "--angle", "angle", "--json"]
    r = cli("response", *ms, *args)
    assert r.code == 0, r.err
    assert len(_warns(r)) == 1
    assert json.loads(r.out)["points"][0]["frequency_hz"] < 0.1               # the 0.001x frequency, now named
    assert cli("response", *ms, *args, "--strict").code == 3
    r = cli("response", *ms, *args, "--time-unit", "ms")
    assert r.code == 0 and _warns(r) == [], r.err
    truth = json.loads((sims / "c" / "centrifuge_truth.json").read_text())
    f_true = next(p["frequency_hz"] for p in truth["points"] if p["file"] == files[0].name)
    assert math.isclose(json.loads(r.out)["points"][0]["frequency_hz"], f_true, rel_tol=1e-3)
    assert _warns(cli("response", *files, *args)) == []


def test_gfimu_in_ms(cli, sims, tmp_path):
    ms = _to_ms(sims / "g" / "gfimu.csv", tmp_path / "gfimu.csv")
    args = ["--layout", sims / "g" / "layout.csv", "--method", "integration", "--json"]
    r = cli("gfimu", ms, *args)
    assert r.code == 0, r.err
    assert len(_warns(r)) == 1
    assert cli("gfimu", ms, *args, "--strict").code == 3
    r = cli("gfimu", ms, *args, "--time-unit", "ms")
    assert r.code == 0 and _warns(r) == [] and math.isclose(json.loads(r.out)["sample_rate_hz"], 1000.0), r.err
    assert _warns(cli("gfimu", sims / "g" / "gfimu.csv", *args)) == []


def test_gfimu_at_20_khz_in_ms(cli, tmp_path):
    # 20 kHz in ms reads as 20 Hz, a plausible IMU rate: the rates themselves give it away.
    from senscal.cli import main

    with pytest.raises(SystemExit):
        main(["simulate", "gfimu", "--out", str(tmp_path / "g"), "--seed", "2", "--fs", "20000", "--duration", "0.5"])
    ms = _to_ms(tmp_path / "g" / "gfimu.csv", tmp_path / "ms.csv")
    args = ["--layout", tmp_path / "g" / "layout.csv", "--method", "integration", "--json"]
    (w,) = _warns(cli("gfimu", ms, *args))
    assert "angular rate" in w, w
    assert _warns(cli("gfimu", tmp_path / "g" / "gfimu.csv", *args)) == []


def test_drift_in_ms(cli, sims, tmp_path):
    ms = _to_ms(sims / "d" / "drift.csv", tmp_path / "drift.csv")
    args = ["--preset", "covariate", "--channels", "thermal", "--covariate", "temperature", "--no-compare", "--json"]
    r = cli("drift", ms, *args)
    assert r.code == 0, r.err
    assert len(_warns(r)) == 1
    assert cli("drift", ms, *args, "--strict").code == 3
    r = cli("drift", ms, *args, "--time-unit", "ms")
    assert r.code == 0 and _warns(r) == [], r.err
    assert _warns(cli("drift", sims / "d" / "drift.csv", *args)) == []


def test_time_unit_option_errors_are_one_line(cli, sims, tmp_path):
    f = sorted((sims / "h").glob("hydraulic_*.csv"))[0]
    hdr = _to_ms(f, tmp_path / "hdr.csv", "t [ms]")
    args = ["--position", "position", "--velocity", "velocity"]
    for extra, frag in ((["--time-unit", "s"], "contradicts the header"),
                        (["--time-unit", "fortnights"], "not a time unit"),
                        (["--time-unit", "ms", "--fs", "1000", "--time-column", "none"], "drop --time-unit")):
        r = cli("velocity", hdr, *args, *extra)
        assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and frag in r.err, r.err
    r = cli("velocity", hdr, *args, "--time-unit", "ms")                   # agrees with the header
    assert r.code == 0, r.err
