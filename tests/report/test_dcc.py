"""The Digital Calibration Certificate: schema validity, numbers round trip, escaping, refusals, offline."""

from __future__ import annotations

import hashlib
import math
import re
import socket
import urllib.request
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from senscal.report import dcc as dccmod
from senscal.report.dcc import (DCC_NS, SI_NS, DccError, dcc_missing_fields, dcc_xml, dsi_unit, read_dcc_quantities,
                                validate_dcc, write_dcc)
from senscal.report.lab import CertificateInfo, Condition, LabProfile, Person, RunInfo, Standard
from senscal.simulate.vibration import simulate_centrifuge, simulate_hydraulic
from senscal.validation import check_coverage, coverage_row, mc_seeds
from senscal.vibration import (amplitude_linearity, frequency_response, response_point, velocity_calibration,
                               velocity_point)

NS = {"dcc": DCC_NS, "si": SI_NS}
SCHEMAS = Path(dccmod.__file__).parent / "schemas"


def _info(**run) -> CertificateInfo:
    lab = LabProfile(name="Vibration Lab", address="Bundesallee 100\n38116 Braunschweig", email="lab@example.org",
                     country="DE", accreditation="DAkkS D-K-12345-01-00", procedure="QP-VIB-07 rev 3",
                     approvers=(Person("A. Approver", "Head of laboratory"), Person("B. Deputy")),
                     standards=(Standard("Reference accelerometer", "RS-1", "PTB-1234", "PTB", "2027-01-01", 0.002),))
    base = RunInfo(certificate_id="VIB-2026-0042", customer="ACME Sensors", customer_address="1 Main St, Springfield",
                   customer_email="qa@acme.example", item="piezoelectric accelerometer", manufacturer="ACME",
                   model="A-100", serial="SN-77", calibration_date="2026-03-02/2026-03-04", receipt_date="2026-02-27",
                   issue_date="2026-03-05", location="laboratory", conformity="pass",
                   decision_rule="simple acceptance (ILAC-G8)", conditions=(Condition("temperature", 23.1, 0.5, "degC"),))
    return CertificateInfo(lab, replace(base, **run))


@pytest.fixture(scope="module")
def response():
    recs, _ = simulate_centrifuge(frequencies=(1.0, 5.0), seed=3, min_duration=5.0)
    pts = [response_point(r["output"], r.time, input_amplitude=100.0, angle_deg=r["angle"], static_sensitivity=0.05,
                          u_input=0.002, initial_phase=0.0, u_input_phase=1e-4, source=f"rec{i}.csv")
           for i, r in enumerate(recs)]
    return frequency_response(pts, static_sensitivity=0.05)


@pytest.fixture(scope="module")
def velocity():
    recs, _ = simulate_hydraulic(frequencies=(2.0, 3.5, 5.5), periods=4.3, min_duration=2.0, seed=1)
    return velocity_calibration([velocity_point(r["position"], r["velocity"], r.time) for r in recs], unit="V/(m/s)")


@pytest.fixture(scope="module")
def linearity():
    levels = (20.0, 40.0, 60.0, 80.0, 100.0)
    recs, _ = simulate_centrifuge(frequencies=(1.0,), accelerations=levels, cubic=2e-6, seed=8, min_duration=10.0)
    pts = [response_point(r["output"], r.time, input_amplitude=a, angle_deg=r["angle"], harmonics=3)
           for r, a in zip(recs, levels)]
    return amplitude_linearity(levels, [p.output_amplitude for p in pts], [p.u_output_amplitude for p in pts])


# ---------------------------------------------------------------------------
# vendored schemas, offline


def test_vendored_schemas_are_the_published_versions():
    readme = (SCHEMAS / "README.md").read_text()
    for name, version in (("dcc.xsd", "3.1.2"), ("SI_Format.xsd", "2.1.0")):
        text = (SCHEMAS / name).read_text()
        assert re.search(rf'<xs:schema version="{re.escape(version)}"', text)
        digest = hashlib.sha256((SCHEMAS / name).read_bytes()).hexdigest()
        assert f"{digest}  {name}" in readme, f"{name} changed without its README"
    assert "GNU LESSER GENERAL PUBLIC LICENSE" in (SCHEMAS / "COPYING.LESSER").read_text()
    # the only import is D-SI: nothing else needs vendoring
    imports = re.findall(r"<xs:(?:import|include)\b[^>]*>", (SCHEMAS / "dcc.xsd").read_text())
    assert len(imports) == 1 and "https://ptb.de/si" in imports[0]
    assert not re.findall(r"<xs:(?:import|include)\b", (SCHEMAS / "SI_Format.xsd").read_text())


