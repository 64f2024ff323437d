"""Issue 32 items 4, 5 and 7: the registry's guarantees at their edges."""

from __future__ import annotations

import re
import sqlite3

import numpy as np
import pytest

from senscal.io import Recording, write_recording


def _record(cli, db, value, date, *extra):
    return cli("registry", "record", "S1", "--quantity", "s", "--value", value, "--uncertainty", "0.1", "--unit", "V",
               "--date", date, "--k", "2", "--db", db, *extra)


def _head(err: str) -> str:
    m = re.search(r"registry head after \d+ records: ([0-9a-f]{64})", err)
    assert m, err
    return m.group(1)


def _drop_triggers(con):
    for (name,) in con.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'").fetchall():
        con.execute(f"DROP TRIGGER {name}")


@pytest.fixture
def three(cli, tmp_path):
    db = tmp_path / "r.sqlite"
    heads = []
    for i, (v, d) in enumerate([("1.0", "2023-01-01"), ("1.1", "2024-01-01"), ("1.2", "2025-01-01")]):
        r = _record(cli, db, v, d, *(["--create", "--create-sensor", "acc"] if i == 0 else []))
        assert r.code == 0, r.err
        heads.append(_head(r.err))  # every write prints the head to keep elsewhere
    return db, heads


def test_expect_head_accepts_the_head_and_an_older_one(cli, three):
    db, heads = three
    for h in (heads[2], heads[1], heads[2][:16]):
        r = cli("registry", "verify", "--db", db, "--expect-head", h)
        assert r.code == 0, r.err


def test_expect_head_catches_truncation_that_plain_verify_cannot(cli, three):
    db, heads = three
    con = sqlite3.connect(db)
    _drop_triggers(con)
    last = con.execute("SELECT id FROM calibrations ORDER BY id DESC LIMIT 1").fetchone()[0]
    con.execute("DELETE FROM quantities WHERE calibration_id = ?", (last,))
    con.execute("DELETE FROM calibrations WHERE id = ?", (last,))
    # The head row rewritten to match: the file alone is consistent again.
    prev = con.execute("SELECT chain_hash FROM calibrations ORDER BY id DESC LIMIT 1").fetchone()[0]
    con.execute("UPDATE registry_chain SET n_records = 2, head = ?", (prev,))
    con.commit()
    con.close()
    assert cli("registry", "verify", "--db", db).code == 0  # the gap the kept head closes
    r = cli("registry", "verify", "--db", db, "--expect-head", heads[2])
    assert r.code == 3 and "registry-tampered" in r.err and "not in the chain" in r.err, r.err


def test_expect_head_catches_a_wipe(cli, three):
    db, heads = three
    con = sqlite3.connect(db)
    _drop_triggers(con)
    con.execute("DELETE FROM quantities")
    con.execute("DELETE FROM calibrations")
    con.execute("DELETE FROM registry_chain")
    con.commit()
    con.close()
    assert cli("registry", "verify", "--db", db).code == 0
    r = cli("registry", "verify", "--db", db, "--expect-head", heads[0])
    assert r.code == 3 and "0 records" in r.err, r.err


@pytest.mark.parametrize("head", ["zz", "abc", "g" * 64, "0" * 65])
def test_expect_head_malformed_is_one_line(cli, three, head):
    db, _ = three
    r = cli("registry", "verify", "--db", db, "--expect-head", head)
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("content", [b"", b"x", b"SQLite format 3"])
@pytest.mark.parametrize("cmd", [["sensors"], ["verify"], ["history", "S1"],
                                 ["due", "S1", "--quantity", "s", "--tolerance", "1%"], ["export", "{o}"]])
def test_read_only_commands_refuse_a_file_without_a_registry(cli, tmp_path, content, cmd):
    db = tmp_path / "e.sqlite"
    db.write_bytes(content)
    args = [a.replace("{o}", str(tmp_path / "x.json")) for a in cmd]
    r = cli("registry", *args, "--db", db)
    assert r.code == 2 and "no senscal registry" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert db.read_bytes() == content  # no schema created, not even a header written
    assert not (tmp_path / "x.json").exists()


@pytest.mark.parametrize("serial", ["A\u202e321", "A\u200b1", "A\u2066B", "\ufeffA", "A\u2028B"])
def test_serials_with_invisible_or_bidi_characters_are_refused(cli, tmp_path, serial):
    db = tmp_path / "r.sqlite"
    r = cli("registry", "add", serial, "--kind", "acc", "--db", db)
    assert r.code == 2 and "U+" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    r = cli("registry", "record", serial, "--quantity", "s", "--value", "1", "--uncertainty", "0.1", "--unit", "V",
            "--date", "2024-01-01", "--k", "2", "--db", db, "--create-sensor", "acc", "--create")
    assert r.code == 2 and "U+" in r.err, r.err


def test_second_save_with_another_date_says_so(cli, tmp_path):
    t = np.arange(1000) / 1000.0
    rng = np.random.default_rng(1)
    f = write_recording(Recording({"x": np.sin(2 * np.pi * 12.5 * t) + 0.01 * rng.standard_normal(t.size)}, t=t),
                        tmp_path / "s.csv")
    db = tmp_path / "r.sqlite"
    base = ["fit", f, "--freq", "12.5", "--save", "--sensor", "S1", "--db", db]
    r = cli(*base, "--create-sensor", "acc", "--date", "2024-01-01")
    assert r.code == 0, r.err
    r = cli(*base, "--date", "2025-06-01")
    assert r.code == 0, r.err
    assert "2025-06-01" in r.err and "differs" in r.err and "NOT recorded" in r.err, r.err
    r = cli(*base, "--date", "2024-01-01")  # the same date again: plain "already saved"
    assert "already saved" in r.err and "differs" not in r.err, r.err
    con = sqlite3.connect(db)
    assert con.execute("SELECT COUNT(*) FROM calibrations").fetchone()[0] == 1
    assert con.execute("SELECT performed_at FROM calibrations").fetchone()[0].startswith("2024-01-01")


@pytest.mark.parametrize("k", ["nan", "inf", "-1", "0"])
def test_due_k_must_be_a_positive_finite_number(cli, three, k):
    db, _ = three
    r = cli("registry", "due", "S1", "--quantity", "s", "--tolerance", "5%", "--k", k, "--db", db)
    assert r.code == 2 and "--k" in r.err and len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("sql,code", [
    ("UPDATE alembic_version SET version_num = ''", 2),
    ("UPDATE calibrations SET recorded_at = 'garbage' WHERE id = 1", 3),
    ("UPDATE calibrations SET conditions = '{x' WHERE id = 1", 3),
    ("UPDATE sensors SET kind = CAST(X'FFFE41' AS TEXT)", 3),
])
@pytest.mark.parametrize("cmd", [["verify"], ["history", "S1"], ["sensors"], ["export", "-"]])
def test_direct_edits_that_do_not_decode_are_named(cli, three, sql, code, cmd):
    db, _ = three
    con = sqlite3.connect(db)
    _drop_triggers(con)
    con.execute(sql)
    con.commit()
    con.close()
    r = cli("registry", *cmd, "--db", db)
    lines = [ln for ln in r.err.splitlines() if ln.strip()]
    if cmd == ["sensors"] and "calibrations" in sql:
        assert r.code == 0, r.err  # sensors does not read the records
        return
    assert r.code == code and len(lines) == 1 and "internal error" not in r.err, r.err
    if code == 3:
        assert "registry-tampered" in r.err
