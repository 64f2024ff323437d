"""``--dcc FILE.xml`` on the calibration commands: a valid DCC with the command's own numbers, or one line and no file."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import pytest

from senscal.report.dcc import DCC_NS, SI_NS, read_dcc_quantities, validate_dcc

NS = {"dcc": DCC_NS, "si": SI_NS}

LAB = """\
name = "Vibration Lab <&> GmbH"
address = "Bundesallee 100, 38116 Braunschweig"
email = "lab@example.org"
country = "DE"
approvers = [{name = "A. Approver", role = "Head of laboratory"}]
standards = [{name = "Reference accelerometer", serial = "RS-1", certificate = "PTB-1234", traceability = "PTB"}]

[run]
customer_address = "1 Main St, Springfield"
customer_email = "qa@acme.example"
"""


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    from senscal.simulate.common import write_simulation
    from senscal.simulate.vibration import simulate_centrifuge

    d = tmp_path_factory.mktemp("cf")
    recs, truth = simulate_centrifuge(frequencies=(1.0, 5.0), seed=7, min_duration=5.0)
    write_simulation(recs, truth, d, "centrifuge")
    return sorted(str(p) for p in d.glob("centrifuge_[0-9]*.csv"))


def _args(records, lab, out):
    return ["response", *records, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--static-sensitivity", "0.05", "--initial-phase-deg", "0", "--json", "--dcc", out, "--lab", lab,
            "--customer", 'ACME "Sensors" <script>', "--item", "piezoelectric accelerometer", "--manufacturer", "ACME",
            "--serial", "SN-1&2", "--location", "laboratory", "--calibration-date", "2026-03-02",
            "--env", "temperature=23.1+-0.5 degC"]


def test_response_dcc_from_the_command_line(cli, records, tmp_path):
    lab = tmp_path / "lab.toml"
    lab.write_text(LAB)
    out = tmp_path / "out" / "response.xml"
    r = cli(*_args(records, lab, out), "--mkdir")  # a new folder for the DCC only on request (issue 32)
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    data = out.read_bytes()
    validate_dcc(data)
    q = read_dcc_quantities(data)
    # the DCC states values to 12 significant digits (no float noise); the JSON keeps every digit
    r12 = lambda v: float(f"{v:.12g}")  # noqa: E731
    assert q["senscal_sensitivity"]["value"] == [r12(p["sensitivity"]) for p in doc["points"]]
    assert q["senscal_frequency"]["value"] == [r12(p["frequency_hz"]) for p in doc["points"]]
    assert q["senscal_normalizedSensitivity"]["value"] == [r12(p["normalized_sensitivity"]) for p in doc["points"]]
    root = ET.fromstring(data)
    assert root.findtext(".//dcc:customer/dcc:name/dcc:content", namespaces=NS) == 'ACME "Sensors" <script>'
    assert root.findtext(".//dcc:item//dcc:identification/dcc:value", namespaces=NS) == "SN-1&2"
    assert root.findtext(".//dcc:calibrationLaboratory//dcc:name/dcc:content", namespaces=NS) == "Vibration Lab <&> GmbH"
    assert root.findtext(".//dcc:beginPerformanceDate", namespaces=NS) == "2026-03-02"
    assert root.findtext(".//dcc:uniqueIdentifier", namespaces=NS)


def test_missing_lab_fields_give_one_line_and_no_file(cli, records, tmp_path):
    lab = tmp_path / "lab.toml"
    lab.write_text(LAB.replace('country = "DE"\n', "").replace('email = "lab@example.org"\n', ""))
    out = tmp_path / "response.xml"
    r = cli(*_args(records, lab, out))
    assert r.code == 2
    line = r.err.strip()
    assert "\n" not in line and "lab.country" in line and "lab.email" in line and "Traceback" not in r.err
    assert not out.exists()
