"""``senscal registry serve``: the read-only web view, through Flask's test client (issue 29).

The pages are checked against the registry's own answers (the due date of a
sensor is the one ``registry due`` computes, the chain status the one of
``registry verify``, the impact of a standard the one of ``registry
impact``), the database is checked to be byte for byte unchanged after every
page was read, and the options are checked to refuse bad values in one line.
"""

from __future__ import annotations

import hashlib
import queue
import re
import shutil
import socket
import subprocess
import sys
import threading
import urllib.request
from datetime import datetime, timezone
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.exc import DBAPIError

from senscal.registry import Quantity, open_registry

pytest.importorskip("flask")

from senscal.registry.web import ViewOptions, create_app, open_read_only  # noqa: E402

AS_OF = datetime(2024, 9, 1, tzinfo=timezone.utc)


def _fill(url, folder: Path):
    """Two sensors (A1 drifting, with certificate files; B2 without records), one reference standard."""
    reg = open_registry(url)
    reg.add_sensor("A1", "accelerometer", model="4371", nominal={"sensitivity": {"value": 0.01, "unit": "V/(m/s^2)"}})
    reg.add_sensor("B2", "velocity sensor")
    reg.add_standard("REF-1", certificate="DKD-K-1/2023", due="2024-06-30", u_relative="0.2%", name="reference",
                     traceability="PTB")
    recs = []
    for i, year in enumerate(range(2020, 2024)):
        pdf = folder / f"A1-{year}.pdf"
        pdf.write_bytes(b"%PDF-1.4 certificate of " + str(year).encode())
        recs.append(reg.record("A1", [Quantity("sensitivity", 0.0100 + 4e-5 * i, 1e-6, "V/(m/s^2)", 2.0),
                                      Quantity("phase@160Hz", -0.5, 0.05, "deg", 2.0)],
                               performed_at=f"{year}-03-01", certificate=pdf, note=f"cert {year}",
                               standards=["REF-1"] if year >= 2022 else []))
    (folder / "A1-2023.xml").write_text("<dcc/>")  # the DCC written beside the last PDF (--report/--dcc)
    return reg, recs


@pytest.fixture
def site(tmp_path):
    path = tmp_path / "lab.sqlite"
    reg, recs = _fill(path, tmp_path)
    reg.close()
    ro = open_read_only(path)
    app = create_app(ro, ViewOptions(tolerance=0.02, as_of=AS_OF))
    yield app.test_client(), ro, recs, path
    ro.close()


def _links(html: str) -> list[str]:
    return re.findall(r'href="([^"#]+)"', html)


def _crawl(client, start="/") -> dict[str, str]:
    """Every page reachable from ``start`` (downloads fetched, not followed)."""
    seen: dict[str, str] = {}
    todo = [start]
    while todo:
        url = todo.pop()
        if url in seen:
            continue
        r = client.get(url)
        assert r.status_code == 200, (url, r.status_code)
        seen[url] = r.get_data(as_text=True) if r.mimetype == "text/html" else ""
        if r.mimetype == "text/html":
            todo += [u for u in _links(seen[url]) if u.startswith("/")]
    return seen


