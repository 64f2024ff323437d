"""Sensor metadata under the chain: fixed by the triggers once a sensor has records, its digest in each record.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-26

* ``calibrations.sensor_digest``: SHA-256 of the sensor's metadata (serial,
  kind, model, manufacturer, nominal values, notes, registration time) when
  the record was made.  Part of the record's hashed content when present, so
  it cannot be changed or removed without breaking the chain; ``registry
  verify`` compares it with the sensor as it is now.  Records made before
  this revision carry none (their hash is unchanged).
* Both back ends: the trigger that kept the serial and kind of a sensor with
  records now keeps every metadata column (model, manufacturer, nominal,
  notes, created_at) too: they are printed beside the calibrations.
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: Union[str, Sequence[str], None] = "0002"
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

_HAS_HISTORY = "EXISTS (SELECT 1 FROM calibrations WHERE sensor_id = OLD.id)"
_SQLITE_CHANGED = " OR ".join(f"NEW.{c} IS NOT OLD.{c}" for c in (
    "id", "serial", "kind", "model", "manufacturer", "nominal", "notes", "created_at"))
# PostgreSQL: json has no equality operator; compare the text.
_PG_CHANGED = " OR ".join(
    [f"NEW.{c} IS DISTINCT FROM OLD.{c}" for c in ("id", "serial", "kind", "model", "manufacturer", "notes",
                                                   "created_at")]
    + ["NEW.nominal::text IS DISTINCT FROM OLD.nominal::text"])


def upgrade() -> None:
    dialect = op.get_bind().dialect.name
    op.add_column("calibrations", sa.Column("sensor_digest", sa.String(64)))
    if dialect == "sqlite":
        op.execute("DROP TRIGGER sensors_keep_history_update")
        op.execute("CREATE TRIGGER sensors_keep_history_update BEFORE UPDATE ON sensors "
                   f"WHEN ({_SQLITE_CHANGED}) AND {_HAS_HISTORY} "
                   "BEGIN SELECT RAISE(ABORT, 'a sensor with calibration records cannot be changed'); END")
    elif dialect == "postgresql":
        op.execute(
            "CREATE OR REPLACE FUNCTION senscal_keep_history() RETURNS trigger AS $$ BEGIN "
            f"IF (TG_OP = 'DELETE' OR {_PG_CHANGED}) AND {_HAS_HISTORY} THEN "
            "RAISE EXCEPTION 'a sensor with calibration records cannot be deleted or changed'; END IF; "
            "IF TG_OP = 'DELETE' THEN RETURN OLD; END IF; RETURN NEW; END; $$ LANGUAGE plpgsql")


def downgrade() -> None:
    dialect = op.get_bind().dialect.name
    if dialect == "sqlite":
        op.execute("DROP TRIGGER IF EXISTS sensors_keep_history_update")
        op.execute("CREATE TRIGGER sensors_keep_history_update BEFORE UPDATE ON sensors "
                   "WHEN (NEW.id IS NOT OLD.id OR NEW.serial IS NOT OLD.serial OR NEW.kind IS NOT OLD.kind) "
                   f"AND {_HAS_HISTORY} "
                   "BEGIN SELECT RAISE(ABORT, 'a sensor with calibration records cannot be renamed'); END")
    elif dialect == "postgresql":
        op.execute(
            "CREATE OR REPLACE FUNCTION senscal_keep_history() RETURNS trigger AS $$ BEGIN "
            "IF (TG_OP = 'DELETE' OR NEW.id <> OLD.id OR NEW.serial <> OLD.serial OR NEW.kind <> OLD.kind) "
            f"AND {_HAS_HISTORY} THEN "
            "RAISE EXCEPTION 'a sensor with calibration records cannot be deleted or renamed'; END IF; "
            "IF TG_OP = 'DELETE' THEN RETURN OLD; END IF; RETURN NEW; END; $$ LANGUAGE plpgsql")
    with op.batch_alter_table("calibrations") as batch:
        batch.drop_column("sensor_digest")
