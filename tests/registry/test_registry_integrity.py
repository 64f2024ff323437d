"""Registry integrity: triggers prevent, the hash chain detects (issue 19 item 5, issue 20 item 4).

Both back ends (the ``db_url`` fixture). Every tampering is first tried as
plain SQL with the triggers in place (refused, history unchanged, ``registry
verify`` exits 0); then as someone with full access who drops the triggers
(it succeeds, and ``registry verify`` exits 3 naming the broken record).
"""

from __future__ import annotations

import json

import pytest
import sqlalchemy as sa
from sqlalchemy.exc import DBAPIError

from senscal.registry import Quantity, open_registry

TRIGGERS = {
    "sqlite": ["quantities_no_replace", "quantities_no_update", "quantities_no_delete", "calibrations_no_replace",
               "calibrations_no_update", "calibrations_no_delete", "sensors_no_replace",
               "sensors_keep_history_delete", "sensors_keep_history_update"],
    "postgresql": [("quantities", "quantities_append_only"), ("calibrations", "calibrations_append_only"),
                   ("sensors", "sensors_keep_history")],
}


def _history(url):
    reg = open_registry(url)
    reg.add_sensor("A1", "accelerometer")
    reg.add_sensor("B2", "accelerometer")
    recs = [reg.record("A1", [Quantity("sensitivity", 0.0100 + 1e-5 * i, 2e-6, "V/(m/s^2)", 2.0),
                              Quantity("phase", 0.1 * i, 0.01, "deg", 2.0)], performed_at=f"202{i}-03-01")
            for i in range(4)]
    return reg, recs


def _refused(reg, *statements):
    for sql in statements:
        with pytest.raises(DBAPIError):
            with reg.engine.begin() as conn:
                conn.execute(sa.text(sql))


def _drop_triggers(reg):
    with reg.engine.begin() as conn:
        if conn.dialect.name == "sqlite":
            for name in TRIGGERS["sqlite"]:
                conn.execute(sa.text(f"DROP TRIGGER {name}"))
        else:
            for table, name in TRIGGERS["postgresql"]:
                conn.execute(sa.text(f"DROP TRIGGER {name} ON {table}"))


def _verify(cli, url):
    return cli("registry", "verify", "--db", url)


def _cal_id(reg, uid):
    with reg.engine.connect() as conn:
        return conn.execute(sa.text("SELECT id FROM calibrations WHERE uid = :u"), {"u": uid}).scalar_one()


def test_sqlite_foreign_keys_on_every_connection(tmp_path):
    from senscal.registry.db import read_connection

    reg = open_registry(tmp_path / "r.sqlite")
    conns = [read_connection(reg.engine) for _ in range(3)]       # distinct pooled connections
    try:
        assert [c.execute(sa.text("PRAGMA foreign_keys")).scalar() for c in conns] == [1, 1, 1]
    finally:
        for c in conns:
            c.close()
        reg.close()


def test_intact_registry_verifies(cli, db_url):
    reg, recs = _history(db_url)
    rep = reg.verify()
    assert rep.intact and rep.n_records == 4 and rep.problems == () and len(rep.head) == 64
    r = _verify(cli, db_url)
    assert r.code == 0 and rep.head in r.out, r.err
    h = cli("registry", "history", "A1", "--db", db_url, "--strict", "--json")
    assert h.code == 0 and json.loads(h.out)["warnings"] == [], h.err
    doc = json.loads(cli("registry", "verify", "--db", db_url, "--json").out)
    assert doc["intact"] and doc["n_records"] == 4 and doc["head"] == rep.head
    # The chain extends with every record, and an empty registry verifies too.
    reg.record("B2", [Quantity("sensitivity", 0.02, 1e-5, "V/(m/s^2)")], performed_at="2024-01-01")
    assert reg.verify().intact and reg.verify().head != rep.head
    reg.close()


