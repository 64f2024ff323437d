"""Reference standards on the certificate and in the DCC (issue 29): hashType links, --standard, standard-overdue."""

from __future__ import annotations

import hashlib
import json
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import pytest

from senscal.report.dcc import DCC_NS, dcc_xml
from senscal.report.lab import CertificateInfo, Condition, LabProfile, Person, RunInfo, Standard, load_lab_profile
from senscal.simulate.vibration import simulate_hydraulic
from senscal.vibration import velocity_calibration, velocity_point

NS = {"dcc": DCC_NS}
SHARED_SCHEMAS = Path(__file__).resolve().parents[3] / "shared" / "schemas" / "dcc"
SHA = hashlib.sha256(b"the standard's own DCC").hexdigest()


@pytest.fixture(scope="module")
def velocity():
    recs, _ = simulate_hydraulic(frequencies=(2.0, 3.5), periods=4.3, min_duration=2.0, seed=1)
    return velocity_calibration([velocity_point(r["position"], r["velocity"], r.time) for r in recs], unit="V/(m/s)")


def _info(*standards: Standard) -> CertificateInfo:
    lab = LabProfile(name="Vibration Lab", address="Bundesallee 100\n38116 Braunschweig", email="lab@example.org",
                     country="DE", approvers=(Person("A. Approver", "Head of laboratory"),), standards=standards)
    run = RunInfo(certificate_id="VIB-1", customer="ACME", customer_address="1 Main St", customer_email="qa@acme.example",
                  item="velocity sensor", manufacturer="ACME", model="V-1", serial="SN-1",
                  calibration_date="2026-03-02", issue_date="2026-03-05", location="laboratory",
                  conditions=(Condition("temperature", 23.1, 0.5, "degC"),))
    return CertificateInfo(lab, run)


def test_dcc_links_the_standards_own_dcc_by_sha256(velocity):
    linked = Standard("Laser vibrometer", "LV-1", "PTB-1.21-4711", "PTB", "2027-01-01", 0.001, id="LV-1",
                      certificate_sha256=SHA)
    plain = Standard("Position reference", "PR-1", "DKD-9", "PTB", "2027-01-01", 0.002, id="PR-1")
    xml = dcc_xml("velocity", velocity, _info(linked, plain), unit="V/(m/s)")  # validated against the schema
    root = ET.fromstring(xml)
    eqs = root.findall(".//dcc:measuringEquipment", NS)
    assert len(eqs) == 2
    link = eqs[0].find("dcc:certificate", NS)
    assert link.find("dcc:referralID", NS).text == "PTB-1.21-4711"
    assert link.find("dcc:value", NS).text == SHA
    assert "SHA256" in link.find("dcc:procedure", NS).text
    assert eqs[1].find("dcc:certificate", NS) is None  # no hash given: no link
    # The schema order puts the link after the description and before the identifications.
    tags = [e.tag.split("}")[1] for e in eqs[0]]
    assert tags.index("certificate") < tags.index("identifications")


@pytest.mark.skipif(not (SHARED_SCHEMAS / "dcc.xsd").is_file(), reason="../shared/schemas/dcc not present")
def test_the_linked_dcc_is_valid_against_the_shared_3_1_2_schema(velocity):
    import xmlschema

    d = SHARED_SCHEMAS
    si = d / "SI_Format.xsd" if (d / "SI_Format.xsd").is_file() else d.parent / "SI_Format.xsd"
    schema = xmlschema.XMLSchema(str(d / "dcc.xsd"), locations={"https://ptb.de/si": str(si)}, allow="local")
    assert schema.version == "3.1.2"
    s = Standard("Laser vibrometer", "LV-1", "PTB-1.21-4711", "PTB", "2027-01-01", 0.001, certificate_sha256=SHA)
    schema.validate(dcc_xml("velocity", velocity, _info(s), unit="V/(m/s)").decode())


def test_lab_profile_certificate_sha256_is_checked(tmp_path):
    from senscal.errors import InputError

    good = tmp_path / "lab.toml"
    good.write_text(f'name = "L"\n[[standards]]\nname = "S"\nid = "S-1"\ncertificate_sha256 = "SHA256:{SHA.upper()}"\n')
    lab, _ = load_lab_profile(good)
    assert lab.standards[0].certificate_sha256 == SHA and lab.standards[0].id == "S-1"
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "L"\n[[standards]]\nname = "S"\ncertificate_sha256 = "12ab"\n')
    with pytest.raises(InputError, match="certificate_sha256"):
        load_lab_profile(bad)


def test_velocity_with_an_overdue_standard_says_so_on_the_certificate_and_in_the_dcc(cli, tmp_path):
    recs, truth = simulate_hydraulic(frequencies=(2.0, 3.5), periods=4.3, min_duration=2.0, seed=1)
    from senscal.simulate.common import write_simulation

    files = write_simulation(recs, truth, tmp_path / "hy", "hydraulic")
    db = tmp_path / "lab.sqlite"
    own = tmp_path / "ref_dcc.xml"
    own.write_bytes(b"<x/>")
    assert cli("registry", "standard", "add", "LV-1", "--certificate", own, "--due", "2026-01-31",
               "--u-relative", "0.1%", "--name", "Laser vibrometer", "--traceability", "PTB", "--db", db).code == 0
    lab = tmp_path / "lab.toml"
    lab.write_text('name = "Vibration Lab"\naddress = "Bundesallee 100, Braunschweig"\ncountry = "DE"\n'
                   'email = "lab@example.org"\napprovers = [{name = "A. Approver"}]\n'
                   '[run]\ncustomer = "ACME"\ncustomer_address = "1 Main St"\ncustomer_email = "qa@acme.example"\n'
                   'item = "velocity sensor"\nmanufacturer = "ACME"\nlocation = "laboratory"\n')
    args = ["velocity", *files, "--position", "position", "--velocity", "velocity", "--lab", lab,
            "--env", "temperature=23.1+-0.5 degC", "--serial", "SN-1", "--standard", "LV-1", "--db", db,
            "--save", "--sensor", "SN-1", "--create-sensor", "velocity sensor", "--json"]
    r = cli(*args, "--date", "2026-02-02", "--report", tmp_path / "c.html", "--dcc", tmp_path / "c.xml", "--strict")
    assert r.code == 3 and "standard-overdue: reference standard LV-1" in r.err
    html = (tmp_path / "c.html").read_text()
    std_table = html.split("Reference standards and traceability")[1].split("</table>")[0]
    assert "Laser vibrometer" in std_table and "OVERDUE" in std_table
    assert "standard-overdue" in html
    xml = (tmp_path / "c.xml").read_bytes()
    assert b"standard-overdue" in xml
    assert hashlib.sha256(own.read_bytes()).hexdigest().encode() in xml
    # Not named twice: the profile's own reference-standard-due is left out for the registry's standard.
    assert "reference-standard-due" not in r.err
    doc = json.loads(r.out)
    assert doc["standards"][0]["overdue"] is True
    # In date on the calibration day: no warning, --strict passes.
    r = cli(*args, "--date", "2026-01-31", "--strict")
    assert r.code == 0 and "standard-overdue" not in r.err
