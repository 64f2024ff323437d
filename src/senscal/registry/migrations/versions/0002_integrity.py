"""Registry integrity: hash chain over the records, no REPLACE, sensors with history kept.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22

* ``calibrations.chain_hash`` and the one-row table ``registry_chain`` (count
  and head of the chain); existing records are chained in insertion order.
* SQLite: ``INSERT OR REPLACE`` deleted the old row without firing the DELETE
  triggers (recursive triggers are off by default), so BEFORE INSERT triggers
  now refuse any insert whose key already exists, on all three tables.
* Both back ends: a sensor that has calibration records cannot be deleted,
  renamed or change kind; PostgreSQL also refuses TRUNCATE, which bypasses
  row triggers.
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: Union[str, Sequence[str], None] = "0001"
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

# Keys whose reuse by an INSERT would be a REPLACE in SQLite.
_SQLITE_KEYS = {
    "sensors": "id = NEW.id OR serial = NEW.serial",
    "calibrations": "id = NEW.id OR uid = NEW.uid",
    "quantities": "id = NEW.id OR (calibration_id = NEW.calibration_id AND name = NEW.name)",
}
_HAS_HISTORY = "EXISTS (SELECT 1 FROM calibrations WHERE sensor_id = OLD.id)"


def _backfill(conn) -> None:
    """Chain the records present before this revision, in insertion order."""
    from senscal.registry.chain import GENESIS, canonical_content, link
    from senscal.registry.db import calibrations, quantities, sensors

    c = calibrations.c
    # The columns of this revision only (later ones, e.g. 0003's sensor_digest, do not exist yet).
    cols = [col for col in calibrations.c if col.name != "sensor_digest"]
    rows = conn.execute(sa.select(*cols, sensors.c.serial, sensors.c.kind)
                        .outerjoin(sensors, sensors.c.id == c.sensor_id).order_by(c.id)).mappings().all()
    qs: dict[int, list] = {}
    for q in conn.execute(sa.select(quantities)).mappings():
        qs.setdefault(q["calibration_id"], []).append((q["name"], q["value"], q["uncertainty"], q["unit"], q["k"]))
    head = GENESIS
    for r in rows:
        head = link(head, canonical_content(r, r["serial"], r["kind"], qs.get(r["id"], ())))
        conn.execute(calibrations.update().where(c.id == r["id"]).values(chain_hash=head))
    conn.execute(sa.text("INSERT INTO registry_chain (id, n_records, head) VALUES (1, :n, :h)"),
                 {"n": len(rows), "h": head})


def upgrade() -> None:
    conn = op.get_bind()
    dialect = conn.dialect.name
    op.add_column("calibrations", sa.Column("chain_hash", sa.String(64)))
    op.create_table(
        "registry_chain",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("n_records", sa.Integer, nullable=False),
        sa.Column("head", sa.String(64), nullable=False),
        sa.CheckConstraint("id = 1", name="ck_registry_chain_one_row"),
    )
    if dialect == "sqlite":
        op.execute("DROP TRIGGER calibrations_no_update")
        _backfill(conn)
        op.execute("CREATE TRIGGER calibrations_no_update BEFORE UPDATE ON calibrations "
                   "BEGIN SELECT RAISE(ABORT, 'calibrations are append-only'); END")
        for table, key in _SQLITE_KEYS.items():
            op.execute(f"CREATE TRIGGER {table}_no_replace BEFORE INSERT ON {table} "
                       f"WHEN EXISTS (SELECT 1 FROM {table} WHERE {key}) "
                       f"BEGIN SELECT RAISE(ABORT, '{table}: key exists; records are never replaced'); END")
        op.execute(f"CREATE TRIGGER sensors_keep_history_delete BEFORE DELETE ON sensors WHEN {_HAS_HISTORY} "
                   "BEGIN SELECT RAISE(ABORT, 'a sensor with calibration records cannot be deleted'); END")
        op.execute("CREATE TRIGGER sensors_keep_history_update BEFORE UPDATE ON sensors "
                   "WHEN (NEW.id IS NOT OLD.id OR NEW.serial IS NOT OLD.serial OR NEW.kind IS NOT OLD.kind) "
                   f"AND {_HAS_HISTORY} "
                   "BEGIN SELECT RAISE(ABORT, 'a sensor with calibration records cannot be renamed'); END")
    elif dialect == "postgresql":
        op.execute("ALTER TABLE calibrations DISABLE TRIGGER calibrations_append_only")
        _backfill(conn)
        op.execute("ALTER TABLE calibrations ENABLE TRIGGER calibrations_append_only")
        op.execute(
            "CREATE FUNCTION senscal_keep_history() RETURNS trigger AS $$ BEGIN "
            "IF (TG_OP = 'DELETE' OR NEW.id <> OLD.id OR NEW.serial <> OLD.serial OR NEW.kind <> OLD.kind) "
            f"AND {_HAS_HISTORY} THEN "
            "RAISE EXCEPTION 'a sensor with calibration records cannot be deleted or renamed'; END IF; "
            "IF TG_OP = 'DELETE' THEN RETURN OLD; END IF; RETURN NEW; END; $$ LANGUAGE plpgsql")
        op.execute("CREATE TRIGGER sensors_keep_history BEFORE UPDATE OR DELETE ON sensors "
                   "FOR EACH ROW EXECUTE FUNCTION senscal_keep_history()")
        for table in ("sensors", "calibrations", "quantities"):
            op.execute(f"CREATE TRIGGER {table}_no_truncate BEFORE TRUNCATE ON {table} "
                       "FOR EACH STATEMENT EXECUTE FUNCTION senscal_append_only()")


def downgrade() -> None:
    dialect = op.get_bind().dialect.name
    if dialect == "sqlite":
        for table in _SQLITE_KEYS:
            op.execute(f"DROP TRIGGER IF EXISTS {table}_no_replace")
        op.execute("DROP TRIGGER IF EXISTS sensors_keep_history_delete")
        op.execute("DROP TRIGGER IF EXISTS sensors_keep_history_update")
    elif dialect == "postgresql":
        for table in ("sensors", "calibrations", "quantities"):
            op.execute(f"DROP TRIGGER IF EXISTS {table}_no_truncate ON {table}")
        op.execute("DROP TRIGGER IF EXISTS sensors_keep_history ON sensors")
        op.execute("DROP FUNCTION IF EXISTS senscal_keep_history()")
    op.drop_table("registry_chain")
    op.drop_column("calibrations", "chain_hash")