def test_validation_never_touches_the_network(monkeypatch, response):
    def refuse(*a, **k):
        raise AssertionError("network access during DCC validation")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(socket, "getaddrinfo", refuse)
    real_urlopen = urllib.request.urlopen

    def local_only(url, *a, **k):
        # xmlschema opens even its local files through urlopen: only file: URLs may pass
        if not str(getattr(url, "full_url", url)).startswith("file:"):
            refuse()
        return real_urlopen(url, *a, **k)

    monkeypatch.setattr(urllib.request, "urlopen", local_only)
    dccmod.dcc_schema.cache_clear()
    try:
        validate_dcc(dcc_xml("response", response, _info()))
    finally:
        dccmod.dcc_schema.cache_clear()


# ---------------------------------------------------------------------------
# numbers round trip


def _exact(got, want):
    # values are stated to 12 significant digits (no float noise); coverage factors to 3, as on the certificate
    assert len(got) == len(want)
    assert all(g == float(f"{w:.12g}") for g, w in zip(got, want)), (got, want)


def _r12(v):
    return float(f"{v:.12g}")


def _k3(got, want):
    assert len(got) == len(want)
    assert all(g == float(f"{w:.3g}") for g, w in zip(got, want)), (got, want)


def test_response_numbers_round_trip(response, tmp_path):
    path = write_dcc(tmp_path / "r.xml", "response", response, _info())
    q = read_dcc_quantities(path)
    pts = response.points
    _exact(q["senscal_frequency"]["value"], [p.frequency for p in pts])
    _exact(q["senscal_frequency"]["U"], [2 * p.u_frequency for p in pts])
    _exact(q["senscal_sensitivity"]["value"], [p.sensitivity for p in pts])
    _exact(q["senscal_sensitivity"]["U"], [p.sensitivity_budget.expanded for p in pts])
    _k3(q["senscal_sensitivity"]["k"], [p.sensitivity_budget.coverage_factor for p in pts])
    _exact(q["senscal_normalizedSensitivity"]["value"], [p.normalized_sensitivity for p in pts])
    _exact(q["senscal_normalizedSensitivity"]["U"], [p.normalized_budget.expanded for p in pts])
    deg, rad = q["senscal_phaseDelay@\\degree"], q["senscal_phaseDelay@\\radian"]
    _exact(rad["value"], [p.phase_delay for p in pts])
    _exact(rad["U"], [p.phase_delay_budget.expanded for p in pts])
    _k3(rad["k"], [p.phase_delay_budget.coverage_factor for p in pts])
    _exact(deg["value"], [math.degrees(p.phase_delay) for p in pts])
    _exact(deg["U"], [math.degrees(p.phase_delay_budget.expanded) for p in pts])
    for doc in q.values():
        assert doc["p"] == [0.9545] * len(doc["value"]) or not doc["U"]
    assert set(q["senscal_sensitivity"]["unit"]) == {"\\volt\\metre\\tothe{-1}\\second\\tothe{2}"}
    assert set(deg["unit"]) == {"\\degree"} and set(q["senscal_normalizedSensitivity"]["unit"]) == {"\\one"}


def test_velocity_numbers_round_trip(velocity):
    q = read_dcc_quantities(dcc_xml("velocity", velocity, _info()))
    pts = velocity.points
    mean = q["senscal_meanSensitivity"]
    _exact(mean["value"], [velocity.sensitivity])
    _exact(mean["U"], [velocity.budget.expanded])
    _k3(mean["k"], [velocity.budget.coverage_factor])
    assert mean["unit"] == ["\\volt\\metre\\tothe{-1}\\second"]
    _exact(q["senscal_frequency"]["value"], [p.frequency for p in pts])
    _exact(q["senscal_sensitivity"]["value"], [p.sensitivity for p in pts])
    _exact(q["senscal_sensitivity"]["U"], [p.budget.expanded for p in pts])
    _exact(q["senscal_phase@\\radian"]["value"], [p.phase for p in pts])
    _exact(q["senscal_phase@\\radian"]["U"], [2 * p.u_phase for p in pts])


