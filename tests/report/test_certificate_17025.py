"""Certificates a lab can issue: every ISO/IEC 17025 7.8 field, DRAFT when one is missing, PDF pages, budget checks.

WeasyPrint takes a few seconds per document, so each PDF is rendered once per module.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from dataclasses import replace

import pytest

from senscal.diagnostics import warning_names
from senscal.errors import InputError
from senscal.report.certificate import (budget_warnings, certificate_html, certificate_warnings, write_certificate)
from senscal.report.lab import CertificateInfo, Condition, LabProfile, Person, RunInfo, Standard, missing_fields
from senscal.simulate.vibration import simulate_centrifuge
from senscal.vibration import frequency_response, response_point

POPPLER = all(shutil.which(t) for t in ("pdftotext", "pdfinfo", "pdfimages"))
needs_poppler = pytest.mark.skipif(not POPPLER, reason="poppler-utils (pdftotext) not installed")

LAB = LabProfile(name="Schwingungslabor Nord & Söhne", address="Hafenstraße 7\n20457 Hamburg",
                 accreditation="DAkkS D-K-99999-01-00", procedure="QP-VIB-07 rev 3", email="lab@example.org",
                 approvers=(Person("Dr. Ada Prüfer", "Head of laboratory"),),
                 standards=(Standard("Reference double centrifuge DC-2", "DC2-0042", "PTB-1.21-4711", "PTB Braunschweig",
                                     "2027-03-01", 0.0005),))
RUN = RunInfo(customer="Kunde <GmbH>", customer_address="Am Markt 1, 10115 Berlin", item="servo accelerometer",
              manufacturer="Qfab", model="QF-1", serial="SN-4711", calibration_date="2026-01-05",
              location="Laboratory hall 2, Hamburg", issue_date="2026-01-07",
              conditions=(Condition("temperature", 23.1, 0.5, "degC"), Condition("relative humidity", 41.0, 3.0, "%")),
              deviations="Frequency points above 10 Hz omitted at the customer's request.",
              conformity="The sensitivity deviates from its nominal value by less than 2 % at every frequency.",
              decision_rule="Simple acceptance (ILAC-G8:09/2019, 4.2.1), w = 0")
FULL = CertificateInfo(LAB, RUN)
DRAFT = CertificateInfo(LAB, replace(RUN, customer="", conditions=()))


@pytest.fixture(scope="module")
def resp():
    recs, _ = simulate_centrifuge(frequencies=(1.0, 5.0, 10.0), seed=3, min_duration=4.0)
    pts = [response_point(r["output"], r.time, input_amplitude=100.0, angle_deg=r["angle"], static_sensitivity=0.05,
                          u_input=0.002, u_static_sensitivity=0.0005, initial_phase=1.5707963267948966,
                          u_input_phase=1e-3, source=f"rec{i}.csv") for i, r in enumerate(recs)]
    return frequency_response(pts, static_sensitivity=0.05)


@pytest.fixture
def no_plots(monkeypatch):
    """HTML-only tests: a stand-in for the plots (matplotlib's SVG takes seconds on a shared machine)."""
    monkeypatch.setattr("senscal.report.certificate.svg_inline", lambda fig: "<svg></svg>")


def _render(tmp_path_factory, resp, info, name):
    path = tmp_path_factory.mktemp("cert") / name
    write_certificate(path, "response", resp, info=info, unit=resp.unit, method="Double centrifuge, angle-synchronised "
                      "sine fit", conditions={"peak input acceleration (m/s^2)": 100.0}, files=["rec<0>.csv"])
    return path


def _pages(pdf) -> list[str]:
    """Text of each page, whitespace collapsed (pdftotext ends each page with a form feed)."""
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    return [" ".join(p.split()) for p in text.split("\f")[:-1]]


def _page_count(pdf) -> int:
    info = subprocess.run(["pdfinfo", str(pdf)], capture_output=True, text=True, check=True).stdout
    return int(re.search(r"Pages:\s+(\d+)", info).group(1))


@pytest.fixture(scope="module")
def full_pdf(tmp_path_factory, resp):
    return _render(tmp_path_factory, resp, FULL, "cert.pdf")


@pytest.fixture(scope="module")
def draft_pdf(tmp_path_factory, resp):
    return _render(tmp_path_factory, resp, DRAFT, "draft.pdf")


def _expected_fields(info: CertificateInfo) -> list[str]:
    """The text of every 17025 7.8.2.1 / 7.8.4.1 field, as the certificate must state it."""
    lab, run = info.lab, info.run
    return ["Calibration certificate",                                                   # a) title
            lab.name, *lab.address.split("\n"), lab.accreditation,                      # b) laboratory
            run.location,                                                               # c) where
            run.customer, run.customer_address,                                         # e) customer
            lab.procedure, "Double centrifuge",                                         # f) method
            run.item, run.manufacturer, run.model, run.serial,                          # g) item
            run.calibration_date, run.issue_date,                                       # i), j) dates
            "relate only to the item calibrated",                                       # l)
            resp_unit_label, "S_i / S_0", "phase delay (°)",                           # m) results with units
            run.deviations,                                                             # n) deviations
            *(a.name for a in lab.approvers), *(a.role for a in lab.approvers),        # o) who authorises
            *(c.name for c in run.conditions), "°C", "1 °C", "6 %",                     # 7.8.4.1 a) conditions, U=2u
            "expanded uncertainty with coverage factor k = 2",                          # 7.8.4.1 b) uncertainty
            *(s.name for s in lab.standards), *(s.certificate for s in lab.standards),  # 7.8.4.1 c) traceability
            *(s.traceability for s in lab.standards),
            run.conformity, run.decision_rule]                                          # 7.8.6 conformity


resp_unit_label = "V/(m/s²)"


@needs_poppler
def test_pdf_states_every_17025_field_and_the_id_on_every_page(full_pdf):
    pages = _pages(full_pdf)
    n = _page_count(full_pdf)
    assert len(pages) == n >= 2
    text = " ".join(pages)
    # compared without spaces: table cells wrap where the layout needs
    bare = "".join(text.split())
    for field in _expected_fields(FULL):
        assert "".join(field.split()) in bare, field
    cert_id = re.search(r"Certificate id (SC-\d{8}-[0-9A-F]{8})", text).group(1)
    for i, page in enumerate(pages, start=1):
        assert f"Certificate {cert_id}" in page and f"Page {i} of {n}" in page, (i, page[:200])
    assert "DRAFT" not in text and "MISSING" not in text and "not stated" not in text
    assert text.rstrip().endswith(f"End of certificate {cert_id} Certificate {cert_id} Page {n} of {n}")


@needs_poppler
def test_pdf_plots_are_vector_graphics(full_pdf):
    # the Bode plot is inline SVG: drawn as paths, so the PDF holds no raster image at all
    out = subprocess.run(["pdfimages", "-list", str(full_pdf)], capture_output=True, text=True, check=True).stdout
    assert len(out.strip().splitlines()) == 2, out  # the two header lines only
    assert full_pdf.read_bytes().startswith(b"%PDF-")


@needs_poppler
def test_missing_fields_make_a_draft_on_every_page(draft_pdf):
    pages = _pages(draft_pdf)
    assert len(pages) == _page_count(draft_pdf)
    for page in pages:
        assert "DRAFT" in page
    text = " ".join(pages)
    assert "run.customer" in text and "run.conditions" in text and "not stated" not in text
    assert text.count("MISSING (required)") == 2  # the customer row and the conditions section


def test_draft_html_and_warning(resp, no_plots):
    assert missing_fields(FULL) == []
    html = certificate_html("response", resp, info=DRAFT, unit=resp.unit)
    assert 'class="watermark">DRAFT<' in html and "MISSING (required)" in html and "not stated" not in html
    warns = certificate_warnings("response", resp, DRAFT)
    assert warning_names(warns) == ("certificate-draft",)
    assert "run.customer" in warns[0] and "run.conditions" in warns[0]
    assert 'class="watermark"' not in certificate_html("response", resp, info=FULL, unit=resp.unit)
    # an empty profile: every required lab and run field is named
    names = certificate_warnings("response", resp, CertificateInfo())[0]
    for f in ("lab.name", "lab.address", "lab.approvers", "lab.standards", "run.customer", "run.item", "run.serial",
              "run.calibration_date", "run.location", "run.conditions"):
        assert f in names


def test_conformity_without_decision_rule_is_a_draft(resp, no_plots):
    info = CertificateInfo(LAB, replace(RUN, decision_rule=""))
    assert "run.decision_rule" in certificate_warnings("response", resp, info)[0]
    assert "MISSING (required with a statement of conformity)" in certificate_html("response", resp, info=info)


def test_every_user_string_is_escaped(resp, no_plots):
    evil = "<script>alert(1)</script>"
    lab = replace(LAB, name=evil + " Lab", address=evil, accreditation=evil,
                  approvers=(Person(evil, evil),), standards=(Standard(evil, evil, evil, evil),))
    run = replace(RUN, customer=evil, item=evil, serial=evil, model=evil, location=evil, deviations=evil,
                  conditions=(Condition(evil, 1.0, 0.1, evil),), remarks=evil)
    html = certificate_html("response", resp, info=CertificateInfo(lab, run), unit=evil, files=[evil + ".csv"],
                            method=evil, conditions={evil: evil}, warnings=[evil])
    assert "<script" not in html and html.count("&lt;script&gt;") >= 14
    assert not re.search(r'(src|href)="(https?:)?//', html)


def test_approver_must_be_one_of_the_lab(resp, no_plots):
    html = certificate_html("response", resp, info=CertificateInfo(LAB, replace(RUN, approver="Dr. Ada Prüfer")))
    assert "Head of laboratory" in html
    with pytest.raises(InputError, match="not among the lab's approvers"):
        certificate_html("response", resp, info=CertificateInfo(LAB, replace(RUN, approver="Mallory")))


def test_report_suffix(tmp_path, resp, no_plots):
    with pytest.raises(InputError, match=r"unsupported extension '\.txt'"):
        write_certificate(tmp_path / "x.txt", "response", resp, info=FULL)
    assert not (tmp_path / "x.txt").exists()
    p = write_certificate(tmp_path / "x.html", "response", resp, info=FULL)
    assert p.read_text().startswith("<!DOCTYPE html>")


def test_budget_zero_component(resp):
    # the fixture gives every type B component a value: no warning
    assert budget_warnings("response", resp) == ()
    recs, _ = simulate_centrifuge(frequencies=(5.0,), seed=4, min_duration=4.0)
    p = response_point(recs[0]["output"], recs[0].time, input_amplitude=100.0, angle_deg=recs[0]["angle"],
                       static_sensitivity=0.05, u_input=0.0, u_static_sensitivity=0.001,
                       initial_phase=1.5707963267948966, u_input_phase=1e-3)
    warns = budget_warnings("response", frequency_response([p], static_sensitivity=0.05))
    assert warning_names(warns) == ("budget-zero-component",)
    assert "'input amplitude'" in warns[0] and "--u-input" in warns[0]


def test_u_below_reference(resp):
    rel = [p.sensitivity_budget.combined / p.sensitivity_budget.value for p in resp.points]
    below = replace(LAB.standards[0], u_relative=1.5 * max(rel))   # the reference is worse than every result
    above = replace(LAB.standards[0], u_relative=0.5 * min(rel))
    assert warning_names(budget_warnings("response", resp, [below])) == ("u-below-reference",)
    assert f"{len(rel)} result(s)" in budget_warnings("response", resp, [below])[0]
    assert budget_warnings("response", resp, [above]) == ()
    assert budget_warnings("response", resp, [replace(below, u_relative=None)]) == ()


def test_velocity_budget_checks_cover_points_and_mean():
    from senscal.simulate.vibration import simulate_hydraulic
    from senscal.vibration import velocity_calibration, velocity_point

    recs, _ = simulate_hydraulic(frequencies=(2.0, 4.0), seed=5)
    for u_pos in (0.0, 0.001):
        cal = velocity_calibration([velocity_point(r["position"], r["velocity"], r.time, u_position=u_pos)
                                    for r in recs], u_position=u_pos)
        rel = [cal.budget.combined / cal.sensitivity] + [p.budget.combined / p.sensitivity for p in cal.points]
        warns = budget_warnings("velocity", cal, [replace(LAB.standards[0], u_relative=1.01 * max(rel))])
        # zero --u-position: named in the points' and the mean's budgets; every result (2 points + mean) below
        assert warning_names(warns) == (("budget-zero-component",) if u_pos == 0 else ()) + ("u-below-reference",)
        assert "3 result(s)" in warns[-1]
        if u_pos == 0:
            assert "'position reference' (--u-position) in the budget of sensitivity, mean sensitivity" in warns[0]


def test_logo_is_embedded_and_a_missing_one_is_named(resp, no_plots, tmp_path):
    from senscal.report.plots import new_figure, save_figure

    fig, ax = new_figure(width=1.0, height=0.5)
    logo = save_figure(fig, tmp_path / "logo.png")
    html = certificate_html("response", resp, info=CertificateInfo(replace(LAB, logo=str(logo)), RUN))
    assert '<img alt="logo" src="data:image/png;base64,' in html and str(tmp_path) not in html
    with pytest.raises(InputError, match="cannot read the lab logo"):
        certificate_html("response", resp, info=CertificateInfo(replace(LAB, logo=str(tmp_path / "no.png")), RUN))


# ---------------------------------------------------------------------------
# presentation (issue 31): rounding, typography, traceability that follows from the standards, due dates


@pytest.mark.parametrize("value, U, want", [
    (0.0499999, 0.0002, ("0.05000", "0.00020")),     # GUM 7.2.6: the value to the last digit of U
    (0.0499999, 0.000996, ("0.0500", "0.0010")),     # U rounds up a decade: one digit fewer
    (-12.3456, 0.25, ("-12.35", "0.25")),
    (123456.7, 35.0, ("123457", "35")),
    (1.23e-9, 4.5e-12, ("1.2300e-09", "4.5e-12")),
])
def test_value_rounded_to_its_uncertainty(value, U, want):
    from senscal.report.certificate import value_and_u

    assert value_and_u(value, U) == want
    v, u = value_and_u(value, U)
    # the rounding changes the value by at most half a unit of U's last digit
    assert abs(float(v) - value) <= 0.5 * 10 ** -(len(u.split("e")[0].split(".")[-1]) if "." in u else 0) * \
        (10 ** int(u.split("e")[1]) if "e" in u else 1) + 1e-15


def test_pretty_units():
    from senscal.report.certificate import pretty_unit

    assert pretty_unit("V/(m/s^2)") == "V/(m/s²)" and pretty_unit("degC") == "°C"
    assert pretty_unit("rad/s^(-2)") == "rad/s⁻²" and pretty_unit("pC/(m/s^2)") == "pC/(m/s²)"


def test_certificate_rounds_values_and_prints_units_as_symbols(resp, no_plots):
    html = certificate_html("response", resp, info=FULL, unit="V/(m/s^2)")
    assert "m/s^2" not in html.replace("(m/s^2)</td>", "") or "m/s²" in html
    assert "V/(m/s²)" in html and "°C" in html and "degC" not in html
    # no value printed with more digits than its U: every (value, U) cell pair of the results table
    table = html.split("<h2>Results</h2>")[1].split("</table>")[0]
    cells = re.findall(r"<td>([^<]*)</td>", table)
    p = resp.points[0]
    assert f"{p.sensitivity:.6g}" not in cells or len(f"{p.sensitivity:.6g}") <= 7
    decimals = lambda t: len(t.split(".")[1]) if "." in t else 0   # noqa: E731
    assert decimals(cells[1]) == decimals(cells[2])           # sensitivity and its U
    # one spelling, and the approver's line carries a date
    assert "Normalised" not in html or "normalized" not in html.lower().replace("normalised", "")
    assert "Date: 2026-01-07" in html


def test_traceability_claim_follows_from_the_standards(resp, no_plots):
    from senscal.report.dcc import dcc_xml
    from senscal.report.lab import traceability_claim

    sim = replace(LAB.standards[0], traceability="none: simulated data")
    assert traceability_claim(LAB.standards)[0] is True
    claimed, text = traceability_claim((sim,))
    assert claimed is False and "No metrological traceability" in text
    html = certificate_html("response", resp, info=CertificateInfo(replace(LAB, standards=(sim,)), RUN))
    assert "metrologically traceable to the International System" not in html and "No metrological" in html
    lab = replace(LAB, country="DE")
    run = replace(RUN, certificate_id="C-1", customer_email="qa@example.org")
    xml = dcc_xml("response", resp, CertificateInfo(replace(lab, standards=(sim,)), run))
    assert b"<dcc:traceable>false</dcc:traceable>" in xml
    assert b"<dcc:traceable>true</dcc:traceable>" in dcc_xml("response", resp, CertificateInfo(lab, run))


def test_reference_standard_due_date_is_flagged(resp, no_plots):
    assert "reference-standard-due" not in warning_names(certificate_warnings("response", resp, FULL))
    for due, word in (("", "MISSING"), ("2025-12-31", "OVERDUE")):
        info = CertificateInfo(replace(LAB, standards=(replace(LAB.standards[0], due=due),)), RUN)
        assert "reference-standard-due" in warning_names(certificate_warnings("response", resp, info))
        html = certificate_html("response", resp, info=info)
        std_table = html.split("Reference standards and traceability")[1].split("</table>")[0]
        assert word in std_table
