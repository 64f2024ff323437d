"""``senscal shaft calibrate|compensate`` and ``senscal simulate shaft`` end to end."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from senscal.io import Recording, read_recording, write_recording


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.cli import main

    out = tmp_path_factory.mktemp("shaft")
    try:
        main(["simulate", "shaft", "--out", str(out), "--seed", "3", "--cal-duration", "6", "--test-duration", "4"])
    except SystemExit as exc:
        assert exc.code in (0, None)
    return out


def test_simulate_writes_recordings_and_truth(sim):
    truth = json.loads((sim / "shaft_truth.json").read_text())
    assert truth["tilt_deg"] == 20.0 and truth["gravity"]["amplitude"] == pytest.approx(9.80665 * math.cos(math.radians(20)))
    rec = read_recording(sim / "shaft_cal.csv")
    assert rec.names == ["angle", "accel"]
    assert rec["angle"].min() >= 0 and rec["angle"].max() < 360  # wrapped encoder
    assert rec.unit("angle") == "deg" and rec.unit("accel") == "m/s^2"  # units in the header


def test_calibrate_takes_the_angle_unit_from_the_header(cli, sim):
    r = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["output_unit"] == "m/s^2"


def test_calibrate_json_contract_and_model(cli, sim, tmp_path):
    model = tmp_path / "model.json"
    r = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--angle-unit", "deg",
            "--out", model, "--plot", tmp_path / "cal.png", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    for k in ("amplitude", "u_amplitude", "phase_deg", "u_phase_deg", "offset", "u_offset", "residual_rms",
              "tilt_deg", "revolutions"):
        assert isinstance(doc[k], float), k
    truth = json.loads((sim / "shaft_truth.json").read_text())
    assert abs(doc["amplitude"] - truth["gravity"]["amplitude"]) < 4 * doc["u_amplitude"]
    assert abs(doc["tilt_deg"] - 20.0) < 4 * doc["u_tilt_deg"]
    assert doc["revolutions"] == pytest.approx(6.0, abs=0.01)
    assert model.exists() and (tmp_path / "cal.png").stat().st_size > 10_000
    # Human-readable output shows k=2.
    r2 = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--angle-unit", "deg")
    assert r2.code == 0 and "k=2" in r2.out


def test_compensate_csv_columns_json_and_plot(cli, sim, tmp_path):
    model = tmp_path / "model.json"
    assert cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel",
               "--angle-unit", "deg", "--out", model).code == 0
    before = (sim / "shaft_test.csv").read_bytes()
    out = tmp_path / "out.csv"
    r = cli("shaft", "compensate", sim / "shaft_test.csv", "--model", model, "--angle", "angle", "--accel", "accel",
            "--radius", "0.1", "--angle-unit", "deg", "--centripetal", "--out", out, "--plot", tmp_path / "c.png",
            "--json")
    assert r.code == 0, r.err
    df = pd.read_csv(out)
    assert list(df.columns) == ["t", "tangential_acceleration", "angular_acceleration", "angular_acceleration_encoder"]
    back = read_recording(out)
    doc = json.loads(r.out)
    assert doc["correlation"] > 0.999
    assert doc["rms_difference"] < 2 * doc["expected_rms_difference"]
    assert doc["uncompensated_rms_difference"] > 50 * doc["rms_difference"]
    truth = read_recording(sim / "shaft_test_truth.csv")["angular_acceleration"]
    err = np.sqrt(np.mean((back["angular_acceleration"] - truth) ** 2))
    json_truth = json.loads((sim / "shaft_truth.json").read_text())
    assert err == pytest.approx(json_truth["angular_acceleration_noise_floor"], rel=0.06)
    assert (tmp_path / "c.png").exists()
    assert (sim / "shaft_test.csv").read_bytes() == before  # input untouched


def test_angle_unit_from_the_file(cli, sim, tmp_path):
    rec = read_recording(sim / "shaft_cal.csv")
    p = write_recording(Recording(channels=dict(rec.channels), t=rec.time, units={"angle": "deg", "accel": "m/s^2"}),
                        tmp_path / "cal.parquet")
    r = cli("shaft", "calibrate", p, "--angle", "angle", "--accel", "accel", "--json")
    assert r.code == 0, r.err
    r = cli("shaft", "calibrate", p, "--angle", "angle", "--accel", "accel", "--angle-unit", "rad")
    assert r.code == 2 and "contradicts" in r.err


def _one_line_error(r):
    assert r.code == 2, (r.code, r.out, r.err)
    lines = [ln for ln in r.err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("senscal: error:"), r.err
    assert "Traceback" not in r.err


def test_bad_inputs_give_one_line_errors(cli, sim, tmp_path):
    cal = sim / "shaft_cal.csv"
    base = ["shaft", "calibrate", cal, "--angle", "angle", "--accel", "accel"]
    # A file without units, in degrees, read as radians: the angle seems to reverse at each wrap.
    df = pd.read_csv(cal)
    df.columns = [c.split(" [")[0] for c in df.columns]
    df.to_csv(tmp_path / "plain.csv", index=False)
    r = cli("shaft", "calibrate", tmp_path / "plain.csv", "--angle", "angle", "--accel", "accel")
    _one_line_error(r)
    assert "--angle-unit" in r.err
    _one_line_error(cli(*base, "--angle-unit", "grad"))
    _one_line_error(cli("shaft", "calibrate", cal, "--angle", "nope", "--accel", "accel"))
    # Less than one revolution.
    rec = read_recording(cal)
    short = write_recording(rec.slice(0, 800), tmp_path / "short.csv")
    r = cli("shaft", "calibrate", short, "--angle", "angle", "--accel", "accel", "--angle-unit", "deg")
    _one_line_error(r)
    assert "revolution" in r.err
    # Not monotonic.
    df.loc[3000:3004, "angle"] = df.loc[3000:3004, "angle"].to_numpy()[::-1]
    df.to_csv(tmp_path / "back.csv", index=False)  # (units dropped: --angle-unit deg below)
    r = cli("shaft", "calibrate", tmp_path / "back.csv", "--angle", "angle", "--accel", "accel", "--angle-unit", "deg")
    _one_line_error(r)
    assert "monotonic" in r.err
    # Radius <= 0, missing model, wrong model file.
    model = tmp_path / "m.json"
    assert cli(*base, "--angle-unit", "deg", "--out", model).code == 0
    comp = ["shaft", "compensate", sim / "shaft_test.csv", "--angle", "angle", "--accel", "accel", "--angle-unit", "deg"]
    for rad in ("0", "-0.2"):
        r = cli(*comp, "--model", model, "--radius", rad)
        _one_line_error(r)
        assert "radius" in r.err
    _one_line_error(cli(*comp, "--model", tmp_path / "none.json", "--radius", "0.1"))
    (tmp_path / "other.json").write_text(json.dumps({"kind": "something else"}))
    _one_line_error(cli(*comp, "--model", tmp_path / "other.json", "--radius", "0.1"))
    # Refuse to overwrite the input.
    _one_line_error(cli(*comp, "--model", model, "--radius", "0.1", "--out", sim / "shaft_test.csv"))


def test_strict_turns_warnings_into_exit_3(cli, sim, tmp_path):
    r = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--angle-unit", "deg",
            "--sensitivity", "0.5", "--strict", "--json")
    assert r.code == 3
    assert "exceeds sensitivity" in r.err


def test_calibrate_save_to_registry(cli, tmp_path):
    sim = tmp_path / "sim"
    assert cli("simulate", "shaft", "--out", sim, "--seed", "4").code == 0
    db = tmp_path / "r.sqlite"
    r = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json",
            "--save", "--sensor", "SHAFT-1", "--create-sensor", "accelerometer", "--db", db)
    assert r.code == 0, r.err
    amp = json.loads(r.out)["amplitude"]
    h = json.loads(cli("registry", "history", "SHAFT-1", "--db", db, "--json").out)["records"]
    assert any(x["quantity"] == "gravity_amplitude" and x["value"] == pytest.approx(amp) for x in h)


def test_once_per_turn_ripple_is_named_and_strict_exits_3(cli, tmp_path):
    """An unbalanced rotor (1 % speed ripple locked to the turn, nothing else): one named warning, exit 3."""
    from senscal.cli import main

    out = tmp_path / "sync"
    try:
        main(["simulate", "shaft", "--out", str(out), "--seed", "4", "--cal-duration", "10", "--test-duration", "1",
              "--ripple", "0", "--sync-ripple", "0.01", "--noise-rho", "0.5"])
    except SystemExit as exc:
        assert exc.code in (0, None)
    truth = json.loads((out / "shaft_truth.json").read_text())
    assert truth["noise_rho"] == 0.5 and truth["calibration"]["sync_ripple"] == 0.01
    args = ("shaft", "calibrate", out / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json")
    r = cli(*args)
    assert r.code == 0
    doc = json.loads(r.out)
    assert [w.split(":")[0] for w in doc["warnings"]] == ["synchronous-ripple"]
    assert doc["synchronous_ripple"] == pytest.approx(0.01, rel=0.05)
    assert "warning: synchronous-ripple:" in r.err
    r = cli(*args, "--strict")
    assert r.code == 3 and "synchronous-ripple" in r.err
    assert json.loads(r.out)["warnings"] == doc["warnings"]  # the result is still printed before exit 3