def test_replace_of_a_quantity(cli, db_url):
    reg, recs = _history(db_url)
    cid = _cal_id(reg, recs[1].uid)
    with reg.engine.connect() as conn:
        qid = conn.execute(sa.text("SELECT id FROM quantities WHERE calibration_id = :c AND name = 'sensitivity'"),
                           {"c": cid}).scalar_one()
    if reg.engine.dialect.name == "sqlite":
        replace = (f"INSERT OR REPLACE INTO quantities (id, calibration_id, name, value, uncertainty, unit, k) "
                   f"VALUES ({qid}, {cid}, 'sensitivity', 0.0202, 2e-6, 'V/(m/s^2)', 2)")
    else:
        replace = (f"INSERT INTO quantities (id, calibration_id, name, value, uncertainty, unit, k) "
                   f"VALUES ({qid}, {cid}, 'sensitivity', 0.0202, 2e-6, 'V/(m/s^2)', 2) "
                   "ON CONFLICT (id) DO UPDATE SET value = EXCLUDED.value")
    _refused(reg, replace)
    assert _verify(cli, db_url).code == 0
    assert [p.value for p in reg.history("A1", "sensitivity")][1] == pytest.approx(0.01001)
    _drop_triggers(reg)
    with reg.engine.begin() as conn:
        conn.execute(sa.text(replace))
    assert [p.value for p in reg.history("A1", "sensitivity")][1] == pytest.approx(0.0202)   # the tampering took
    r = _verify(cli, db_url)
    assert r.code == 3 and "registry-tampered" in r.err and recs[1].uid in r.err, r.err
    assert len(r.err.strip().splitlines()) == 1
    assert reg.verify().first_broken == recs[1].uid
    # History and due dates still answer, with the named warning; --strict exits 3.
    h = cli("registry", "history", "A1", "--db", db_url)
    assert h.code == 0 and "registry-tampered" in h.err, h.err
    assert json.loads(cli("registry", "history", "A1", "--db", db_url, "--json").out)["warnings"][0].startswith(
        "registry-tampered")
    assert cli("registry", "history", "A1", "--db", db_url, "--strict").code == 3
    due = ["registry", "due", "A1", "--quantity", "sensitivity", "--tolerance", "1%", "--db", db_url]
    assert "registry-tampered" in cli(*due).err and cli(*due, "--strict").code == 3
    reg.close()


@pytest.mark.parametrize("which", [1, 3])          # a record in the middle, and the newest
def test_direct_delete_of_a_record(cli, db_url, which):
    reg, recs = _history(db_url)
    cid = _cal_id(reg, recs[which].uid)
    deletes = (f"DELETE FROM quantities WHERE calibration_id = {cid}", f"DELETE FROM calibrations WHERE id = {cid}")
    _refused(reg, *deletes)
    assert _verify(cli, db_url).code == 0
    _drop_triggers(reg)
    with reg.engine.begin() as conn:
        for sql in deletes:
            conn.execute(sa.text(sql))
    assert len(reg.history("A1", "sensitivity")) == 3
    r = _verify(cli, db_url)
    assert r.code == 3 and "registry-tampered" in r.err, r.err
    if which == 1:
        assert recs[2].uid in r.err           # the next record no longer chains
    else:
        assert "head says 4 records" in r.err
    reg.close()


def test_sensor_with_history_cannot_be_deleted_or_renamed(cli, db_url):
    reg, recs = _history(db_url)
    _refused(reg, "DELETE FROM sensors WHERE serial = 'A1'", "UPDATE sensors SET serial = 'A9' WHERE serial = 'A1'",
             "UPDATE sensors SET kind = 'gyro' WHERE serial = 'A1'")
    if reg.engine.dialect.name == "postgresql":
        _refused(reg, "TRUNCATE sensors CASCADE", "TRUNCATE quantities")
    else:
        _refused(reg, "INSERT OR REPLACE INTO sensors (id, serial, kind, created_at) "
                      "VALUES (1, 'A1', 'gyro', '2020-01-01 00:00:00')")
    # With history its metadata is printed beside the calibrations: fixed too (issue 32, schema 0003).
    _refused(reg, "UPDATE sensors SET notes = 'moved to lab 2' WHERE serial = 'A1'",
             "UPDATE sensors SET model = 'X9' WHERE serial = 'A1'",
             "UPDATE sensors SET nominal = NULL WHERE serial = 'A1'")
    # Without history a sensor is only a name: notes may change, it may be removed.
    with reg.engine.begin() as conn:
        conn.execute(sa.text("UPDATE sensors SET notes = 'moved to lab 2' WHERE serial = 'B2'"))
        conn.execute(sa.text("DELETE FROM sensors WHERE serial = 'B2'"))
    assert [s.serial for s in reg.sensors()] == ["A1"] and _verify(cli, db_url).code == 0
    _drop_triggers(reg)
    with reg.engine.begin() as conn:
        conn.execute(sa.text("UPDATE sensors SET serial = 'A9' WHERE serial = 'A1'"))
    r = _verify(cli, db_url)
    assert r.code == 3 and recs[0].uid in r.err, r.err
    reg.close()