def test_linearity_numbers_round_trip(linearity):
    q = read_dcc_quantities(dcc_xml("linearity", linearity, _info(), unit="pC/(m/s^2)"))
    k = linearity.coverage_factor
    _exact(q["senscal_linearityPercent"]["value"], [linearity.linearity_percent])
    _exact(q["senscal_linearityPercent"]["U"], [2 * linearity.u_linearity_percent])
    _exact(q["senscal_sensitivity"]["value"], [linearity.slope])
    _exact(q["senscal_sensitivity"]["U"], [k * linearity.u_slope])
    _exact(q["senscal_intercept"]["U"], [k * linearity.u_intercept])
    assert q["senscal_intercept"]["unit"] == ["\\pico\\coulomb"]
    _exact(q["senscal_inputAmplitude"]["value"], [p.input_amplitude for p in linearity.points])
    _exact(q["senscal_outputAmplitude"]["value"], [p.output_amplitude for p in linearity.points])
    _exact(q["senscal_outputAmplitude"]["U"], [2 * p.u_output_amplitude for p in linearity.points])
    _exact(q["senscal_deviationPercent"]["value"], [p.deviation_percent for p in linearity.points])


def test_dcc_interval_covers_the_truth():
    """value +/- U as the DCC states it (not as the engine holds it) covers the simulated truth 95 % of the time."""
    s, U_s, t_s, ph, U_ph, t_ph, m, U_m, t_m = ([] for _ in range(9))
    for seed in range(mc_seeds(400, 100)):
        recs, truth = simulate_hydraulic(frequencies=(2.0, 3.5, 5.5), periods=4.3, min_duration=2.0, seed=seed)
        cal = velocity_calibration([velocity_point(r["position"], r["velocity"], r.time) for r in recs],
                                   unit="V/(m/s)")
        q = read_dcc_quantities(dcc_xml("velocity", cal, _info()))
        s += q["senscal_sensitivity"]["value"]
        U_s += q["senscal_sensitivity"]["U"]
        t_s += [p["sensitivity"] for p in truth["points"]]
        ph += q["senscal_phase@\\degree"]["value"]
        U_ph += q["senscal_phase@\\degree"]["U"]
        t_ph += [p["phase_deg"] for p in truth["points"]]
        m += q["senscal_meanSensitivity"]["value"]
        U_m += q["senscal_meanSensitivity"]["U"]
        t_m.append(truth["sensitivity"])
    # coverage_row tests |e - t| <= 2 u: u = U / 2 puts the DCC's own U (its k included) on the test
    check_coverage([coverage_row("dcc", "velocity-white", "S (point)", s, [u / 2 for u in U_s], t_s),
                    coverage_row("dcc", "velocity-white", "phase deg (point)", ph, [u / 2 for u in U_ph], t_ph),
                    coverage_row("dcc", "velocity-white", "mean S", m, [u / 2 for u in U_m], t_m)])


# ---------------------------------------------------------------------------
# administrative data


