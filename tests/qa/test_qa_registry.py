"""QA: the registry database is an input that no output may overwrite."""

from __future__ import annotations

import hashlib


def test_registry_export_onto_its_own_database_is_refused(cli, tmp_path):
    db = tmp_path / "reg.sqlite"
    assert cli("registry", "add", "SN-1", "--kind", "accelerometer", "--db", db).code == 0
    before = hashlib.sha256(db.read_bytes()).hexdigest()
    r = cli("registry", "export", db, "--db", db)
    assert r.code == 2, r.err
    assert "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1
    assert hashlib.sha256(db.read_bytes()).hexdigest() == before
    assert "SN-1" in cli("registry", "sensors", "--db", db).out


def test_registry_add_non_finite_nominal(cli, tmp_path):
    r = cli("registry", "add", "SN-2", "--kind", "accelerometer", "--nominal", "sensitivity=nan", "--db",
            tmp_path / "r.sqlite")
    assert r.code == 2 and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err