def test_overview_marks_due_dates_as_registry_due_computes_them(site):
    client, reg, recs, _ = site
    html = client.get("/").get_data(as_text=True)
    rep = reg.drift("A1", "sensitivity", tolerance=0.02, as_of=AS_OF)
    # +4e-5 a year from 0.0100: the line leaves 2 % in 2025 (earlier with its k=2 band), after AS_OF.
    assert rep.due_date is not None and rep.due_date > AS_OF and not rep.overdue
    row = re.search(r"<tr>\s*<th scope=\"row\"><a href=\"/sensors/A1\">A1</a>.*?</tr>", html, re.S).group(0)
    # phase@160Hz: U = 0.1 deg already exceeds 2 % of 0.5 deg, so the sensor is overdue by that quantity.
    phase = reg.drift("A1", "phase@160Hz", tolerance=0.02, as_of=AS_OF)
    assert phase.overdue
    assert "OVERDUE" in row and "phase@160Hz" in row and phase.due_date.date().isoformat() in row
    # The sensor page lists both quantities with their own due dates.
    page = client.get("/sensors/A1").get_data(as_text=True)
    assert rep.due_date.date().isoformat() in page and "OVERDUE" in page
    # The standard was due 2024-06-30: overdue on AS_OF, in date the day before that.
    std = re.search(r"<a href=\"/standards/REF-1\">REF-1</a>.*?</tr>", html, re.S).group(0)
    assert "2024-06-30" in std and "OVERDUE" in std
    early = create_app(reg, ViewOptions(tolerance=0.02, as_of=datetime(2024, 6, 20, tzinfo=timezone.utc)))
    std = re.search(r"REF-1</a>.*?</tr>", early.test_client().get("/").get_data(as_text=True), re.S).group(0)
    assert "due soon" in std and "OVERDUE" not in std
    # Without a tolerance there are no due dates, and the page says how to get them.
    plain = create_app(reg, ViewOptions(as_of=AS_OF)).test_client().get("/").get_data(as_text=True)
    row = re.search(r"/sensors/A1\">A1</a>.*?</tr>", plain, re.S).group(0)
    assert "OVERDUE" not in row and "--tolerance" in plain


def test_sensor_page_plots_history_and_drift(site):
    client, reg, recs, _ = site
    html = client.get("/sensors/A1").get_data(as_text=True)
    assert html.count("<svg") == 2 and html.count('role="img"') == 2  # one plot per quantity, named for readers
    rep = reg.drift("A1", "sensitivity", tolerance=0.02, as_of=AS_OF)
    from senscal.report.certificate import value_and_u

    v, U = value_and_u(rep.drift_per_year, 2 * rep.u_drift_per_year)
    assert f"{v} &plusmn; {U}" in html
    for r in recs:
        assert f'href="/calibrations/{r.uid}"' in html
    q = client.get("/sensors/A1/history/sensitivity")
    assert q.status_code == 200 and q.get_data(as_text=True).count("<svg") == 1
    b2 = client.get("/sensors/B2").get_data(as_text=True)
    assert "No calibrations recorded yet" in b2 and "<svg" not in b2


def test_calibration_page_downloads_its_certificate_and_dcc(site, tmp_path):
    client, reg, recs, _ = site
    last = recs[-1]
    html = client.get(f"/calibrations/{last.uid}").get_data(as_text=True)
    assert f"/calibrations/{last.uid}/certificate.pdf" in html and f"/calibrations/{last.uid}/certificate.xml" in html
    r = client.get(f"/calibrations/{last.uid}/certificate.pdf")
    assert r.status_code == 200 and r.mimetype == "application/pdf"
    assert r.data == (tmp_path / "A1-2023.pdf").read_bytes()
    assert r.headers["Content-Disposition"].startswith("attachment") and "A1-2023.pdf" in r.headers["Content-Disposition"]
    x = client.get(f"/calibrations/{last.uid}/certificate.xml")
    assert x.status_code == 200 and x.data == b"<dcc/>" and x.headers["Content-Disposition"].startswith("attachment")
    # The standards it used, from the record (REF-1 was in date on 2023-03-01).
    assert 'href="/standards/REF-1"' in html and "OVERDUE when used" not in html
    # An older record has no DCC beside its PDF: no XML link, and asking for one is a 404.
    first = recs[0]
    assert "certificate.xml" not in client.get(f"/calibrations/{first.uid}").get_data(as_text=True)
    assert client.get(f"/calibrations/{first.uid}/certificate.xml").status_code == 404
    # The record itself as JSON.
    j = client.get(f"/calibrations/{first.uid}/record.json")
    assert j.status_code == 200 and j.json["uid"] == first.uid and j.json["serial"] == "A1"


