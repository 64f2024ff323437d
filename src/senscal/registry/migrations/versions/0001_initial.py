"""Initial registry schema: sensors, append-only calibrations, quantities.

Revision ID: 0001
Revises:
Create Date: 2026-11-21

"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = "0001"
down_revision: Union[str, Sequence[str], None] = None
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

_APPEND_ONLY = ("calibrations", "quantities")


def upgrade() -> None:
    op.create_table(
        "sensors",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("serial", sa.String(200), nullable=False, unique=True),
        sa.Column("kind", sa.String(200), nullable=False),
        sa.Column("model", sa.String(200)),
        sa.Column("manufacturer", sa.String(200)),
        sa.Column("nominal", sa.JSON),
        sa.Column("notes", sa.Text),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_table(
        "calibrations",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("uid", sa.String(36), nullable=False, unique=True),
        sa.Column("sensor_id", sa.Integer, sa.ForeignKey("sensors.id"), nullable=False, index=True),
        sa.Column("performed_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("utc_offset_s", sa.Integer, nullable=False),
        sa.Column("recorded_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("job", sa.String(100), nullable=False),
        sa.Column("method", sa.String(200)),
        sa.Column("conditions", sa.JSON),
        sa.Column("result", sa.JSON),
        sa.Column("certificate", sa.Text),
        sa.Column("input_files", sa.JSON),
        sa.Column("senscal_version", sa.String(50)),
        sa.Column("operator", sa.String(200)),
        sa.Column("note", sa.Text),
        sa.Column("supersedes", sa.String(36), sa.ForeignKey("calibrations.uid"), index=True),
    )
    op.create_table(
        "quantities",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id"), nullable=False, index=True),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("value", sa.Double, nullable=False),
        sa.Column("uncertainty", sa.Double, nullable=False),
        sa.Column("unit", sa.String(50), nullable=False),
        sa.Column("k", sa.Double, nullable=False),
        sa.UniqueConstraint("calibration_id", "name", name="uq_quantity_per_calibration"),
    )
    # Records are evidence: corrections are new records that supersede old
    # ones, so the database itself refuses edits and deletions.
    dialect = op.get_bind().dialect.name
    if dialect == "sqlite":
        for table in _APPEND_ONLY:
            for action in ("UPDATE", "DELETE"):
                op.execute(
                    f"CREATE TRIGGER {table}_no_{action.lower()} BEFORE {action} ON {table} "
                    f"BEGIN SELECT RAISE(ABORT, '{table} are append-only'); END"
                )
    elif dialect == "postgresql":
        op.execute(
            "CREATE FUNCTION senscal_append_only() RETURNS trigger AS $$ BEGIN "
            "RAISE EXCEPTION '% are append-only', TG_TABLE_NAME; END; $$ LANGUAGE plpgsql"
        )
        for table in _APPEND_ONLY:
            op.execute(
                f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                "FOR EACH ROW EXECUTE FUNCTION senscal_append_only()"
            )


def downgrade() -> None:
    dialect = op.get_bind().dialect.name
    for table in reversed(_APPEND_ONLY):
        if dialect == "sqlite":
            op.execute(f"DROP TRIGGER IF EXISTS {table}_no_update")
            op.execute(f"DROP TRIGGER IF EXISTS {table}_no_delete")
    op.drop_table("quantities")
    op.drop_table("calibrations")
    op.drop_table("sensors")
    if dialect == "postgresql":
        op.execute("DROP FUNCTION IF EXISTS senscal_append_only()")