def test_administrative_data(response):
    info = _info()
    root = ET.fromstring(dcc_xml("response", response, info))
    adm = root.find("dcc:administrativeData", NS)
    core = adm.find("dcc:coreData", NS)
    assert root.get("schemaVersion") == "3.1.2"
    assert core.findtext("dcc:countryCodeISO3166_1", namespaces=NS) == "DE"
    assert core.findtext("dcc:uniqueIdentifier", namespaces=NS) == "VIB-2026-0042"
    assert core.findtext("dcc:receiptDate", namespaces=NS) == "2026-02-27"
    assert core.findtext("dcc:beginPerformanceDate", namespaces=NS) == "2026-03-02"
    assert core.findtext("dcc:endPerformanceDate", namespaces=NS) == "2026-03-04"
    assert core.findtext("dcc:performanceLocation", namespaces=NS) == "laboratory"
    sw = adm.find("dcc:dccSoftware/dcc:software", NS)
    assert sw.findtext("dcc:name/dcc:content", namespaces=NS) == "senscal"
    item = adm.find("dcc:items/dcc:item", NS)
    assert item.findtext("dcc:manufacturer/dcc:name/dcc:content", namespaces=NS) == "ACME"
    assert item.findtext("dcc:model", namespaces=NS) == "A-100"
    assert item.findtext("dcc:identifications/dcc:identification/dcc:value", namespaces=NS) == "SN-77"
    lab = adm.find("dcc:calibrationLaboratory", NS)
    assert lab.findtext("dcc:calibrationLaboratoryCode", namespaces=NS) == "DAkkS D-K-12345-01-00"
    # one dcc:further per address line (no newline inside a text)
    lines = [e.text for e in lab.findall("dcc:contact/dcc:location/dcc:further/dcc:content", NS)]
    assert lines == info.lab.address.splitlines() and len(lines) == 2
    persons = adm.findall("dcc:respPersons/dcc:respPerson", NS)
    assert [p.findtext("dcc:person/dcc:name/dcc:content", namespaces=NS) for p in persons] == ["A. Approver", "B. Deputy"]
    assert [p.findtext("dcc:mainSigner", namespaces=NS) for p in persons] == ["true", "false"]
    assert adm.findtext("dcc:customer/dcc:eMail", namespaces=NS) == "qa@acme.example"
    statements = {s.get("refType"): s for s in adm.findall("dcc:statements/dcc:statement", NS)}
    assert statements["senscal_issueDate"].findtext("dcc:date", namespaces=NS) == "2026-03-05"
    assert statements["senscal_conformity"].findtext("dcc:conformity", namespaces=NS) == "pass"
    assert "ILAC-G8" in statements["senscal_conformity"].findtext("dcc:declaration/dcc:content", namespaces=NS)
    eq = root.find(".//dcc:measuringEquipment", NS)
    assert eq.findtext("dcc:name/dcc:content", namespaces=NS) == "Reference accelerometer"
    assert [i.findtext("dcc:value", namespaces=NS) for i in eq.findall(".//dcc:identification", NS)] == ["RS-1", "PTB-1234"]
    temp = root.find(".//dcc:influenceCondition//si:real", NS)
    assert temp.findtext("si:unit", namespaces=NS) == "\\degreecelsius"
    assert float(temp.findtext("si:expandedUnc/si:uncertainty", namespaces=NS)) == 2 * 0.5


def test_free_text_location_is_other_and_stated(response):
    root = ET.fromstring(dcc_xml("response", response, _info(location="customer's site, hall 3")))
    assert root.findtext(".//dcc:performanceLocation", namespaces=NS) == "other"
    assert "hall 3" in root.find(".//dcc:statement[@refType='senscal_location']/dcc:declaration/dcc:content", NS).text


def test_warnings_are_stated(response):
    root = ET.fromstring(dcc_xml("response", response, _info(), warnings=["coloured-noise: the residuals are AR(1)."]))
    md = root.findall(".//dcc:measurementMetaData/dcc:metaData[@refType='senscal_warning']", NS)
    assert len(md) == 1 and "coloured-noise" in md[0].findtext("dcc:declaration/dcc:content", namespaces=NS)


# ---------------------------------------------------------------------------
# refusals: missing data, bad strings, schema violations


def test_missing_fields_are_named_in_one_line_and_nothing_is_written(response, tmp_path):
    info = CertificateInfo(replace(_info().lab, email="", country=""), replace(_info().run, customer_email="", serial=""))
    assert set(dcc_missing_fields(info)) == {"lab.email", "lab.country", "run.customer_email", "run.serial"}
    out = tmp_path / "x.xml"
    with pytest.raises(DccError) as exc:
        write_dcc(out, "response", response, info)
    msg = str(exc.value)
    assert "\n" not in msg and all(f in msg for f in ("lab.email", "lab.country", "run.customer_email", "run.serial"))
    assert not out.exists()


def test_failed_dcc_leaves_an_existing_file_untouched(response, tmp_path):
    out = tmp_path / "x.xml"
    out.write_text("previous")
    with pytest.raises(DccError):
        write_dcc(out, "response", response, _info(calibration_date="2026-02-30"))
    assert out.read_text() == "previous"
    assert list(tmp_path.iterdir()) == [out]


@pytest.mark.parametrize("run, needle", [
    ({"calibration_date": "02.03.2026"}, "run.calibration_date"),
    ({"calibration_date": "2026-03-04/2026-03-02"}, "ends before it begins"),
    ({"receipt_date": "yesterday"}, "run.receipt_date"),
])
def test_bad_dates_are_refused(response, run, needle):
    with pytest.raises(DccError, match=re.escape(needle)):
        dcc_xml("response", response, _info(**run))


