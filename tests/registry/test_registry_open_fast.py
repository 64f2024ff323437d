"""Opening a registry already at the newest schema skips alembic (issue 16: a loop of CLI calls).

Alembic and numpy cost seconds of every ``senscal registry record`` call on
a loaded machine; an up-to-date database needs neither. The shortcut rests on
:data:`senscal.registry.db.HEAD_REVISION`, which must stay equal to the head
alembic computes from the shipped migrations.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
import sqlalchemy as sa

from senscal.errors import InputError
from senscal.registry import Quantity, open_registry
from senscal.registry import db


def test_head_revision_constant_matches_the_migrations():
    # A new migration without updating HEAD_REVISION would leave registries un-upgraded.
    assert db.HEAD_REVISION == db.head_revision()


def test_open_and_record_in_an_up_to_date_registry_imports_no_alembic_or_numpy(tmp_path):
    url = f"sqlite:///{tmp_path / 'r.sqlite'}"
    open_registry(url).close()  # created (and migrated by alembic) in this process
    code = (
        "import sys, json\n"
        "from senscal.registry import open_registry, Quantity\n"
        f"with open_registry({url!r}) as reg:\n"
        "    reg.record('SN-1', [Quantity('sensitivity', 0.01, 1e-5, 'V')], performed_at='2024-01-01',\n"
        "               create_kind='accelerometer')\n"
        "    n = len(reg.history('SN-1', 'sensitivity'))\n"
        "print(json.dumps({'n': n, 'mods': [m for m in ('alembic', 'numpy', 'scipy', 'pandas')\n"
        "                                   if m in sys.modules]}))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    assert got == {"n": 1, "mods": []}


def test_current_revision_reads_empty_and_migrated_databases(tmp_path):
    url = f"sqlite:///{tmp_path / 'r.sqlite'}"
    engine = db.create_registry_engine(url)
    try:
        assert db.current_revision(engine) is None
        db.upgrade(engine)
        assert db.current_revision(engine) == db.HEAD_REVISION
    finally:
        engine.dispose()


def test_database_at_an_old_revision_is_still_upgraded(db_url):
    from alembic import command

    engine = db.create_registry_engine(db_url)
    with engine.begin() as conn:
        command.upgrade(db._alembic_config(conn), "0001")
    assert db.current_revision(engine) == "0001"
    engine.dispose()
    with open_registry(db_url) as reg:
        assert db.current_revision(reg.engine) == db.HEAD_REVISION
        # The 0002 schema (hash chain) is in place: a record is chained and verifies.
        reg.record("OLD-1", [Quantity("sensitivity", 0.01, 1e-5, "V")], performed_at="2023-01-01",
                   create_kind="accelerometer")
        assert reg.verify().intact and reg.verify().n_records == 1


@pytest.mark.parametrize("stored", ["0999", "0002+0999"])
def test_unknown_revision_is_refused_in_one_line(tmp_path, stored):
    url = f"sqlite:///{tmp_path / 'r.sqlite'}"
    open_registry(url).close()
    engine = sa.create_engine(url)
    with engine.begin() as conn:
        conn.execute(sa.text("DELETE FROM alembic_version"))
        for rev in stored.split("+"):
            conn.execute(sa.text("INSERT INTO alembic_version (version_num) VALUES (:v)"), {"v": rev})
    engine.dispose()
    with pytest.raises(InputError) as exc:
        open_registry(url)
    msg = str(exc.value)
    assert "\n" not in msg and "does not know" in msg and "upgrade senscal" in msg


def test_cli_refuses_an_unknown_revision_with_exit_2_and_no_traceback(tmp_path):
    path = tmp_path / "r.sqlite"
    open_registry(f"sqlite:///{path}").close()
    engine = sa.create_engine(f"sqlite:///{path}")
    with engine.begin() as conn:
        conn.execute(sa.text("UPDATE alembic_version SET version_num = '0999'"))
    engine.dispose()
    before = path.read_bytes()
    out = subprocess.run([sys.executable, "-m", "senscal", "registry", "sensors", "--db", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "'0999'" in lines[0] and "Traceback" not in out.stderr
    assert path.read_bytes() == before
