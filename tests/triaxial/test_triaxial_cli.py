"""The triaxial commands: contract, files, and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from senscal.io import read_recording


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.cli import main

    d = tmp_path_factory.mktemp("tri")
    for motion in ("sphere", "planar", "tumble"):
        try:
            main(["simulate", "magnetometer", "--out", str(d / motion), "--motion", motion, "--seed", "3"])
        except SystemExit as exc:
            assert not exc.code
    return d


def test_calibrate_json_and_apply(cli, sim, tmp_path):
    f = sim / "sphere" / "magnetometer.csv"
    src = f.read_bytes()
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--field", "50000", "--json",
            "--out", tmp_path / "p.json", "--plot", tmp_path / "p.png")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    truth = json.loads((sim / "sphere" / "magnetometer_truth.json").read_text())
    assert doc["model"] == "full" and doc["method"] == "ml"
    p = doc["parameters"]
    assert abs(p["alpha_deg"]["value"] - truth["alpha_deg"]) < 4 * p["alpha_deg"]["u"]
    assert p["alpha_deg"]["U_k2"] == pytest.approx(2 * p["alpha_deg"]["u"])
    assert doc["unidentifiable"] == [] and doc["coverage"]["fraction"] > 0.9
    assert doc["norm_error_after"]["std"] < doc["norm_error_before"]["std"] / 10
    assert (tmp_path / "p.png").stat().st_size > 1000
    r = cli("triaxial", "apply", f, "--params", tmp_path / "p.json", "--channels", "x,y,z", "--out", tmp_path / "c.csv")
    assert r.code == 0, r.err
    c = read_recording(tmp_path / "c.csv")
    n = np.linalg.norm(c.data(["x", "y", "z"]), axis=0)
    assert abs(np.std(n) - truth["noise_std"]) < 0.2 * truth["noise_std"]
    assert f.read_bytes() == src  # input never modified


def test_planar_protocol_output_names_unidentifiable(cli, sim):
    r = cli("triaxial", "calibrate", sim / "planar" / "magnetometer.csv", "--channels", "x,y,z", "--field", "50000",
            "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    pairs = [sorted(g["parameters"]) for g in doc["unidentifiable"]]
    assert ["Bx", "alpha"] in pairs and ["By", "beta"] in pairs
    # Whichever model the held-out evidence picks, alpha is never quoted as a number.
    assert doc["parameters"].get("alpha_deg", {"value": None})["value"] is None
    assert doc["planarity"]["planar"] and doc["heading"]["U_after_deg"]["k"] == 2
    r = cli("triaxial", "calibrate", sim / "planar" / "magnetometer.csv", "--channels", "x,y,z", "--field", "50000",
            "--strict")
    assert r.code == 3 and "alpha cannot be told from Bx" in r.err and len(r.err.strip().splitlines()) == 1


def test_lms_and_linear_methods(cli, sim):
    f = sim / "sphere" / "magnetometer.csv"
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--field", "50000", "--method", "lms", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["method"] == "lms" and "dKx" in doc["parameters"] and doc["parameters"]["dKx"]["u"] is None
    assert doc["lms_vs_least_squares"]["epochs"] == 50
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--field", "50000", "--method", "linear")
    assert r.code == 0 and "dKx" in r.out


def test_static_accelerometer_session(cli, sim):
    r = cli("triaxial", "calibrate", sim / "tumble" / "magnetometer.csv", "--channels", "x,y,z", "--field", "9.80665",
            "--static", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["static"]["n_poses"] == 30 and doc["model"] == "full"


@pytest.mark.parametrize("args, text", [
    (["--channels", "x,y"], "exactly three"),
    (["--channels", "x,y,q"], "no channel 'q'"),
    (["--channels", "x,y,z", "--method", "magic"], "unknown method"),
    (["--channels", "x,y,z", "--model", "cubic"], "unknown model"),
    (["--channels", "x,y,z", "--field", "-3"], "positive"),
    (["--channels", "x,y,z", "--method", "lms", "--lr", "0"], "learning rate"),
])
def test_calibrate_bad_input_is_one_line_exit_2(cli, sim, args, text):
    r = cli("triaxial", "calibrate", sim / "sphere" / "magnetometer.csv", *args)
    assert r.code == 2, (r.out, r.err)
    assert text in r.err and len(r.err.strip().splitlines()) == 1 and "Traceback" not in r.err


def test_apply_bad_params_file(cli, sim, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"hello": 1}')
    r = cli("triaxial", "apply", sim / "sphere" / "magnetometer.csv", "--params", bad, "--channels", "x,y,z",
            "--out", tmp_path / "o.csv")
    assert r.code == 2 and "not a senscal triaxial calibration" in r.err
    r = cli("triaxial", "apply", sim / "sphere" / "magnetometer.csv", "--params", tmp_path / "none.json",
            "--channels", "x,y,z", "--out", tmp_path / "o.csv")
    assert r.code == 2 and "not found" in r.err


def test_too_few_readings_cli(cli, tmp_path):
    f = tmp_path / "few.csv"
    f.write_text("t,x,y,z\n0,1,0,0\n1,0,1,0\n2,0,0,1\n")
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z")
    assert r.code == 2 and "needs at least 5" in r.err


def test_save_to_registry(cli, sim, tmp_path):
    db = tmp_path / "reg.sqlite"
    f = sim / "planar" / "magnetometer.csv"
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--field", "50000", "--json", "--save",
            "--sensor", "MAG-1", "--create-sensor", "magnetometer", "--db", db)
    assert r.code == 0, r.err
    assert "saved calibration" in r.err
    r = cli("registry", "history", "MAG-1", "--db", db, "--json")
    assert r.code == 0, r.err
    text = r.out
    assert "gamma_deg" in text and "alpha_deg" not in text  # unidentifiable parameters are not recorded
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--sensor", "MAG-1")
    assert r.code == 2 and "add --save" in r.err
