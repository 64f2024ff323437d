"""Shared test fixtures."""

from __future__ import annotations

import os
from dataclasses import dataclass

import pytest
from hypothesis import settings

# CI machines are shared and slow: no deadlines, fewer examples.
settings.register_profile("ci", deadline=None, max_examples=40)
settings.register_profile("dev", deadline=None, max_examples=60)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


@pytest.fixture(scope="session", autouse=True)
def private_user_dirs(tmp_path_factory):
    """The default registry and lab profile live in a private folder for the whole session.

    A test (or a command it runs, subprocesses included) that forgets ``--db`` must not write
    to the developer's own registry, and parallel workers must not share one SQLite file.
    """
    base = tmp_path_factory.mktemp("user-dirs")
    mp = pytest.MonkeyPatch()
    mp.setenv("XDG_DATA_HOME", str(base / "data"))
    mp.setenv("XDG_CONFIG_HOME", str(base / "config"))
    mp.delenv("SENSCAL_DB", raising=False)
    mp.delenv("SENSCAL_LAB", raising=False)
    yield base
    mp.undo()


@dataclass
class CliResult:
    code: int
    out: str
    err: str


@pytest.fixture
def cli(capsys):
    """Run the ``senscal`` command in-process: ``cli("fit", "x.csv", "--json")``."""
    from senscal.cli import main

    def run(*args: str) -> CliResult:
        capsys.readouterr()
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        cap = capsys.readouterr()
        return CliResult(code, cap.out, cap.err)

    return run


def pytest_report_header(config):
    """The versions a run resolved, so a failure on a fresh machine names the release that changed."""
    from importlib.metadata import PackageNotFoundError, version

    parts = []
    for dist in ("numpy", "scipy", "pandas", "numba", "typer", "click", "rich", "hypothesis", "weasyprint",
                 "xmlschema", "sqlalchemy", "dask"):
        try:
            parts.append(f"{dist} {version(dist)}")
        except PackageNotFoundError:
            parts.append(f"{dist} missing")
    return "senscal dependencies: " + ", ".join(parts)
