"""Reference standards in the registry (issue 29): certificates, due dates, --standard, impact, tamper evidence."""

from __future__ import annotations

import datetime as dt
import json
import sqlite3

import pytest

from senscal.registry import (DuplicateStandardError, Quantity, UnknownStandardError, open_registry)
from senscal.registry.standards import check_ident, check_sha256, check_u_relative, parse_due

Q = [Quantity("sensitivity", 0.0100, 1e-5, "V/(m/s^2)")]


def _ok(r):
    assert r.code == 0, r.err
    return r


def _one_line_error(r, *fragments):
    assert r.code == 2, (r.out, r.err)
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("senscal: error:"), r.err
    for f in fragments:
        assert f in lines[0], lines[0]
    return lines[0]


def _registry_with_history(url):
    reg = open_registry(url)
    reg.add_standard("REF-1", certificate="PTB-1", due="2026-06-30", u_relative="0.2%", name="Reference")
    reg.add_standard("CF-1", certificate="DKD-7", due="2030-01-31", u_relative=0.0005)
    reg.add_sensor("A1", "accelerometer")
    reg.add_sensor("A2", "accelerometer")
    # REF-1 is in date on its due day, overdue the day after.
    reg.record("A1", Q, performed_at="2026-06-30", standards=["REF-1", "CF-1"])
    reg.record("A2", Q, performed_at="2026-07-01", standards=["REF-1"])
    reg.record("A2", [Quantity("sensitivity", 0.0101, 1e-5, "V/(m/s^2)")], performed_at="2026-07-02",
               standards=["CF-1"])
    return reg


def test_standards_are_stored_linked_and_judged(db_url):
    with _registry_with_history(db_url) as reg:
        [cf, ref] = reg.standards()
        assert (ref.ident, ref.certificate, ref.due, ref.u_relative) == ("REF-1", "PTB-1", dt.date(2026, 6, 30), 0.002)
        assert cf.name is None and cf.u_relative == 0.0005
        a1 = reg.calibrations("A1")[0]
        assert {(s.ident, s.overdue) for s in a1.standards} == {("REF-1", False), ("CF-1", False)}
        a2 = reg.calibrations("A2")
        assert [(s.ident, s.overdue) for s in a2[0].standards] == [("REF-1", True)]
        imp = reg.impact("REF-1")
        assert [r.serial for r in imp.rows] == ["A1", "A2"] and [r.overdue for r in imp.rows] == [False, True]
        assert (imp.n_calibrations, imp.n_sensors, imp.n_overdue) == (2, 2, 1)
        assert [r.serial for r in reg.impact("REF-1", since="2026-07-01").rows] == ["A2"]
        assert reg.impact("CF-1", since="2026-07-03").n_calibrations == 0
        # A recalibration of the standard is a new certificate; old calibrations keep the one they used.
        reg.add_standard("REF-1", certificate="PTB-2", due="2027-06-30", u_relative="0.2%", renew=True)
        assert reg.standard("REF-1").certificate == "PTB-2" and reg.standard("REF-1").name == "Reference"
        assert [s.certificate for s in reg.standard_history("REF-1")] == ["PTB-1", "PTB-2"]
        reg.record("A1", [Quantity("sensitivity", 0.0102, 1e-5, "V/(m/s^2)")], performed_at="2026-08-01",
                   standards=["REF-1"])
        assert [r.standard_certificate for r in reg.impact("REF-1").rows] == ["PTB-1", "PTB-1", "PTB-2"]
        rep = reg.verify()
        assert rep.intact and rep.n_standards == 3 and rep.n_records == 4, rep.problems