def test_certificate_reference_that_is_no_file(tmp_path):
    reg = open_registry(tmp_path / "r.sqlite")
    reg.add_sensor("C3", "accelerometer")
    rec = reg.record("C3", [Quantity("sensitivity", 0.01, 1e-5, "V/(m/s^2)")], performed_at="2024-01-01",
                     certificate="DKD-K-0815 (paper)")
    gone = reg.record("C3", [Quantity("sensitivity", 0.01, 1e-5, "V/(m/s^2)")], performed_at="2024-02-01",
                      certificate=tmp_path / "moved-away.pdf")
    reg.close()
    with open_read_only(tmp_path / "r.sqlite") as ro:
        client = create_app(ro).test_client()
        html = client.get(f"/calibrations/{rec.uid}").get_data(as_text=True)
        assert "DKD-K-0815 (paper)" in html and "nothing to download" in html
        assert client.get(f"/calibrations/{rec.uid}/certificate.pdf").status_code == 404
        assert "nothing to download" in client.get(f"/calibrations/{gone.uid}").get_data(as_text=True)
        assert client.get(f"/calibrations/{gone.uid}/certificate.pdf").status_code == 404


def test_pdf_printed_from_an_html_certificate(tmp_path):
    """An HTML certificate without a PDF beside it downloads as PDF too, printed from that HTML (WeasyPrint)."""
    html = tmp_path / "C-7.html"
    html.write_text('<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>C-7</title></head>'
                    "<body><h1>Calibration certificate C-7</h1></body></html>", encoding="utf-8")
    reg = open_registry(tmp_path / "r.sqlite")
    reg.add_sensor("C7", "accelerometer")
    rec = reg.record("C7", [Quantity("sensitivity", 0.01, 1e-5, "V/(m/s^2)")], performed_at="2024-01-01",
                     certificate=html)
    reg.close()
    with open_read_only(tmp_path / "r.sqlite") as ro:
        client = create_app(ro).test_client()
        page = client.get(f"/calibrations/{rec.uid}").get_data(as_text=True)
        assert "Download the PDF certificate" in page and "Download the HTML certificate" in page
        pdf = client.get(f"/calibrations/{rec.uid}/certificate.pdf")
        assert pdf.status_code == 200 and pdf.mimetype == "application/pdf" and pdf.data.startswith(b"%PDF-")
        assert 'filename="C-7.pdf"' in pdf.headers["Content-Disposition"]
        if shutil.which("pdftotext"):
            text = subprocess.run(["pdftotext", "-", "-"], input=pdf.data, capture_output=True).stdout.decode()
            assert "Calibration certificate C-7" in text
        # A PDF written beside it is the one offered, not a new print.
        (tmp_path / "C-7.pdf").write_bytes(b"%PDF-1.4 the issued one")
        assert client.get(f"/calibrations/{rec.uid}/certificate.pdf").data == b"%PDF-1.4 the issued one"


def test_standard_page_is_the_impact_report(site):
    client, reg, recs, _ = site
    html = client.get("/standards/REF-1").get_data(as_text=True)
    rep = reg.impact("REF-1")
    assert rep.n_calibrations == 2
    for row in rep.rows:
        assert f'href="/calibrations/{row.calibration}"' in html
    for r in recs[:2]:  # the two records before the standard was used
        assert f"/calibrations/{r.uid}" not in html
    assert client.get("/standards/NOPE-9").status_code == 404


def test_every_page_is_self_contained_and_keyboard_usable(site):
    client, *_ = site
    pages = _crawl(client)
    assert {"/", "/sensors/A1", "/sensors/B2", "/chain", "/standards/REF-1"} <= set(pages)
    assert any(u.endswith("/certificate.pdf") for u in pages)
    for url, html in pages.items():
        if not html:
            continue
        # Nothing fetched from anywhere: no scripts, no external style sheets, fonts or images.
        # (The inline plots refer to their own clip paths: url(#id).)
        assert not re.search(r"<script|<link|<img|<iframe|url\((?!#)", html, re.I), url
        assert not re.search(r'(src|href)="(https?:)?//', html), url
        assert '<html lang="en">' in html and '<a class="skip" href="#content">' in html, url
        assert "<h1>" in html and 'id="content"' in html, url
    r = client.get("/")
    csp = r.headers["Content-Security-Policy"]
    assert "default-src 'none'" in csp and "script-src" not in csp
    css = re.search(r"<style>(.*?)</style>", pages["/"], re.S).group(1)
    assert ":focus-visible" in css and "outline" in css


