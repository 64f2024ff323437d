"""Every shell and Python block of README.md and docs/*.md runs as written.

Blocks of one page run in order in one fresh folder (later blocks use what
earlier ones made: ``senscal simulate ... --out data`` then ``senscal fit
data/sine.csv``), with a private registry (``SENSCAL_DB``) and Matplotlib's
Agg backend.  A block that cannot run as is (it installs the package, or
names a cluster or a file the reader brings) is marked by the line
``<!-- docs-test: skip (reason) -->`` just above its fence; the reason is
required so a skipped block is a decision, not an accident.  A page with no
runnable block at all is listed in ``NO_RUNNABLE`` with its reason, so a page
that loses its last block by accident fails instead of being skipped.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w+)?\s*$")
SKIP = re.compile(r"<!--\s*docs-test:\s*skip\s*\((.+)\)\s*-->")
RUNNABLE = {"bash", "sh", "shell", "python", "console"}
# Pages that show no runnable block on purpose, and why.
NO_RUNNABLE = {
    "uncertainty.md": "reference tables of measured coverage; the Monte-Carlo runs behind them are "
                      "tests/*/test_coverage_*.py (mc_seeds) and benchmarks/bench_coverage.py",
}


def console_commands(code: str) -> str:
    """The commands of a ``console`` block: ``$ `` lines and their ``\\`` continuations."""
    cmds, cont = [], False
    for ln in code.splitlines():
        if ln.startswith("$ ") or cont:
            body = ln[2:] if ln.startswith("$ ") and not cont else ln
            cmds.append(body)
            cont = body.rstrip().endswith("\\")
    return "\n".join(cmds)


def blocks(page: Path) -> list[tuple[int, str, str, str | None]]:
    """(line, language, code, skip-reason) of every fenced block of a page."""
    out = []
    lines = page.read_text(encoding="utf-8").splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m and m.group(1):
            lang = m.group(1)
            start = i
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            prev = next((lines[k] for k in range(start - 1, -1, -1) if lines[k].strip()), "")
            sk = SKIP.search(prev)
            out.append((start + 1, lang, "\n".join(lines[start + 1:j]), sk.group(1) if sk else None))
            i = j + 1
        else:
            i += 1
    return out


def runnable_blocks(page: Path) -> list[tuple[int, str, str, str | None]]:
    return [b for b in blocks(page) if b[1] in RUNNABLE and b[3] is None]


RUN_PAGES = [p for p in PAGES if runnable_blocks(p)]


def _senscal_cmd() -> str:
    # The console script of the interpreter running the tests, not the first `senscal` on PATH
    # (a pyenv shim there costs a few hundred ms per command and may pick another interpreter).
    exe = Path(sys.executable).with_name("senscal")
    return shlex.quote(str(exe)) if exe.is_file() else f"{shlex.quote(sys.executable)} -m senscal"


def test_every_page_is_considered():
    names = {p.name for p in PAGES}
    assert {p.name for p in (ROOT / "docs").glob("*.md")} <= names
    assert set(NO_RUNNABLE) <= names, f"NO_RUNNABLE names a page that does not exist: {set(NO_RUNNABLE) - names}"
    for page in PAGES:
        if page in RUN_PAGES:
            assert page.name not in NO_RUNNABLE, f"{page.name} now has runnable blocks: remove it from NO_RUNNABLE"
        else:
            assert page.name in NO_RUNNABLE, (
                f"{page.name} has no runnable block; add one, or list the page in NO_RUNNABLE with the reason")


@pytest.mark.parametrize("page", RUN_PAGES, ids=[p.name for p in RUN_PAGES])
def test_page_blocks_run(page: Path, tmp_path: Path):
    runnable = runnable_blocks(page)
    env = dict(os.environ, SENSCAL_DB=str(tmp_path / "registry.sqlite"), MPLBACKEND="Agg",
               PYTHONPATH=str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    shim = tmp_path / "_bin"
    shim.mkdir()
    # The blocks say `senscal ...` and `python3 ...`; run this checkout's senscal and the interpreter
    # of the tests, whatever is first on PATH.
    # (Scripts, not symlinks: a virtual environment's python finds its pyvenv.cfg from its own path.)
    for name, cmd in (("senscal", _senscal_cmd()), ("python3", shlex.quote(sys.executable)),
                      ("python", shlex.quote(sys.executable))):
        (shim / name).write_text(f"#!/bin/sh\nexec {cmd} \"$@\"\n")
        (shim / name).chmod(0o755)
    env["PATH"] = f"{shim}{os.pathsep}{env['PATH']}"
    for line, lang, code, _ in runnable:
        if lang == "python":
            cmd = [sys.executable, "-c", code]
        else:
            cmd = ["bash", "-euo", "pipefail", "-c", console_commands(code) if lang == "console" else code]
        proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, (
            f"{page.name}:{line} ({lang}) exited {proc.returncode}\n--- code\n{code}\n--- stderr\n{proc.stderr[-3000:]}")


def test_skips_carry_a_reason():
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for m in re.finditer(r"<!--\s*docs-test:[^>]*-->", text):
            assert SKIP.search(m.group(0)), f"{page.name}: malformed docs-test marker {m.group(0)!r}"
