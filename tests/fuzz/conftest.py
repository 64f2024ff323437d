"""Fuzz suite fixtures: the corpus (built once per session) and the outcome table printed at the end."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

# --import-mode=importlib puts nothing on sys.path; the harness module sits beside this file.
sys.path.insert(0, str(Path(__file__).parent))

from _fuzz_harness import TALLY, build_corpus, dump_summary  # noqa: E402


@pytest.fixture(scope="session")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz_corpus")
    return {t.command: t for t in build_corpus(d)}


def pytest_terminal_summary(terminalreporter):
    if TALLY.counts:
        terminalreporter.write_sep("-", "fuzz outcomes (cases per command)")
        terminalreporter.write_line(TALLY.table())
        dump_summary(TALLY, os.environ.get("SENSCAL_FUZZ_REPORT"))