def test_nothing_writes(site):
    client, reg, recs, path = site
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    pages = _crawl(client)
    app = client.application
    for rule in app.url_map.iter_rules():
        assert rule.methods <= {"GET", "HEAD", "OPTIONS"}, rule
    for url in pages:
        for method in ("post", "put", "delete", "patch"):
            assert getattr(client, method)(url).status_code == 405, (method, url)
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before
    # The connection itself refuses to write (mode=ro and query_only), whatever code runs on it.
    with pytest.raises(DBAPIError):
        with reg.engine.begin() as conn:
            conn.execute(sa.text("INSERT INTO sensors (serial, kind, created_at) VALUES ('X', 'y', '2024-01-01')"))
    assert hashlib.sha256(path.read_bytes()).hexdigest() == before


def test_broken_chain_is_shown(site):
    client, reg, recs, path = site
    w = open_registry(path)
    with w.engine.begin() as conn:
        conn.execute(sa.text("DROP TRIGGER quantities_no_update"))
        conn.execute(sa.text("UPDATE quantities SET value = 0.0202 WHERE name = 'sensitivity' AND calibration_id = "
                             "(SELECT id FROM calibrations WHERE uid = :u)"), {"u": recs[1].uid})
    w.close()
    rep = reg.verify()
    assert not rep.intact and rep.first_broken == recs[1].uid
    html = client.get("/").get_data(as_text=True)
    assert "HASH CHAIN BROKEN" in html and "intact" not in html.split("HASH CHAIN BROKEN")[0].split("<main")[-1]
    chain = client.get("/chain").get_data(as_text=True)
    assert "BROKEN" in chain and f'href="/calibrations/{recs[1].uid}"' in chain
    for p in rep.problems:
        assert p.replace("'", "&#39;").replace('"', "&#34;") in chain


def test_intact_chain_shows_the_head(site):
    client, reg, *_ = site
    rep = reg.verify()
    assert rep.intact
    assert rep.head[:16] in client.get("/").get_data(as_text=True)
    assert rep.head in client.get("/chain").get_data(as_text=True)


def test_unknown_things_are_404_and_foreign_hosts_400(site):
    client, *_ = site
    for url in ("/sensors/NOPE", "/calibrations/0000", "/calibrations/0000/certificate.pdf",
                "/sensors/A1/history/nope", "/standards/NOPE", "/standards/not an id", "/nothing"):
        r = client.get(url)
        assert r.status_code == 404 and "<h1>Not found</h1>" in r.get_data(as_text=True), url
    # A page elsewhere that points a name at 127.0.0.1 (DNS rebinding) gets nothing.
    for host in ("attacker.example", "localhost.attacker.example:8000", "[::2]:8000", "127.0.0.2"):
        assert client.get("/", headers={"Host": host}).status_code == 400, host
    for host in ("127.0.0.1:8000", "localhost:8000", "[::1]:8000"):
        assert client.get("/chain", headers={"Host": host}).status_code == 200, host


# --- opening read-only -------------------------------------------------------------------

def test_both_back_ends_are_read_only(db_url, tmp_path):
    """SQLite (mode=ro, query_only) and PostgreSQL (read-only sessions): the view reads, nothing writes."""
    reg, recs = _fill(db_url, tmp_path)
    reg.close()
    with open_read_only(db_url) as ro:
        client = create_app(ro, ViewOptions(tolerance=0.02, as_of=AS_OF)).test_client()
        assert "/sensors/A1" in client.get("/").get_data(as_text=True)
        assert client.get(f"/calibrations/{recs[-1].uid}/certificate.pdf").status_code == 200
        with pytest.raises(DBAPIError):
            with ro.engine.begin() as conn:
                conn.execute(sa.text("INSERT INTO sensors (serial, kind, created_at) "
                                     "VALUES ('X', 'y', CURRENT_TIMESTAMP)"))
    with open_registry(db_url) as again:
        assert [s.serial for s in again.sensors()] == ["A1", "B2"]



