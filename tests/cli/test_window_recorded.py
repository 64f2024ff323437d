"""A result says which part of its records it used (issue 32): --start/--stop in the JSON, the registry, the
certificate."""

from __future__ import annotations

import json

import pytest

WINDOW = {"start_s": 0.5, "stop_s": 1.5, "relative_to": "the first sample of each recording"}


@pytest.fixture(scope="module")
def sine(tmp_path_factory):
    from senscal.cli import main

    d = tmp_path_factory.mktemp("win")
    with pytest.raises(SystemExit):
        main(["simulate", "sine", "--out", str(d), "--seed", "4", "--channels", "1"])
    return d / "sine.csv"


def test_fit_json_carries_the_window_only_when_one_was_cut(cli, sine):
    r = cli("fit", sine, "--start", "500 ms", "--stop", "1.5", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["window"] == WINDOW
    assert doc["channels"]["ch1"]["n_samples"] == 1001
    # The next run in the same process cuts nothing: no window is carried over.
    r = cli("fit", sine, "--json")
    assert r.code == 0 and "window" not in json.loads(r.out)
    r = cli("fit", sine, "--stop", "1", "--json")
    assert json.loads(r.out)["window"] == {**WINDOW, "start_s": None, "stop_s": 1.0}


def test_allan_json_carries_it(cli, sine):
    r = cli("allan", sine, "-c", "ch1", "--start", "0.5", "--json")
    assert r.code == 0 and json.loads(r.out)["window"]["start_s"] == 0.5, r.err


def test_registry_record_and_certificate_carry_it(cli, tmp_path):
    assert cli("simulate", "centrifuge", "--out", tmp_path, "--seed", "3", "--freqs", "2",
               "--accelerations", "20,50,80").code == 0
    files = sorted(tmp_path.glob("centrifuge_0*.csv"))
    db, cert = tmp_path / "reg.db", tmp_path / "lin.html"
    r = cli("linearity", *files, "--output", "output", "--input-amplitudes", "20,50,80", "--angle", "angle",
            "--start", "1", "--stop", "9", "--report", cert, "--save", "--sensor", "S1", "--create-sensor",
            "accelerometer", "--db", db, "--json")
    assert r.code == 0, r.err
    want = {**WINDOW, "start_s": 1.0, "stop_s": 9.0}
    assert json.loads(r.out)["window"] == want
    assert "from 1 s to 9 s after the first sample of each recording" in cert.read_text()
    assert cli("registry", "export", tmp_path / "exp.json", "--db", db).code == 0
    (rec,) = json.loads((tmp_path / "exp.json").read_text())["sensors"][0]["calibrations"]
    assert rec["conditions"]["window"] == want and rec["result"]["window"] == want
    # Another window of the same files is another calibration, not "already saved".
    r = cli("linearity", *files, "--output", "output", "--input-amplitudes", "20,50,80", "--angle", "angle",
            "--start", "2", "--save", "--sensor", "S1", "--db", db)
    assert r.code == 0 and "already" not in r.out + r.err, r.err
    assert cli("registry", "export", tmp_path / "exp2.json", "--db", db).code == 0
    recs = json.loads((tmp_path / "exp2.json").read_text())["sensors"][0]["calibrations"]
    assert sorted(c["conditions"]["window"]["start_s"] for c in recs) == [1.0, 2.0]


def test_batch_summary_carries_the_jobs_window(cli, sine):
    r = cli("batch", "fit", sine, "--workers", "1", "--start", "500 ms", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["window"] == {**WINDOW, "stop_s": None}
    assert doc["rows"][0]["result"]["channels"]["ch1"]["n_samples"] == 1500