def test_duplicates_unknown_ids_and_bad_values_are_refused(db_url):
    with _registry_with_history(db_url) as reg:
        with pytest.raises(DuplicateStandardError, match="--renew"):
            reg.add_standard("REF-1", certificate="X", due="2027-01-01", u_relative=0.001)
        with pytest.raises(DuplicateStandardError, match="already has certificate"):
            reg.add_standard("REF-1", certificate="PTB-1", due="2027-01-01", u_relative=0.001, renew=True)
        with pytest.raises(UnknownStandardError, match="registered: CF-1, REF-1"):
            reg.add_standard("NEW-1", certificate="X", due="2027-01-01", u_relative=0.001, renew=True)
        with pytest.raises(UnknownStandardError, match="standard add NOPE"):
            reg.record("A1", Q, performed_at="2026-09-01", standards=["NOPE"])
        with pytest.raises(UnknownStandardError):
            reg.impact("NOPE")
        # Nothing was added by the refused calls.
        assert reg.verify().n_records == 3 and len(reg.standards(include_superseded=True)) == 2


@pytest.mark.parametrize("call, bad", [
    (check_ident, "REF 1"), (check_ident, ""), (check_ident, "-x"), (check_ident, "a" * 201),
    (parse_due, "2026-13-01"), (parse_due, "2026-1-1"), (parse_due, "tomorrow"), (parse_due, "0001-01-01"),
    (check_u_relative, "-0.1"), (check_u_relative, "nan"), (check_u_relative, "1"), (check_u_relative, "abc%"),
    (check_sha256, "abc"), (check_sha256, "g" * 64),
])
def test_validators_refuse_bad_values(call, bad):
    from senscal.errors import InputError

    with pytest.raises(InputError):
        call(bad)


def test_validators_accept_good_values():
    assert check_u_relative("0.2%") == pytest.approx(0.002) and check_u_relative(0) == 0.0
    assert parse_due("2027-03-31") == dt.date(2027, 3, 31)
    assert check_sha256("SHA256:" + "A" * 64) == "a" * 64
    assert check_ident("DKD-K/12345:1.2#3") == "DKD-K/12345:1.2#3"


def test_export_import_keeps_standards_and_links(db_url, tmp_path):
    with _registry_with_history(db_url) as reg:
        doc = json.loads(json.dumps(reg.export()))
    assert doc["version"] == 2 and len(doc["standards"]) == 2
    with open_registry(f"sqlite:///{tmp_path / 'copy.sqlite'}") as copy:
        added = copy.import_(doc)
        assert added["standards"] == 2 and added["calibrations"] == 3
        assert [r.serial for r in copy.impact("REF-1").rows] == ["A1", "A2"]
        assert copy.verify().intact
        again = copy.import_(doc)
        assert again["calibrations"] == 0 and "standards" not in again


def test_tampering_with_standards_or_links_breaks_the_chain(tmp_path):
    path = tmp_path / "r.sqlite"
    _registry_with_history(f"sqlite:///{path}").close()
    con = sqlite3.connect(path)
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):
        con.execute("UPDATE standards SET due = '2030-01-01' WHERE ident = 'REF-1'")
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):
        con.execute("DELETE FROM calibration_standards")
    # Behind the triggers' back: the overdue standard made to look in date.
    con.execute("DROP TRIGGER standards_no_update")
    con.execute("UPDATE standards SET due = '2030-01-01' WHERE ident = 'REF-1'")
    con.commit()
    with open_registry(f"sqlite:///{path}") as reg:
        rep = reg.verify()
    assert not rep.intact and any("reference standard 'REF-1'" in p for p in rep.problems)
    # A link removed (the calibration no longer names a standard it used) breaks that record's hash.
    path2 = tmp_path / "r2.sqlite"
    _registry_with_history(f"sqlite:///{path2}").close()
    con = sqlite3.connect(path2)
    con.execute("DROP TRIGGER calibration_standards_no_delete")
    con.execute("DELETE FROM calibration_standards WHERE id = (SELECT max(id) FROM calibration_standards)")
    con.commit()
    with open_registry(f"sqlite:///{path2}") as reg:
        rep = reg.verify()
    assert not rep.intact and rep.first_broken is not None