def test_bad_country_code_is_refused(response):
    info = CertificateInfo(replace(_info().lab, country="Germany"), _info().run)
    with pytest.raises(DccError, match="ISO 3166-1"):
        dcc_xml("response", response, info)


def test_non_xml_suffix_is_refused(response, tmp_path):
    with pytest.raises(Exception, match="extension"):
        write_dcc(tmp_path / "x.html", "response", response, _info())


def test_non_finite_value_is_refused(response):
    bad = replace(response, points=(replace(response.points[0], sensitivity=float("nan")),) + response.points[1:])
    bad = replace(bad, points=tuple(replace(p, sensitivity_budget=None) if i == 0 else p
                                    for i, p in enumerate(bad.points)))
    with pytest.raises(DccError, match="non-finite"):
        dcc_xml("response", bad, _info())


def _drop(xml: bytes, path: str) -> bytes:
    root = ET.fromstring(xml)
    parent = root.find(path.rsplit("/", 1)[0], NS)
    parent.remove(parent.find(path.rsplit("/", 1)[1], NS))
    return ET.tostring(root)


def test_validation_catches_a_missing_required_element(response):
    good = dcc_xml("response", response, _info())
    validate_dcc(good)
    with pytest.raises(DccError) as exc:
        validate_dcc(_drop(good, "dcc:administrativeData/dcc:coreData/dcc:uniqueIdentifier"))
    msg = str(exc.value)
    assert "\n" not in msg and "coreData" in msg and "uniqueIdentifier" in msg


def test_validation_catches_a_bad_value(response):
    root = ET.fromstring(dcc_xml("response", response, _info()))
    root.find(".//si:expandedUncXMLList/si:coverageFactorXMLList", NS).text = "0.5 2.0"
    with pytest.raises(DccError, match=r"coverageFactorXMLList"):
        validate_dcc(ET.tostring(root))


def test_a_writer_bug_is_caught_before_writing(monkeypatch, response, tmp_path):
    """If the writer itself produced an invalid document, validation stops it before a file appears."""
    monkeypatch.setattr(dccmod, "COVERAGE_PROBABILITY", "95 %")
    out = tmp_path / "x.xml"
    with pytest.raises(DccError, match="coverageProbability"):
        write_dcc(out, "response", response, _info())
    assert not out.exists()


# ---------------------------------------------------------------------------
# escaping


NASTY = {
    "customer": '<script>alert("x")</script> & Sons \'Ltd\'',
    "serial": 'SN<1&2>"3"',
    "customer_address": "]]> &amp; <!-- not a comment -->",
}


def test_user_strings_are_escaped_and_round_trip(response):
    lab = replace(_info().lab, name='Lab "<b>Bold</b>" & Co', address="Straße 1 &\n<Town>")
    info = CertificateInfo(lab, replace(_info().run, **NASTY))
    xml = dcc_xml("response", response, info, files=["<rec>&1.csv"])
    validate_dcc(xml)
    assert b"<script>" not in xml and b"<b>" not in xml
    root = ET.fromstring(xml)
    adm = root.find("dcc:administrativeData", NS)
    assert adm.findtext("dcc:customer/dcc:name/dcc:content", namespaces=NS) == NASTY["customer"]
    assert adm.findtext("dcc:customer/dcc:location/dcc:further/dcc:content", namespaces=NS) == NASTY["customer_address"]
    assert adm.findtext(".//dcc:item//dcc:identification/dcc:value", namespaces=NS) == NASTY["serial"]
    contact = adm.find("dcc:calibrationLaboratory/dcc:contact", NS)
    assert contact.findtext("dcc:name/dcc:content", namespaces=NS) == lab.name
    assert [e.text for e in contact.findall("dcc:location/dcc:further/dcc:content", NS)] == lab.address.splitlines()
    assert root.findtext(".//dcc:measurementResult/dcc:description/dcc:content", namespaces=NS) == "Records: <rec>&1.csv"