def test_open_read_only_refuses_what_is_no_registry(tmp_path):
    from senscal.errors import InputError

    with pytest.raises(InputError, match="does not exist"):
        open_read_only(tmp_path / "missing.sqlite")
    assert not (tmp_path / "missing.sqlite").exists()
    (tmp_path / "empty.sqlite").write_bytes(b"")
    with pytest.raises(InputError, match="no senscal registry"):
        open_read_only(tmp_path / "empty.sqlite")
    assert (tmp_path / "empty.sqlite").read_bytes() == b""
    import sqlite3

    con = sqlite3.connect(tmp_path / "other.sqlite")
    con.execute("CREATE TABLE t (x)")
    con.commit()
    con.close()
    with pytest.raises(InputError, match="no senscal registry"):
        open_read_only(tmp_path / "other.sqlite")


def test_open_read_only_refuses_an_older_schema_without_upgrading_it(tmp_path):
    from alembic import command

    from senscal.errors import InputError
    from senscal.registry import db

    path = tmp_path / "old.sqlite"
    engine = db.create_registry_engine(f"sqlite:///{path}")
    with engine.begin() as conn:
        command.upgrade(db._alembic_config(conn), "0003")
    engine.dispose()
    before = path.read_bytes()
    with pytest.raises(InputError, match="schema revision '0003'.*registry verify"):
        open_read_only(path)
    assert path.read_bytes() == before


# --- the command line --------------------------------------------------------------------

def _one_line_error(r, *fragments):
    assert r.code == 2, (r.out, r.err)
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("senscal: error:"), r.err
    for f in fragments:
        assert f in lines[0], lines[0]


def test_serve_refuses_bad_options_in_one_line(cli, tmp_path):
    db = tmp_path / "lab.sqlite"
    reg, _ = _fill(db, tmp_path)
    reg.close()
    _one_line_error(cli("registry", "serve", "--db", db, "--port", "70000"), "--port", "65535")
    _one_line_error(cli("registry", "serve", "--db", db, "--port", "-1"), "--port")
    _one_line_error(cli("registry", "serve", "--db", tmp_path / "typo.sqlite"), "does not exist")
    _one_line_error(cli("registry", "serve", "--db", tmp_path), "is a folder")
    assert not (tmp_path / "typo.sqlite").exists()
    _one_line_error(cli("registry", "serve", "--db", db, "--host", "0.0.0.0"), "--allow-remote")
    _one_line_error(cli("registry", "serve", "--db", db, "--host", "no-such-host.invalid"), "--host")
    _one_line_error(cli("registry", "serve", "--db", db, "--tolerance", "0"), "--tolerance")
    _one_line_error(cli("registry", "serve", "--db", db, "--tolerance", "abc"), "--tolerance")
    _one_line_error(cli("registry", "serve", "--db", db, "--k", "nan"), "--k")
    _one_line_error(cli("registry", "serve", "--db", db, "--as-of", "2024-13-45"), "--as-of")
    _one_line_error(cli("registry", "serve", "--db", db, "--soon", "-3"), "--soon")
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    try:
        _one_line_error(cli("registry", "serve", "--db", db, "--port", busy.getsockname()[1]), "in use")
    finally:
        busy.close()


