"""Fixtures of the registry tests: one empty registry per test on each back end.

SQLite always; PostgreSQL when ``SENSCAL_TEST_PG_URL`` is set (``.ci/services``
starts a server and sets it). In CI (``CI=true``) a missing PostgreSQL URL is
a failure, not a skip: the issue requires both back ends to be tested.
"""

from __future__ import annotations

import os
import uuid

import pytest


def _pg_url_or_fail() -> str:
    url = os.environ.get("SENSCAL_TEST_PG_URL")
    if not url:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail("SENSCAL_TEST_PG_URL is not set although CI=true: .ci/services must start PostgreSQL "
                        "for the registry tests")
        pytest.skip("PostgreSQL registry tests need SENSCAL_TEST_PG_URL (run: source .ci/services)")
    return url


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request, tmp_path):
    """URL of an empty registry database (a fresh PostgreSQL schema per test)."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'registry.sqlite'}"
        return
    import sqlalchemy as sa
    from sqlalchemy.engine import make_url

    base = make_url(_pg_url_or_fail())
    schema = f"t_{uuid.uuid4().hex[:12]}"
    admin = sa.create_engine(base)
    with admin.begin() as conn:
        conn.execute(sa.text(f"CREATE SCHEMA {schema}"))
    url = base.update_query_dict({"options": f"-csearch_path={schema}"})
    try:
        yield url.render_as_string(hide_password=False)
    finally:
        with admin.begin() as conn:
            conn.execute(sa.text(f"DROP SCHEMA {schema} CASCADE"))
        admin.dispose()


@pytest.fixture
def pg_url():
    """The PostgreSQL server URL itself (for error-message tests)."""
    return _pg_url_or_fail()