def test_a_registry_at_schema_0003_upgrades_with_its_records_intact(tmp_path):
    import sqlalchemy as sa
    from alembic import command

    from senscal.registry import db

    url = f"sqlite:///{tmp_path / 'old.sqlite'}"
    engine = db.create_registry_engine(url)
    with engine.begin() as conn:
        command.upgrade(db._alembic_config(conn), "0003")
    engine.dispose()
    # Records written by the 0003 code path (no standards) keep their hashes after the upgrade.
    with open_registry(url) as reg:
        assert db.current_revision(reg.engine) == "0004" == db.HEAD_REVISION
        reg.add_sensor("A1", "accelerometer")
        reg.record("A1", Q, performed_at="2025-01-01")
        assert reg.verify().intact
        with reg.engine.connect() as conn:
            assert {"standards", "calibration_standards", "standards_chain"} <= set(sa.inspect(conn).get_table_names())


# --- command line ------------------------------------------------------------------

def _sine(tmp_path):
    import numpy as np

    t = np.arange(2000) / 1000.0
    rng = np.random.default_rng(1)
    y = 0.5 * np.sin(2 * np.pi * 12.5 * t + 0.3) + 0.001 * rng.standard_normal(t.size)
    path = tmp_path / "sine.csv"
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="t,x", comments="")
    return path


def test_cli_standard_add_list_show_and_fit_with_standard(cli, tmp_path):
    db = tmp_path / "lab.sqlite"
    _ok(cli("registry", "standard", "add", "REF-1", "--certificate", "PTB-1", "--due", "2026-06-30",
            "--u-relative", "0.2%", "--name", "Reference", "--db", db))
    _ok(cli("registry", "standard", "add", "CF-1", "--certificate", "DKD-7", "--due", "2099-01-31",
            "--u-relative", "0.0005", "--db", db))
    lst = json.loads(_ok(cli("registry", "standard", "list", "--json", "--as-of", "2026-07-01", "--db", db)).out)
    assert [(s["ident"], s["overdue"]) for s in lst["standards"]] == [("CF-1", False), ("REF-1", True)]
    assert "OVERDUE" in _ok(cli("registry", "standard", "list", "--as-of", "2026-07-01", "--db", db)).out
    sine = _sine(tmp_path)
    common = ("fit", sine, "--freq", "12.5", "--save", "--sensor", "A1", "--create-sensor", "accelerometer",
              "--db", db)
    # In date: no warning, --strict passes, the JSON names the standards.
    r = _ok(cli(*common, "--date", "2026-06-30", "--standard", "REF-1", "--standard", "CF-1", "--strict", "--json"))
    doc = json.loads(r.out)
    assert [(s["ident"], s["overdue"]) for s in doc["standards"]] == [("REF-1", False), ("CF-1", False)]
    assert "standard-overdue" not in r.err
    # Past its due date: the named warning, and --strict exits 3 (the record is kept: it was measured).
    r = cli(*common, "--date", "2026-07-01T09:00", "--standard", "REF-1", "--json", "--strict")
    assert r.code == 3 and "standard-overdue: reference standard REF-1" in r.err
    assert json.loads(r.out)["warnings"][-1].startswith("standard-overdue:")
    imp = json.loads(_ok(cli("registry", "impact", "REF-1", "--json", "--db", db)).out)
    assert [row["overdue"] for row in imp["rows"]] == [False, True] and imp["n_sensors"] == 1
    assert json.loads(_ok(cli("registry", "impact", "REF-1", "--since", "2026-07-01", "--json", "--db", db)).out)[
        "n_calibrations"] == 1
    assert "2 calibrations of 1 sensor," in _ok(cli("registry", "impact", "REF-1", "--db", db)).out
    show = json.loads(_ok(cli("registry", "standard", "show", "REF-1", "--json", "--db", db)).out)
    assert show["certificates"][0]["n_calibrations"] == 2
    # Without --save, --standard still looks the standards up and judges them (--db and --date allowed).
    r = cli("fit", sine, "--freq", "12.5", "--standard", "REF-1", "--db", db, "--date", "2026-08-01", "--json")
    assert r.code == 0 and "standard-overdue" in r.err