def test_serve_answers_on_loopback_and_stops_cleanly(tmp_path):
    db = tmp_path / "lab.sqlite"
    reg, recs = _fill(db, tmp_path)
    reg.close()
    before = hashlib.sha256(db.read_bytes()).hexdigest()
    src = Path(__file__).resolve().parents[2] / "src"
    env = {**__import__("os").environ, "PYTHONPATH": str(src)}
    # Started with Ctrl+C ignored, as a job runner or a pytest-xdist worker starts it: it must stop all the same
    # (a child inherits the ignored SIGINT, and Python then leaves it ignored).
    import signal as _signal

    proc = subprocess.Popen([sys.executable, "-m", "senscal", "registry", "serve", "--db", str(db), "--port", "0",
                             "--tolerance", "2%"], stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
                            preexec_fn=lambda: _signal.signal(_signal.SIGINT, _signal.SIG_IGN))
    lines: "queue.Queue[str]" = queue.Queue()
    threading.Thread(target=lambda: [lines.put(ln) for ln in proc.stderr], daemon=True).start()
    try:
        seen = []
        m = None
        while m is None:
            try:
                seen.append(lines.get(timeout=120))  # imports on a busy CI machine, then one line
            except queue.Empty:
                pytest.fail(f"registry serve printed no address within 120 s: {seen}")
            m = re.search(r"http://127\.0\.0\.1:(\d+)/", seen[-1])
        assert "read-only" in seen[-1], seen
        with urllib.request.urlopen(f"http://127.0.0.1:{m.group(1)}/", timeout=60) as resp:
            html = resp.read().decode()
        assert resp.status == 200 and "/sensors/A1" in html
    finally:
        proc.send_signal(__import__("signal").SIGINT)
        try:
            proc.wait(timeout=120)  # a loaded CI machine (load 20 on 2 cores) took over 30 s
        except subprocess.TimeoutExpired:
            proc.kill()
            pytest.fail(f"registry serve did not stop within 120 s of Ctrl+C; it printed {seen}")
    assert proc.returncode == 0, seen
    assert hashlib.sha256(db.read_bytes()).hexdigest() == before


def test_report_of_a_saved_calibration_downloads_from_anywhere(cli, tmp_path, monkeypatch):
    """``--report cert.html --save``: the record keeps the certificate's absolute path, so the view finds it
    whatever folder it runs in."""
    work = tmp_path / "bench"
    work.mkdir()
    monkeypatch.chdir(work)
    assert cli("simulate", "hydraulic", "--out", "hy", "--seed", "1").code == 0
    r = cli("velocity", "hy/hydraulic_01.csv", "--position", "position", "--velocity",
            "velocity", "--report", "cert.html", "--save", "--sensor", "V1", "--create-sensor", "velocity sensor",
            "--db", tmp_path / "lab.sqlite")
    assert r.code == 0, r.err
    monkeypatch.chdir(tmp_path)
    with open_read_only(tmp_path / "lab.sqlite") as ro:
        rec = ro.calibrations("V1")[0]
        assert rec.certificate == str(work / "cert.html")
        client = create_app(ro).test_client()
        page = client.get(f"/calibrations/{rec.uid}").get_data(as_text=True)
        assert "Download the HTML certificate" in page
        got = client.get(f"/calibrations/{rec.uid}/certificate.html")
        assert got.status_code == 200 and got.data == (work / "cert.html").read_bytes()
        # No PDF was written: the view offers one printed from the HTML (test_pdf_printed_from_an_html_certificate).
        assert "Download the PDF certificate" in page and "printed now from the HTML" in page


def test_overview_reads_every_history_in_one_query_with_the_same_points(db_url, tmp_path):
    """``Registry.histories()`` (the overview's one query) gives each sensor the points ``history()`` gives,
    superseded records left out unless asked for; ``drift_report`` on them is ``drift``."""
    from senscal.registry.store import drift_report

    reg, recs = _fill(db_url, tmp_path)
    reg.record("A1", [Quantity("sensitivity", 0.0101, 1e-6, "V/(m/s^2)", 2.0)], performed_at="2021-03-01",
               supersedes=recs[1].uid, note="corrected")
    reg.add_sensor("C3", "accelerometer")
    reg.record("C3", [Quantity("sensitivity", 0.02, 1e-5, "V/(m/s^2)")], performed_at="2024-01-01")
    for superseded in (False, True):
        every = reg.histories(include_superseded=superseded)
        assert set(every) == {"A1", "C3"}  # B2 has no records
        for serial, pts in every.items():
            assert pts == reg.history(serial, include_superseded=superseded)
    pts = [p for p in reg.histories()["A1"] if p.quantity == "sensitivity"]
    a = drift_report("A1", "sensitivity", pts, tolerance=0.02, as_of=AS_OF)
    b = reg.drift("A1", "sensitivity", tolerance=0.02, as_of=AS_OF)
    assert a.to_dict() == b.to_dict() and a.due_date == b.due_date and a.fit.n_records == 4
    reg.close()
