"""``--conformity``/``--decision-rule`` on ``senscal response`` (shared by velocity and linearity): per point
conformity and probability of false accept in the JSON, the statement on the certificate and in the DCC."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import pytest


NS = {"dcc": "https://ptb.de/dcc"}


def _base(files):
    return ["response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--static-sensitivity", "0.05", "--initial-phase-deg", "90", "--json", "--u-input", "0.2%",
            "--u-static-sensitivity", "0.05%", "--u-initial-phase-deg", "0.05", "--sensor-id", "SN-1",
            "--calibration-date", "2026-01-05", "--env", "temperature=23.1+-0.5 degC"]


def test_json_points(cli, centrifuge_files):
    r = cli(*_base(centrifuge_files), "--conformity", "sensitivity=50 mV/(m/s^2)+-2%", "--decision-rule", "guard-band")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    for p in doc["points"]:
        assert p["conformity"] in ("pass", "fail")
        assert 0 <= p["probability_false_accept"] <= 0.5 * 0.0456 + 1e-9   # guard band w = U
        assert p["guard_band"] == pytest.approx(p["U_sensitivity"])
    assert doc["conformity"]["decision_rule"] == "guard-band"
    assert doc["conformity"]["lower"] == pytest.approx(0.049)
    # a tolerance far inside U: no point has its acceptance interval, none passes outright
    r = cli(*_base(centrifuge_files), "--conformity", "sensitivity=0.05+-1e-9", "--decision-rule", "non-binary")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert all(p["conformity"] != "pass" for p in doc["points"])
    assert [w.split(":")[0] for w in doc["warnings"]] == ["conformity-no-acceptance-interval"]
    r = cli(*_base(centrifuge_files), "--conformity", "sensitivity=0.05+-1e-9", "--decision-rule", "non-binary",
            "--strict")
    assert r.code == 3 and "conformity-no-acceptance-interval" in r.err
    # the simple rule has no guard band: no such warning
    r = cli(*_base(centrifuge_files), "--conformity", "sensitivity=0.05+-1e-9")
    assert r.code == 0 and json.loads(r.out)["warnings"] == []


@pytest.mark.parametrize("args, words", [
    (["--conformity", "sensitivity=0.05"], "tolerance"),
    (["--conformity", "gain=1+-1%"], "no quantity 'gain'"),
    (["--conformity", "sensitivity=0.05+-1%", "--decision-rule", "lenient"], "guard-band"),
    (["--decision-rule", "simple"], "needs --conformity"),
    (["--conformity", "sensitivity=50 m+-1%"], "sensitivity"),
])
def test_refusals(cli, centrifuge_files, args, words):
    r = cli(*_base(centrifuge_files), *args)
    assert r.code == 2 and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert words in r.err


def test_certificate_and_dcc_statement(cli, centrifuge_files, tmp_path, lab_profile):
    (tmp_path / "lab.toml").write_text(lab_profile())
    r = cli(*_base(centrifuge_files), "--lab", tmp_path / "lab.toml", "--conformity", "sensitivity=0.05+-5%",
            "--decision-rule", "non-binary", "--report", tmp_path / "c.html", "--dcc", tmp_path / "c.xml")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    verdict = doc["conformity"]["statement"]
    html = (tmp_path / "c.html").read_text()
    assert "Statement of conformity" in html and "ILAC-G8:09/2019 4.2.3" in html and verdict in html
    assert "MISSING" not in html
    from senscal.report.conformity import dcc_conformity
    from senscal.report.dcc import validate_dcc

    xml = (tmp_path / "c.xml").read_bytes()
    validate_dcc(xml)
    root = ET.fromstring(xml)
    st = [s for s in root.iter("{https://ptb.de/dcc}statement") if s.get("refType") == "senscal_conformity"]
    assert len(st) == 1
    assert st[0].findtext("dcc:conformity", namespaces=NS) == dcc_conformity(verdict) != ""
