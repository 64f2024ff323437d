"""Database plumbing of the registry: URLs, engines, schema, migrations.

The default registry is one SQLite file in the user's data folder (or the
URL/path in ``$SENSCAL_DB``), in WAL mode so readers never block the writer.
Any SQLAlchemy URL works (``postgresql://user:pw@host/db`` for a lab's shared
server). Credentials never appear in messages: every URL shown to a person
goes through :func:`mask_url`.
"""

from __future__ import annotations

import os
import re
import sys
from datetime import datetime, timezone
from functools import lru_cache
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.engine import URL, Engine, make_url
from sqlalchemy.exc import ArgumentError, DBAPIError, NoSuchModuleError

from senscal.errors import InputError
from senscal.io.guard import note_input

__all__ = ["default_url", "parse_url", "mask_url", "missing_registry_file", "create_registry_engine", "upgrade", "metadata",
           "sensors", "calibrations", "quantities", "registry_chain", "standards", "calibration_standards",
           "standards_chain", "UTC"]

UTC = timezone.utc
MIGRATIONS = Path(__file__).with_name("migrations")
_PG_LOCK_KEY = 0x5E25CA1  # advisory lock that serialises concurrent schema upgrades
PG_APPEND_LOCK_KEY = 0x5E25CA2  # advisory lock that serialises appends to the hash chain


def default_url() -> str:
    """The registry used when no ``--db`` is given.

    ``$SENSCAL_DB`` (a SQLAlchemy URL or a file path) if set, else
    ``registry.sqlite`` in the user's data folder (``$XDG_DATA_HOME/senscal``,
    ``~/.local/share/senscal``; ``%LOCALAPPDATA%\\senscal`` on Windows,
    ``~/Library/Application Support/senscal`` on macOS).
    """
    env = os.environ.get("SENSCAL_DB")
    if env:
        return env
    if sys.platform.startswith("win"):
        base = Path(os.environ.get("LOCALAPPDATA", Path.home() / "AppData" / "Local"))
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Application Support"
    else:
        base = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    return f"sqlite:///{base / 'senscal' / 'registry.sqlite'}"


_PASSWORD_IN_TEXT = re.compile(r"(://[^:/@\s]*:)([^@\s]*)(@)")


def mask_url(url: str | URL) -> str:
    """The URL with its password replaced by ``***`` (safe to print or log)."""
    if isinstance(url, URL):
        return url.render_as_string(hide_password=True)
    return _PASSWORD_IN_TEXT.sub(r"\1***\3", str(url))


def _scrub(text: str, url: URL) -> str:
    """Remove the password of ``url`` from a driver's message (first line only)."""
    line = str(text).strip().splitlines()[0] if str(text).strip() else "no detail given"
    if url.password:
        line = line.replace(str(url.password), "***")
    return mask_url(line)


def parse_url(url: str | Path | None) -> URL:
    """Turn ``--db`` (URL, file path or None for the default) into a SQLAlchemy URL.

    Raises
    ------
    InputError
        The text is neither a SQLAlchemy URL nor a usable path.
    """
    text = default_url() if url is None else str(url)
    if not text.strip():
        raise InputError("empty database URL; give a SQLAlchemy URL such as sqlite:///registry.sqlite "
                         "or postgresql://user@host/db, or a file path")
    if "://" not in text:
        # A bare path is the friendly spelling of a SQLite file.
        return make_url(f"sqlite:///{Path(text).expanduser()}")
    try:
        u = make_url(text)
    except (ArgumentError, ValueError):
        raise InputError(f"malformed database URL {mask_url(text)!r}; expected dialect[+driver]://user:password@host:port/"
                         "database (e.g. postgresql://lab@db.example/senscal) or sqlite:///path/to/file.sqlite") from None
    if u.drivername == "postgresql":
        # psycopg (v3) is the driver senscal installs; SQLAlchemy's default is psycopg2.
        u = u.set(drivername="postgresql+psycopg")
    return u


def missing_registry_file(url: str | Path | None) -> Path | None:
    """The SQLite file an explicitly named registry would create, or None if it exists.

    ``None`` (the default registry: ``$SENSCAL_DB`` or the user data
    folder), server URLs and in-memory databases never count as missing:
    the default is created on first use.  A named file that does not exist
    is most often a typo, which would otherwise open an empty registry; the
    command line refuses it unless asked to create it (``--create``).
    """
    if url is None:
        return None
    u = url if isinstance(url, URL) else parse_url(url)
    if u.get_backend_name() != "sqlite":
        return None
    db = u.database
    if not db or db == ":memory:" or db.startswith("file:"):
        return None
    path = Path(db)
    return None if path.exists() else path


def _sqlite_pragmas(dbapi_conn, _record) -> None:
    # Autocommit at the driver level so that SQLAlchemy's "begin" hook below
    # decides how transactions start.
    dbapi_conn.isolation_level = None
    cur = dbapi_conn.cursor()
    cur.execute("PRAGMA busy_timeout = 60000")
    cur.execute("PRAGMA journal_mode = WAL")
    cur.execute("PRAGMA foreign_keys = ON")
    cur.execute("PRAGMA synchronous = NORMAL")
    cur.close()


