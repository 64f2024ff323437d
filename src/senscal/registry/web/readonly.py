"""A registry opened for reading only: the database of ``senscal registry serve``.

:class:`senscal.registry.Registry` creates or upgrades the schema when it
opens a database, which is a write.  The web view never writes: it opens
SQLite files with ``mode=ro`` (and ``PRAGMA query_only``), PostgreSQL
sessions with ``default_transaction_read_only``, refuses a database whose
schema is not the one this senscal ships (an older one would have to be
upgraded first, which is a write the user runs on purpose), and reads through
the same query methods as every ``senscal registry`` command.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.exc import DBAPIError

from senscal.errors import InputError
from senscal.registry import db
from senscal.registry.store import Registry, _refuse_short_file

__all__ = ["ReadOnlyRegistry", "open_read_only"]


def _sqlite_read_only_pragmas(dbapi_conn, _record) -> None:
    dbapi_conn.isolation_level = None
    cur = dbapi_conn.cursor()
    cur.execute("PRAGMA busy_timeout = 60000")
    # A second lock besides mode=ro: any statement that would write fails.
    cur.execute("PRAGMA query_only = ON")
    cur.close()


def _sqlite_begin_deferred(conn) -> None:
    # A plain BEGIN is a read snapshot; BEGIN IMMEDIATE (the writers' form) would need the write lock.
    conn.exec_driver_sql("BEGIN")


def _pg_read_only(dbapi_conn, _record) -> None:
    cur = dbapi_conn.cursor()
    cur.execute("SET SESSION CHARACTERISTICS AS TRANSACTION READ ONLY")
    cur.close()
    dbapi_conn.commit()


def _read_only_engine(url: sa.engine.URL) -> sa.engine.Engine:
    if url.get_backend_name() == "sqlite":
        path = Path(url.database).resolve()
        # file: URI with mode=ro: SQLite itself refuses every write. Path.as_uri() escapes '?', '#' and '%'.
        uri = f"{path.as_uri()}?mode=ro"

        def connect():
            return sqlite3.connect(uri, uri=True, timeout=60, check_same_thread=False)

        # "sqlite://" only names the dialect; the creator opens the file. QueuePool: one connection per
        # request thread of the web server, reused.
        engine = sa.create_engine("sqlite://", creator=connect, poolclass=sa.pool.QueuePool)
        event.listen(engine, "connect", _sqlite_read_only_pragmas)
        event.listen(engine, "begin", _sqlite_begin_deferred)
        try:
            with engine.connect():
                pass
        except DBAPIError as exc:
            engine.dispose()
            raise InputError(f"cannot open the registry {path} for reading: {db._scrub(exc.orig, url)}") from None
        return engine
    engine = db.create_registry_engine(url)
    # The connection create_registry_engine opened to check the server is pooled without the setting below.
    engine.dispose()
    if url.get_backend_name() == "postgresql":
        event.listen(engine, "connect", _pg_read_only)
    return engine


class ReadOnlyRegistry(Registry):
    """A :class:`~senscal.registry.Registry` that never writes (see the module docstring).

    Parameters
    ----------
    url : str, Path or None
        As :class:`~senscal.registry.Registry`; an SQLite file must exist.

    Raises
    ------
    InputError
        A missing or empty file, a database without a senscal registry, or
        one at another schema revision than this senscal's.
    """

    def __init__(self, url: str | Path | None = None):  # noqa: D107 - documented on the class
        self._url = db.parse_url(url)
        u = self._url
        if u.get_backend_name() == "sqlite":
            if not u.database or u.database == ":memory:" or u.database.startswith("file:"):
                raise InputError(f"the web view reads a registry file or server; {self.url} is not one "
                                 "(give --db FILE.sqlite or a postgresql:// URL)")
            if Path(u.database).is_dir():
                raise InputError(f"--db {u.database} is a folder; give the registry file in it (e.g. "
                                 f"{Path(u.database) / 'registry.sqlite'})")
            if not Path(u.database).is_file():
                raise InputError(f"registry file {u.database} does not exist; check the --db path (the web view "
                                 "only reads: it never creates a registry)")
            _refuse_short_file(u, "a path to a registry made by 'senscal registry add' or '--save'")
        self.engine = _read_only_engine(u)
        try:
            rev = db.current_revision(self.engine)
        except DBAPIError as exc:
            self.engine.dispose()
            raise InputError(f"cannot read the registry {self.url}: {db._scrub(exc.orig, u)}") from None
        except Exception:
            self.engine.dispose()
            raise
        if rev is None:
            self.engine.dispose()
            raise InputError(f"{self.url} holds no senscal registry (an empty file or another database); "
                             "check the --db path")
        if rev != db.HEAD_REVISION:
            self.engine.dispose()
            older = rev < db.HEAD_REVISION
            raise InputError(
                f"the registry {self.url} has schema revision {rev!r}, this senscal reads {db.HEAD_REVISION!r}; "
                + ("bring it up to date first with 'senscal registry verify --db URL' (that writes the schema "
                   "upgrade; the web view never writes)" if older else "upgrade senscal"))


def open_read_only(url: str | Path | None = None) -> ReadOnlyRegistry:
    """Open the registry at ``url`` for reading only (see :class:`ReadOnlyRegistry`)."""
    return ReadOnlyRegistry(url)