@pytest.mark.parametrize("args, fragment", [
    (("registry", "standard", "add", "REF 1", "--certificate", "C", "--due", "2027-01-01", "--u-relative", "0.1%"),
     "standard ID"),
    (("registry", "standard", "add", "R1", "--certificate", "C", "--due", "2027-02-30", "--u-relative", "0.1%"),
     "--due"),
    (("registry", "standard", "add", "R1", "--certificate", "C", "--due", "2027-01-01", "--u-relative", "-1"),
     "--u-relative"),
    (("registry", "standard", "add", "R1", "--certificate", "C", "--due", "2027-01-01", "--u-relative", "inf"),
     "--u-relative"),
    (("registry", "standard", "add", "R1", "--certificate", " ", "--due", "2027-01-01", "--u-relative", "0.1%"),
     "--certificate"),
    (("registry", "standard", "add", "R1", "--certificate", "C", "--due", "2027-01-01", "--u-relative", "0.1%",
      "--dcc-hash", "12ab"), "--dcc-hash"),
    (("registry", "impact", "REF-1", "--since", "last week"), "--since"),
    (("registry", "impact", "NOPE"), "unknown reference standard 'NOPE'"),
    (("registry", "standard", "show", "NOPE"), "unknown reference standard 'NOPE'"),
    (("registry", "standard", "list", "--as-of", "2026-02-30"), "--as-of"),
])
def test_cli_bad_input_is_one_line(cli, tmp_path, args, fragment):
    db = tmp_path / "lab.sqlite"
    _ok(cli("registry", "standard", "add", "REF-1", "--certificate", "PTB-1", "--due", "2026-06-30",
            "--u-relative", "0.2%", "--db", db))
    _one_line_error(cli(*args, "--db", db), fragment)


def test_cli_unknown_standard_on_a_calibration_is_one_line_before_the_job(cli, tmp_path):
    db = tmp_path / "lab.sqlite"
    _ok(cli("registry", "standard", "add", "REF-1", "--certificate", "PTB-1", "--due", "2026-06-30",
            "--u-relative", "0.2%", "--db", db))
    sine = _sine(tmp_path)
    _one_line_error(cli("fit", sine, "--standard", "NOPE", "--save", "--sensor", "A1", "--create-sensor", "acc",
                        "--db", db), "unknown reference standard 'NOPE'", "registered: REF-1")
    _one_line_error(cli("fit", sine, "--standard", "bad id", "--db", db), "--standard")
    # Nothing was recorded.
    with open_registry(db) as reg:
        assert reg.verify().n_records == 0


def test_cli_dcc_file_is_fingerprinted_and_its_identifier_read(cli, tmp_path):
    import hashlib

    dcc = tmp_path / "ref_dcc.xml"
    dcc.write_text('<?xml version="1.0"?><dcc:digitalCalibrationCertificate xmlns:dcc="https://ptb.de/dcc">'
                   '<dcc:uniqueIdentifier>PTB-1.21-4711</dcc:uniqueIdentifier></dcc:digitalCalibrationCertificate>')
    db = tmp_path / "lab.sqlite"
    s = json.loads(_ok(cli("registry", "standard", "add", "REF-1", "--certificate", dcc, "--due", "2027-01-01",
                           "--u-relative", "0.1%", "--db", db, "--json")).out)
    assert s["certificate"] == "PTB-1.21-4711"
    assert s["certificate_sha256"] == hashlib.sha256(dcc.read_bytes()).hexdigest()
    _one_line_error(cli("registry", "standard", "add", "REF-2", "--certificate", dcc, "--due", "2027-01-01",
                        "--u-relative", "0.1%", "--dcc-hash", "0" * 64, "--db", db), "differs from the SHA-256")