@pytest.mark.parametrize("where, field", [("run", "customer"), ("run", "serial"), ("lab", "name"), ("lab", "address")])
def test_control_characters_are_refused_with_the_field(response, where, field):
    info = _info()
    part = replace(getattr(info, where), **{field: "abc\x07def"})
    info = CertificateInfo(part, info.run) if where == "lab" else CertificateInfo(info.lab, part)
    with pytest.raises(DccError) as exc:
        dcc_xml("response", response, info)
    msg = str(exc.value)
    assert "\n" not in msg and f"{where}.{field}" in msg and "U+0007" in msg


@settings(max_examples=25, deadline=None)
@given(text=st.text(st.characters(blacklist_categories=("Cc", "Cs")), min_size=1, max_size=40)
       .filter(lambda s: s.strip() == s and s.strip()))
def test_any_printable_customer_round_trips(response, text):
    xml = dcc_xml("response", response, _info(customer=text, serial=text))
    root = ET.fromstring(xml)
    assert root.findtext(".//dcc:customer/dcc:name/dcc:content", namespaces=NS) == text
    assert root.findtext(".//dcc:item//dcc:identification/dcc:value", namespaces=NS) == text


# ---------------------------------------------------------------------------
# units


@pytest.mark.parametrize("unit, dsi", [
    ("V/(m/s^2)", "\\volt\\metre\\tothe{-1}\\second\\tothe{2}"),
    ("mV/(m/s^2)", "\\milli\\volt\\metre\\tothe{-1}\\second\\tothe{2}"),
    ("pC/(m/s^2)", "\\pico\\coulomb\\metre\\tothe{-1}\\second\\tothe{2}"),
    ("V/(m/s)", "\\volt\\metre\\tothe{-1}\\second"),
    ("m/s^2", "\\metre\\second\\tothe{-2}"),
    ("m s^-2", "\\metre\\second\\tothe{-2}"),
    ("Hz", "\\hertz"), ("kHz", "\\kilo\\hertz"), ("deg", "\\degree"), ("rad", "\\radian"), ("%", "\\percent"),
    ("degC", "\\degreecelsius"), ("1", "\\one"), ("", "\\one"), ("s/s", "\\one"),
])
def test_dsi_units(unit, dsi):
    assert dsi_unit(unit) == dsi


@pytest.mark.parametrize("unit, needle", [("mV/g", "ambiguous"), ("counts/(m/s^2)", "no D-SI form"),
                                          ("V/(m/s^2", "parenthesis"), ("V//m", "cannot be read")])
def test_units_without_a_dsi_form_are_refused(unit, needle):
    with pytest.raises(DccError, match=needle):
        dsi_unit(unit)


# ---------------------------------------------------------------------------
# senscal.jobs results


def test_job_results_with_repeats(tmp_path):
    from senscal import jobs

    a, _ = simulate_centrifuge(frequencies=(1.0, 5.0), seed=4, min_duration=5.0)
    b, _ = simulate_centrifuge(frequencies=(5.0,), seed=5, min_duration=5.0)
    opts = jobs.options("response", output="output", input_amplitude=100.0, angle="angle", static_sensitivity=0.05,
                        initial_phase_deg=0.0)
    res = jobs.run("response", [*a, *b], opts)
    assert len(res.repeats) == 2 < len(res.response.points) == 3
    q = read_dcc_quantities(dcc_xml("response", res, _info()))
    _exact(q["senscal_sensitivity"]["value"], [p.sensitivity for p in res.response.points])
    _exact(q["senscal_sensitivityRepeats"]["value"], [g.sensitivity for g in res.repeats])
    _exact(q["senscal_sensitivityRepeats"]["U"], [g.sensitivity_budget.expanded for g in res.repeats])
    _exact(q["senscal_phaseDelayRepeats@\\radian"]["U"], [g.phase_delay_budget.expanded for g in res.repeats])
    assert "senscal_frequencyRepeats" in q and not q["senscal_frequencyRepeats"]["U"]  # no u of a mean frequency


