"""The certificate options of ``senscal response`` (shared by velocity and linearity): lab profile, run file, PDF, DCC."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest


ACCREDITED = 'accreditation = "DAkkS D-K-99999-01-00"\nprocedure = "QP-VIB-07 rev 3"\n'

RUN = """
[run]
customer = "ACME <GmbH>"
customer_address = "Am Markt 1, 10115 Berlin"
customer_email = "qa@acme.example"
item = "servo accelerometer"
manufacturer = "Qfab"
deviations = "Points above 10 Hz omitted at the customer's request."
"""


@pytest.fixture(scope="module")
def setup(tmp_path_factory, centrifuge_files, lab_profile):
    d = tmp_path_factory.mktemp("certcli")
    (d / "lab.toml").write_text(lab_profile("0.0005", extra=ACCREDITED, run_fields=False))
    (d / "lab_poor_reference.toml").write_text(lab_profile("0.05", extra=ACCREDITED, run_fields=False))
    (d / "run.toml").write_text(RUN)
    return d, centrifuge_files


def _base(files):
    return ["response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--static-sensitivity", "0.05", "--initial-phase-deg", "90", "--json"]


COMPLETE = ["--u-input", "0.2%", "--u-static-sensitivity", "0.05%", "--u-initial-phase-deg", "0.05",
            "--sensor-id", "SN-1", "--model", "QF-1", "--calibration-date", "2026-01-05",
            "--env", "temperature=23.1+-0.5 degC"]


def _pdf_pages(pdf) -> list[str]:
    text = subprocess.run(["pdftotext", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    return [" ".join(p.split()) for p in text.split("\f")[:-1]]


@pytest.mark.skipif(not shutil.which("pdftotext"), reason="poppler-utils not installed")
def test_complete_certificate_pdf_and_dcc(cli, setup):
    d, files = setup
    r = cli(*_base(files), *COMPLETE, "--lab", d / "lab.toml", "--run", d / "run.toml", "--customer", "ACME <GmbH>",
            "--report", d / "c.pdf", "--dcc", d / "c.xml", "--strict")
    assert r.code == 0, r.err
    assert json.loads(r.out)["warnings"] == []
    pages = _pdf_pages(d / "c.pdf")
    text = " ".join(pages)
    cert_id = re.search(r"Certificate id (SC-\d{8}-[0-9A-F]{8})", text).group(1)
    for i, page in enumerate(pages, start=1):
        assert f"Certificate {cert_id}" in page and f"Page {i} of {len(pages)}" in page
    for field in ("Vibration Lab Nord", "ACME <GmbH>", "servo accelerometer", "Qfab QF-1", "SN-1", "2026-01-05",
                  "Laboratory hall 2", "PTB-1.21-4711", "Dr. Ada Pruefer", "omitted at the customer's request",
                  "temperature", "23.1", "°C"):
        assert field in text, field
    assert "DRAFT" not in text
    from senscal.report.dcc import validate_dcc

    xml = (d / "c.xml").read_bytes()
    validate_dcc(xml)
    assert cert_id.encode() in xml and b"ACME &lt;GmbH&gt;" in xml


@pytest.mark.skipif(not shutil.which("pdftotext"), reason="poppler-utils not installed")
def test_missing_fields_draft_pdf_warning_and_strict(cli, setup, tmp_path):
    d, files = setup
    r = cli(*_base(files), "--report", tmp_path / "draft.pdf")
    assert r.code == 0, r.err
    names = [w.split(":")[0] for w in json.loads(r.out)["warnings"]]
    assert names == ["certificate-draft", "budget-zero-component"]  # no profile; --u-input etc. not given
    assert "warning: certificate-draft" in r.err and "lab.name" in r.err and "run.customer" in r.err
    pages = _pdf_pages(tmp_path / "draft.pdf")
    assert pages and all("DRAFT" in p for p in pages)
    assert "not stated" not in " ".join(pages)
    # --strict: the draft is still written (to be completed), then exit 3
    r = cli(*_base(files), *COMPLETE, "--lab", d / "lab.toml", "--report", tmp_path / "draft.html", "--strict")
    assert r.code == 3
    assert "certificate-draft" in r.err and "run.customer" in r.err and "lab.name" not in r.err
    assert 'class="watermark">DRAFT<' in (tmp_path / "draft.html").read_text()
    # a DCC has no DRAFT mark: refused with the missing fields, and nothing else is written
    r = cli(*_base(files), "--report", tmp_path / "x.html", "--dcc", tmp_path / "x.xml")
    assert r.code == 2 and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1
    assert not (tmp_path / "x.xml").exists() and not (tmp_path / "x.html").exists()


def test_reference_better_than_the_result(cli, setup, tmp_path):
    d, files = setup
    r = cli(*_base(files), *COMPLETE, "--lab", d / "lab_poor_reference.toml", "--run", d / "run.toml",
            "--report", tmp_path / "c.html")
    assert r.code == 0, r.err
    assert [w.split(":")[0] for w in json.loads(r.out)["warnings"]] == ["u-below-reference"]
    assert "Double centrifuge DC-2" in r.err


@pytest.mark.parametrize("args, message", [
    (["--report", "{t}/x.txt"], "unsupported extension '.txt'"),
    (["--dcc", "{t}/x.json"], "unsupported extension '.json'"),
    (["--report", "{t}/x.pdf", "--lab", "{t}/missing.toml"], "missing.toml"),
    (["--report", "{t}/x.pdf", "--lab", "{t}/bad.toml"], "unknown field(s) 'colour'"),
    (["--report", "{t}/x.pdf", "--run", "{t}/bad.toml"], "unknown field(s) 'colour', 'name'"),
    (["--report", "{t}/x.pdf", "--env", "temperature=warm"], "NAME=VALUE+-U UNIT"),
    (["--report", "{t}/x.pdf", "--calibration-date", "5.1.2026"], "not an ISO 8601 date"),
    (["--report", "{t}/x.pdf", "--customer", "AC\udcffME"], "not UTF-8"),   # a non-UTF-8 byte in argv
])
def test_bad_certificate_input_is_one_line_exit_2(cli, setup, tmp_path, args, message):
    d, files = setup
    (tmp_path / "bad.toml").write_text('name = "Lab"\ncolour = "blue"\n')
    r = cli(*_base(files), *[a.format(t=tmp_path) for a in args])
    assert r.code == 2, r.err
    assert message in r.err and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert not list(tmp_path.glob("x.*"))
