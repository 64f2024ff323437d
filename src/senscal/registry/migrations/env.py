"""Alembic environment of the senscal registry.

Migrations are run programmatically by :func:`senscal.registry.db.upgrade`,
which hands over an open connection (already inside the transaction that
holds the migration lock) in ``config.attributes["connection"]``.
"""

from __future__ import annotations

from alembic import context

connection = context.config.attributes.get("connection")
if connection is None:  # pragma: no cover - only reached from the alembic CLI
    raise RuntimeError("run senscal registry migrations through senscal.registry.open_registry()")

context.configure(connection=connection, target_metadata=None, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()