def _sqlite_begin(conn) -> None:
    # Writers: BEGIN IMMEDIATE takes the write lock up front, so two writers
    # queue on the busy timeout instead of deadlocking when both upgrade a
    # read lock. Readers (marked by read_connection) take a plain snapshot and
    # never block a writer in WAL mode.
    conn.exec_driver_sql("BEGIN" if conn.get_execution_options().get("senscal_read") else "BEGIN IMMEDIATE")


def read_connection(engine: Engine):
    """A connection for reading only (on SQLite it does not take the write lock)."""
    return engine.connect().execution_options(senscal_read=True)


def create_registry_engine(url: str | Path | URL | None = None) -> Engine:
    """Create an engine for the registry at ``url`` and check it answers.

    Raises
    ------
    InputError
        Malformed URL, missing driver, or a server/file that cannot be reached.
    """
    u = url if isinstance(url, URL) else parse_url(url)
    kwargs: dict = {}
    if u.get_backend_name() == "sqlite":
        db = u.database
        if db and db != ":memory:" and not db.startswith("file:"):
            path = Path(db)
            if not path.parent.is_dir():
                if db == parse_url(None).database:
                    # The default registry ($SENSCAL_DB or the user data folder) is made on first use.
                    try:
                        path.parent.mkdir(parents=True, exist_ok=True)
                    except OSError as exc:
                        raise InputError(f"cannot create the folder of the registry {path}: {exc.strerror}") from None
                else:
                    # A named --db in a missing folder is a typo unless --mkdir (senscal.io.guard); API use creates it.
                    from senscal.io.guard import make_parent_folder

                    make_parent_folder(path, "registry")
            # The database file is an input: no output of the command may overwrite it.
            note_input(path)
        kwargs["connect_args"] = {"timeout": 60}
    elif u.get_backend_name() == "postgresql":
        kwargs["connect_args"] = {"connect_timeout": 10}
    try:
        engine = sa.create_engine(u, **kwargs)
    except NoSuchModuleError:
        raise InputError(f"unknown database dialect or driver in {mask_url(u)!r}; use sqlite:///FILE or "
                         "postgresql://user@host/db") from None
    except (ImportError, ArgumentError) as exc:
        raise InputError(f"cannot use database URL {mask_url(u)!r}: {_scrub(exc, u)}") from None
    if u.get_backend_name() == "sqlite":
        event.listen(engine, "connect", _sqlite_pragmas)
        event.listen(engine, "begin", _sqlite_begin)
    try:
        with engine.connect():
            pass
    except DBAPIError as exc:
        engine.dispose()
        raise InputError(f"cannot reach the registry database {mask_url(u)!r}: {_scrub(exc.orig, u)}") from None
    return engine


# --- schema used by the queries (the migrations own the DDL) ---------------

class UTCDateTime(sa.types.TypeDecorator):
    """Timezone-aware datetimes stored as UTC on every back end.

    SQLite has no timezone type, so values are normalised to UTC before
    storage and marked UTC again when read.
    """

    impl = sa.DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value, dialect):
        if value is None:
            return None
        if value.tzinfo is None:
            raise InputError("internal: naive datetime given to the registry")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value, dialect):
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=UTC)
        return value.astimezone(UTC)


metadata = sa.MetaData()

sensors = sa.Table(
    "sensors", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("serial", sa.String(200), nullable=False, unique=True),
    sa.Column("kind", sa.String(200), nullable=False),
    sa.Column("model", sa.String(200)),
    sa.Column("manufacturer", sa.String(200)),
    sa.Column("nominal", sa.JSON),
    sa.Column("notes", sa.Text),
    sa.Column("created_at", UTCDateTime, nullable=False),
)

calibrations = sa.Table(
    "calibrations", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("uid", sa.String(36), nullable=False, unique=True),
    sa.Column("sensor_id", sa.Integer, sa.ForeignKey("sensors.id"), nullable=False),
    sa.Column("performed_at", UTCDateTime, nullable=False),
    sa.Column("utc_offset_s", sa.Integer, nullable=False),
    sa.Column("recorded_at", UTCDateTime, nullable=False),
    sa.Column("job", sa.String(100), nullable=False),
    sa.Column("method", sa.String(200)),
    sa.Column("conditions", sa.JSON),
    sa.Column("result", sa.JSON),
    sa.Column("certificate", sa.Text),
    sa.Column("input_files", sa.JSON),
    sa.Column("senscal_version", sa.String(50)),
    sa.Column("operator", sa.String(200)),
    sa.Column("note", sa.Text),
    sa.Column("supersedes", sa.String(36), sa.ForeignKey("calibrations.uid")),
    # sha256(previous record's chain_hash || canonical content): see senscal.registry.chain.
    sa.Column("chain_hash", sa.String(64)),
    # SHA-256 of the sensor's metadata when the record was made (schema 0003; None before): see chain.sensor_digest.
    sa.Column("sensor_digest", sa.String(64)),
)

