"""Every shell and Python block of README.md and docs/*.md runs as written.

Blocks of one page run in order in one fresh folder (later blocks use what
earlier ones made: ``senscal simulate ... --out data`` then ``senscal fit
data/sine.csv``), with a private registry (``SENSCAL_DB``) and Matplotlib's
Agg backend.  A block that cannot run as is (it installs the package, or
names a cluster or a file the reader brings) is marked by the line
``<!-- docs-test: skip (reason) -->`` just above its fence; the reason is
required so a skipped block is a decision, not an accident.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w+)?\s*$")
SKIP = re.compile(r"<!--\s*docs-test:\s*skip\s*\((.+)\)\s*-->")
RUNNABLE = {"bash", "sh", "shell", "python", "console"}


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


def _senscal_cmd() -> str:
    exe = shutil.which("senscal")
    return exe if exe else f"{sys.executable} -m senscal"


@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_page_blocks_run(page: Path, tmp_path: Path):
    runnable = [b for b in blocks(page) if b[1] in RUNNABLE and b[3] is None]
    if not runnable:
        pytest.skip(f"{page.name} has no runnable block")
    env = dict(os.environ, SENSCAL_DB=str(tmp_path / "registry.sqlite"), MPLBACKEND="Agg",
               PYTHONPATH=str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    shim = tmp_path / "_bin"
    shim.mkdir()
    # The blocks say `senscal ...`; run this checkout's senscal whether or not it is on PATH.
    (shim / "senscal").write_text(f"#!/bin/sh\nexec {_senscal_cmd()} \"$@\"\n")
    (shim / "senscal").chmod(0o755)
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