def test_cli_lab_profile_kept_in_step(cli, tmp_path):
    db = tmp_path / "lab.sqlite"
    lab = tmp_path / "lab.toml"
    lab.write_text('name = "Lab"\n[[standards]]\nid = "CF-1"\nname = "Centrifuge"\ncertificate = "DKD-7"\n'
                   'due = "2027-01-31"\nu_relative = 0.0005\n'
                   '[[standards]]\nserial = "8305-1"\nname = "Reference accelerometer"\ncertificate = "PTB-1"\n'
                   'due = "2027-06-30"\nu_relative = 0.002\n')
    added = json.loads(_ok(cli("registry", "standard", "import", "--lab-profile", lab, "--db", db, "--json")).out)
    assert added["added"] == ["CF-1", "8305-1"]
    assert json.loads(_ok(cli("registry", "standard", "check", "--lab-profile", lab, "--db", db, "--json")).out)[
        "in_step"] is True
    again = json.loads(_ok(cli("registry", "standard", "import", "--lab-profile", lab, "--db", db, "--json")).out)
    assert again["unchanged"] == ["CF-1", "8305-1"] and not again["added"]
    # The registry moves on (a recalibration) and gains a standard the profile does not list.
    _ok(cli("registry", "standard", "add", "CF-1", "--certificate", "DKD-8", "--due", "2028-01-31",
            "--u-relative", "0.0005", "--renew", "--db", db))
    _ok(cli("registry", "standard", "add", "NEW-1", "--certificate", "X", "--due", "2028-01-31",
            "--u-relative", "0.001", "--db", db))
    r = cli("registry", "standard", "check", "--lab-profile", lab, "--db", db)
    assert r.code == 3 and "standards-out-of-step" in r.err
    assert "CF-1: certificate DKD-7 in the profile, DKD-8 in the registry" in r.err
    assert "NEW-1" in r.err
    _one_line_error(cli("registry", "standard", "import", "--lab-profile", lab, "--db", db), "--renew")


def test_impact_dates_are_the_records_own(db_url):
    """The impact report's fast date path prints what the records print (offsets, microseconds), and judges
    overdue on the record's local calibration day."""
    with open_registry(db_url) as reg:
        reg.add_standard("REF-1", certificate="PTB-1", due="2026-06-30", u_relative="0.2%")
        reg.add_sensor("A1", "accelerometer")
        for i, when in enumerate(("2026-06-30T23:30:00+00:00", "2026-07-01T00:30:00+02:00",
                                  "2026-06-30T22:00:00.123456-05:00", "2026-07-01T00:00:00.5+00:00")):
            reg.record("A1", [Quantity("sensitivity", 0.01 + i * 1e-6, 1e-5, "V/(m/s^2)")], performed_at=when,
                       standards=["REF-1"])
        recs = {r.uid: r for r in reg.calibrations("A1")}
        rows = reg.impact("REF-1").rows
    assert [r.performed_at for r in rows] == [recs[r.calibration].performed_at.isoformat() for r in rows]
    assert [r.overdue for r in rows] == [recs[r.calibration].standards[0].overdue for r in rows]
    # 00:30 at +02:00 is 2026-06-30 in UTC but 2026-07-01 where it was measured: overdue there.
    assert sorted((r.performed_at[:10], r.overdue) for r in rows) == [
        ("2026-06-30", False), ("2026-06-30", False), ("2026-07-01", True), ("2026-07-01", True)]


def test_impact_is_an_index_range_scan(tmp_path):
    """The impact query reads calibration_standards through its (standard, calibration) index, never the
    whole table (the 100,000-record timing is benchmarks/bench_impact.py)."""
    from sqlalchemy import event

    url = f"sqlite:///{tmp_path / 'r.sqlite'}"
    with _registry_with_history(url) as reg:
        seen = []
        event.listen(reg.engine, "before_cursor_execute",
                     lambda conn, cur, stmt, params, ctx, many: seen.append((stmt, params)))
        reg.impact("REF-1", since="2026-01-01")
        [(sql, params)] = [(s, p) for s, p in seen if "calibration_standards" in s]
        with reg.engine.connect() as conn:
            plan = " | ".join(r[-1] for r in conn.exec_driver_sql("EXPLAIN QUERY PLAN " + sql, params))
    assert "ix_calibration_standards_standard" in plan, plan
    assert "SCAN" not in plan, plan  # every table by index or primary key, none read whole