def test_linearity_job_result_takes_its_output_unit():
    from senscal import jobs

    levels = (20.0, 60.0, 100.0)
    recs, _ = simulate_centrifuge(frequencies=(1.0,), accelerations=levels, seed=6, min_duration=5.0)
    # a file whose header gives no unit for the output: --output-unit states it (one that contradicts a header
    # unit is refused, issue 32)
    recs = [replace(r, units={k: v for k, v in r.units.items() if k != "output"}) for r in recs]
    res = jobs.run("linearity", recs, jobs.options("linearity", output="output", input_amplitudes=levels,
                                                    angle="angle", output_unit="mV"))
    q = read_dcc_quantities(dcc_xml("linearity", res, _info()))
    # an output in mV is converted to V (units are quantities, issue 32): the DCC states V/(m/s^2)
    assert q["senscal_sensitivity"]["unit"] == ["\\volt\\metre\\tothe{-1}\\second\\tothe{2}"]
    assert q["senscal_outputAmplitude"]["unit"] == ["\\volt"] * 3
    _exact(q["senscal_sensitivity"]["value"], [res.linearity.slope])


def test_certificate_id_and_approver_from_the_run(response):
    root = ET.fromstring(dcc_xml("response", response, _info(certificate_id="", approver="B. Deputy"),
                                 certificate_id="SC-20260305-ABCDEF12"))
    assert root.findtext(".//dcc:uniqueIdentifier", namespaces=NS) == "SC-20260305-ABCDEF12"
    names = [e.text for e in root.findall(".//dcc:respPerson/dcc:person/dcc:name/dcc:content", NS)]
    assert names == ["B. Deputy"]
    with pytest.raises(DccError, match="run.certificate_id"):
        dcc_xml("response", response, _info(certificate_id=""))


# ---------------------------------------------------------------------------
# triaxial and shaft calibrations


@pytest.fixture(scope="module")
def triaxial():
    from senscal import jobs
    from senscal.simulate.triaxial import simulate_magnetometer

    return jobs.run("triaxial-calibrate", simulate_magnetometer(seed=1)[0])


@pytest.fixture(scope="module")
def shaft():
    from senscal import jobs
    from senscal.simulate.shaft import simulate_shaft

    return jobs.run("shaft-calibrate", simulate_shaft(seed=1)[0])


def test_triaxial_parameters_round_trip(triaxial):
    res = triaxial
    q = read_dcc_quantities(dcc_xml("triaxial", res, _info(item="three-axis magnetometer")))
    params = res.calibration.parameters
    assert params, "the simulated sphere determines the parameters"
    for name, p in params.items():
        if p["unit"] == "rad":
            assert q[f"senscal_{name}@\\radian"]["value"] == [_r12(p["value"])]
            assert q[f"senscal_{name}@\\radian"]["U"] == [_r12(2 * p["u"])]
            assert q[f"senscal_{name}@\\degree"]["value"] == [_r12(math.degrees(p["value"]))]
        else:
            assert q[f"senscal_{name}"]["value"] == [_r12(p["value"])]
            assert q[f"senscal_{name}"]["U"] == [_r12(2 * p["u"])]
            assert q[f"senscal_{name}"]["unit"] == [dsi_unit(p["unit"])]


def test_undetermined_parameter_is_stated_not_invented(triaxial):
    tri = triaxial.calibration
    first = next(iter(tri.parameters))
    params = {**tri.parameters, first: {**tri.parameters[first], "value": float("nan"), "u": float("nan")}}
    root = ET.fromstring(dcc_xml("triaxial", replace(tri, parameters=params), _info()))
    q = root.find(f".//dcc:quantity[@refType='senscal_{first}']", NS)
    assert q.find("si:real", NS) is None and "not determined" in q.findtext("dcc:noQuantity/dcc:content",
                                                                             namespaces=NS)


def test_shaft_gravity_model_round_trip(shaft):
    res = shaft
    m = res.model
    q = read_dcc_quantities(dcc_xml("shaft", res, _info(item="tangential accelerometer")))
    assert q["senscal_gravity_amplitude"]["value"] == [_r12(m.amplitude)]
    assert q["senscal_gravity_amplitude"]["U"] == [_r12(2 * m.u_amplitude)]
    assert q["senscal_offset"]["value"] == [_r12(m.offset)] and q["senscal_bias"]["value"] == [_r12(m.bias)]
    assert q["senscal_tilt@\\radian"]["value"] == [_r12(m.tilt)] and q["senscal_phase@\\radian"]["U"] == [_r12(2 * m.u_phase)]
    assert q["senscal_bias"]["unit"] == ["\\metre\\second\\tothe{-2}"]


def test_parameter_without_a_unit_is_refused(shaft):
    with pytest.raises(DccError, match="has no unit"):
        dcc_xml("shaft", replace(shaft.model, output_unit=""), _info())