def test_sensor_metadata_edit_behind_the_triggers_is_detected(cli, db_url):
    # Issue 32: model, manufacturer and nominal values sat outside the chain; each record now carries the
    # digest of its sensor's metadata, inside its hash.
    reg, recs = _history(db_url)
    assert _verify(cli, db_url).code == 0
    _drop_triggers(reg)
    with reg.engine.begin() as conn:
        conn.execute(sa.text("UPDATE sensors SET manufacturer = 'Other' WHERE serial = 'A1'"))
    r = _verify(cli, db_url)
    assert r.code == 3 and "metadata of sensor 'A1'" in r.err, r.err
    with reg.engine.begin() as conn:  # restoring the metadata but dropping the digest breaks the chain instead
        conn.execute(sa.text("UPDATE sensors SET manufacturer = NULL WHERE serial = 'A1'"))
        conn.execute(sa.text("UPDATE calibrations SET sensor_digest = NULL"))
    r = _verify(cli, db_url)
    assert r.code == 3 and recs[0].uid in r.err, r.err
    reg.close()


def test_sqlite_plain_client_without_foreign_keys(tmp_path, cli):
    # The sqlite3 shell and Python's sqlite3 module start with foreign keys off:
    # the triggers still keep a sensor's history from being orphaned.
    import sqlite3

    path = tmp_path / "r.sqlite"
    reg, recs = _history(str(path))
    reg.close()
    con = sqlite3.connect(path)
    try:
        assert con.execute("PRAGMA foreign_keys").fetchone() == (0,)
        for sql in ("DELETE FROM sensors WHERE serial = 'A1'",
                    "INSERT OR REPLACE INTO calibrations SELECT * FROM calibrations WHERE id = 1"):
            with pytest.raises(sqlite3.IntegrityError):
                con.execute(sql)
        con.rollback()
    finally:
        con.close()
    assert _verify(cli, str(path)).code == 0


def test_upgrade_from_0001_chains_existing_records(cli, db_url):
    # A registry written by the previous schema (no chain) gets one on upgrade.
    from alembic import command

    from senscal.registry import db

    engine = db.create_registry_engine(db_url)
    with engine.begin() as conn:
        command.upgrade(db._alembic_config(conn), "0001")
        # Ids from the database's own sequences, as the old senscal wrote them.
        conn.execute(sa.text("INSERT INTO sensors (serial, kind, created_at) VALUES "
                             "('OLD-1', 'accelerometer', '2020-01-01 00:00:00')"))
        for i in (1, 2):
            conn.execute(sa.text(
                "INSERT INTO calibrations (uid, sensor_id, performed_at, utc_offset_s, recorded_at, job, result) "
                f"SELECT 'uid-{i}', id, '202{i}-01-01 00:00:00', 3600, '202{i}-01-02 00:00:00', 'manual', "
                "'{\"a\": [1.5, null]}' FROM sensors WHERE serial = 'OLD-1'"))
            conn.execute(sa.text("INSERT INTO quantities (calibration_id, name, value, uncertainty, unit, k) "
                                 f"SELECT id, 'sensitivity', 0.01, 1e-5, 'V', 2 FROM calibrations "
                                 f"WHERE uid = 'uid-{i}'"))
    engine.dispose()
    reg = open_registry(db_url)
    assert reg.verify().intact and reg.verify().n_records == 2
    reg.record("OLD-1", [Quantity("sensitivity", 0.0101, 1e-5, "V")], performed_at="2023-01-01")
    assert reg.verify().intact and _verify(cli, db_url).code == 0
    reg.close()


def test_same_evidence_twice_adds_nothing(db_url):
    reg, recs = _history(db_url)
    again = reg.record("A1", list(recs[2].quantities), performed_at="2022-03-01")
    assert again.already_recorded and again.uid == recs[2].uid
    # A different note (another certificate) is another record.
    other = reg.record("A1", list(recs[2].quantities), performed_at="2022-03-01", note="second certificate")
    assert not other.already_recorded
    assert len(reg.history("A1", "sensitivity")) == 5 and reg.verify().intact
    reg.close()


def test_retry_after_an_output_failure_adds_no_duplicate(cli, tmp_path, monkeypatch):
    # The terminal fails after the record committed (a closed pipe, a full disk under tee):
    # the user retries, and the registry must still hold one record.
    from senscal.cli import cmd_registry

    db = str(tmp_path / "r.sqlite")
    args = ["registry", "record", "S1", "--quantity", "sensitivity", "--value", "0.01", "--uncertainty", "2e-5",
            "--unit", "V/g", "--k", "2", "--date", "2024-02-01", "--create-sensor", "accelerometer", "--db", db]

    def broken(*a, **k):
        raise OSError(5, "Input/output error")

    with monkeypatch.context() as m:
        m.setattr(cmd_registry.console, "print", broken)
        assert cli(*args).code != 0
    r = cli(*args)
    assert r.code == 0 and "already recorded" in r.out and "nothing added" in r.out, (r.out, r.err)
    sens = json.loads(cli("registry", "sensors", "--db", db, "--json").out)["sensors"]
    assert [(s["serial"], s["n_calibrations"]) for s in sens] == [("S1", 1)]
