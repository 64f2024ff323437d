"""Reference standards: their certificates and due dates, and which calibrations used them.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-26

* ``standards``: one row per certificate of a lab's reference standard
  (``ident`` is the lab's id of the standard, e.g. ``REF-8305``; a
  recalibration of the standard is a new row that supersedes the previous
  one, never an edit).  Each row carries ``chain_hash`` in a hash chain of
  its own (head in ``standards_chain``), the same construction as the
  calibrations' chain (:mod:`senscal.registry.standards`).
* ``calibration_standards``: which standard rows a calibration used.  The
  list (ident and the standard row's chain hash) is part of the
  calibration's hashed content, so a link cannot be removed or redirected
  without breaking the calibration chain.  Indexed by standard first: the
  impact report (``registry impact ID``) is a range scan of that index.
* Both back ends: all three tables are append-only like the calibrations
  (no UPDATE/DELETE, no SQLite REPLACE, no PostgreSQL TRUNCATE) except the
  one head row of ``standards_chain``.
"""
from typing import Sequence, Union

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: Union[str, Sequence[str], None] = "0003"
branch_labels: Union[str, Sequence[str], None] = None
depends_on: Union[str, Sequence[str], None] = None

_APPEND_ONLY = ("standards", "calibration_standards")
_SQLITE_KEYS = {
    "standards": "id = NEW.id OR uid = NEW.uid",
    "calibration_standards": "id = NEW.id OR (calibration_id = NEW.calibration_id AND standard_id = NEW.standard_id)",
}


def upgrade() -> None:
    dialect = op.get_bind().dialect.name
    op.create_table(
        "standards",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("uid", sa.String(36), nullable=False, unique=True),
        sa.Column("ident", sa.String(200), nullable=False, index=True),
        sa.Column("name", sa.String(200)),
        sa.Column("serial", sa.String(200)),
        sa.Column("certificate", sa.Text, nullable=False),
        sa.Column("certificate_sha256", sa.String(64)),
        sa.Column("traceability", sa.Text),
        sa.Column("due", sa.Date, nullable=False),
        sa.Column("u_relative", sa.Double, nullable=False),
        sa.Column("recorded_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("operator", sa.String(200)),
        sa.Column("note", sa.Text),
        sa.Column("supersedes", sa.String(36), sa.ForeignKey("standards.uid"), index=True),
        sa.Column("chain_hash", sa.String(64), nullable=False),
    )
    op.create_table(
        "standards_chain",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("n_records", sa.Integer, nullable=False),
        sa.Column("head", sa.String(64), nullable=False),
        sa.CheckConstraint("id = 1", name="ck_standards_chain_one_row"),
    )
    op.create_table(
        "calibration_standards",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id"), nullable=False, index=True),
        sa.Column("standard_id", sa.Integer, sa.ForeignKey("standards.id"), nullable=False),
        sa.UniqueConstraint("calibration_id", "standard_id", name="uq_standard_per_calibration"),
    )
    # The impact report reads every calibration of one standard: standard first, calibration second.
    op.create_index("ix_calibration_standards_standard", "calibration_standards", ["standard_id", "calibration_id"])
    if dialect == "sqlite":
        for table in _APPEND_ONLY:
            for action in ("UPDATE", "DELETE"):
                op.execute(f"CREATE TRIGGER {table}_no_{action.lower()} BEFORE {action} ON {table} "
                           f"BEGIN SELECT RAISE(ABORT, '{table} are append-only'); END")
        for table, key in _SQLITE_KEYS.items():
            op.execute(f"CREATE TRIGGER {table}_no_replace BEFORE INSERT ON {table} "
                       f"WHEN EXISTS (SELECT 1 FROM {table} WHERE {key}) "
                       f"BEGIN SELECT RAISE(ABORT, '{table}: key exists; records are never replaced'); END")
    elif dialect == "postgresql":
        for table in _APPEND_ONLY:
            op.execute(f"CREATE TRIGGER {table}_append_only BEFORE UPDATE OR DELETE ON {table} "
                       "FOR EACH ROW EXECUTE FUNCTION senscal_append_only()")
            op.execute(f"CREATE TRIGGER {table}_no_truncate BEFORE TRUNCATE ON {table} "
                       "FOR EACH STATEMENT EXECUTE FUNCTION senscal_append_only()")


def downgrade() -> None:
    dialect = op.get_bind().dialect.name
    for table in _APPEND_ONLY:
        if dialect == "sqlite":
            for name in ("no_update", "no_delete", "no_replace"):
                op.execute(f"DROP TRIGGER IF EXISTS {table}_{name}")
        elif dialect == "postgresql":
            op.execute(f"DROP TRIGGER IF EXISTS {table}_append_only ON {table}")
            op.execute(f"DROP TRIGGER IF EXISTS {table}_no_truncate ON {table}")
    op.drop_index("ix_calibration_standards_standard", "calibration_standards")
    op.drop_table("calibration_standards")
    op.drop_table("standards_chain")
    op.drop_table("standards")