quantities = sa.Table(
    "quantities", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id"), nullable=False),
    sa.Column("name", sa.String(200), nullable=False),
    sa.Column("value", sa.Double, nullable=False),
    sa.Column("uncertainty", sa.Double, nullable=False),
    sa.Column("unit", sa.String(50), nullable=False),
    sa.Column("k", sa.Double, nullable=False),
)

# Reference standards (schema 0004): one row per certificate of a standard; a recalibration supersedes.
standards = sa.Table(
    "standards", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("uid", sa.String(36), nullable=False, unique=True),
    # The lab's id of the standard (e.g. "REF-8305"): the same for every certificate of it.
    sa.Column("ident", sa.String(200), nullable=False),
    sa.Column("name", sa.String(200)),
    sa.Column("serial", sa.String(200)),
    sa.Column("certificate", sa.Text, nullable=False),
    sa.Column("certificate_sha256", sa.String(64)),
    sa.Column("traceability", sa.Text),
    sa.Column("due", sa.Date, nullable=False),
    sa.Column("u_relative", sa.Double, nullable=False),
    sa.Column("recorded_at", UTCDateTime, nullable=False),
    sa.Column("operator", sa.String(200)),
    sa.Column("note", sa.Text),
    sa.Column("supersedes", sa.String(36), sa.ForeignKey("standards.uid")),
    # sha256(previous standard's chain_hash || canonical content): see senscal.registry.standards.
    sa.Column("chain_hash", sa.String(64), nullable=False),
)

# Which standard rows (a certificate of a standard) each calibration used (schema 0004).
calibration_standards = sa.Table(
    "calibration_standards", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("calibration_id", sa.Integer, sa.ForeignKey("calibrations.id"), nullable=False),
    sa.Column("standard_id", sa.Integer, sa.ForeignKey("standards.id"), nullable=False),
)

# One row (id = 1): number of standard rows and the newest hash of their chain (schema 0004).
standards_chain = sa.Table(
    "standards_chain", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("n_records", sa.Integer, nullable=False),
    sa.Column("head", sa.String(64), nullable=False),
)

# One row (id = 1): number of records and the newest chain hash.
registry_chain = sa.Table(
    "registry_chain", metadata,
    sa.Column("id", sa.Integer, primary_key=True),
    sa.Column("n_records", sa.Integer, nullable=False),
    sa.Column("head", sa.String(64), nullable=False),
)


# --- migrations --------------------------------------------------------------

def _alembic_config(connection=None):
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS))
    if connection is not None:
        cfg.attributes["connection"] = connection
    return cfg


# The newest schema revision this senscal ships. Opening a registry already at
# it must not import alembic (~1-2 s of a CLI call); a test checks that this
# equals alembic's ScriptDirectory head, so a new migration cannot be
# forgotten here.
HEAD_REVISION = "0004"


@lru_cache(maxsize=1)
def head_revision() -> str:
    """The newest schema revision shipped with this senscal, as alembic computes it."""
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(_alembic_config()).get_current_head()


def current_revision(engine: Engine) -> str | None:
    """The schema revision of the database (None for an empty database).

    Read straight from alembic's ``alembic_version`` table, without importing
    alembic. Several rows (branched histories, which senscal never makes) are
    reported as ``"a+b"`` so they never compare equal to the head.
    """
    with read_connection(engine) as conn:
        if not sa.inspect(conn).has_table("alembic_version"):
            conn.rollback()
            return None
        rows = sorted(r[0] for r in conn.execute(sa.text("SELECT version_num FROM alembic_version")))
        conn.rollback()
    if any(not isinstance(r, str) or not r.strip() or not r.isprintable() for r in rows):
        # alembic asserts on an empty revision; senscal never writes one.
        raise InputError(f"the registry {mask_url(engine.url)} has a damaged schema revision {rows!r} (table "
                         "alembic_version); restore the database from a backup or an export")
    return "+".join(rows) if rows else None


def upgrade(engine: Engine) -> None:
    """Bring the database schema to the newest revision (idempotent, concurrency-safe).

    A database already at :data:`HEAD_REVISION` is left alone after one cheap
    read of ``alembic_version``; alembic is imported and run only for a new
    or older database (or one at a revision this senscal does not know).
    Several processes may open a fresh registry at once: the upgrade runs in
    one transaction that first takes a lock (SQLite: ``BEGIN IMMEDIATE``;
    PostgreSQL: a transaction-scoped advisory lock), so exactly one of them
    creates the schema and the others find it at head.
    """
    current = current_revision(engine)
    if current == HEAD_REVISION:
        return
    from alembic import command
    from alembic.util import CommandError

    try:
        with engine.begin() as conn:
            if conn.dialect.name == "postgresql":
                conn.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": _PG_LOCK_KEY})
            command.upgrade(_alembic_config(conn), "head")
    except CommandError:
        raise InputError(f"the registry {mask_url(engine.url)} has schema revision {current!r}, which this "
                         f"senscal does not know (newest: {head_revision()!r}); upgrade senscal") from None


def now_utc() -> datetime:
    return datetime.now(UTC)
