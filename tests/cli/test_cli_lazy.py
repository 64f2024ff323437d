"""The command line loads a command's module only when that command runs."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import pytest

from senscal.cli import _manifest
from senscal.cli._manifest_data import COMMANDS, SIMULATORS

HEAVY = ("numba", "dask", "distributed", "scipy.stats", "pandas", "matplotlib")


def test_manifest_matches_the_code():
    commands, simulators = _manifest.build()
    assert commands == COMMANDS and simulators == SIMULATORS, (
        "the command table is stale: run python -m senscal.cli._manifest > src/senscal/cli/_manifest_data.py")


def _loaded_after(args: list[str], watch: tuple[str, ...] = HEAVY) -> tuple[int, set[str], str]:
    """Exit code, which of ``watch`` were imported, and stdout of ``senscal ARGS`` in a fresh interpreter."""
    code = textwrap.dedent(f"""
        import sys
        from senscal.cli import main
        try:
            main({args!r})
        except SystemExit as exc:
            code = exc.code
        print("LOADED", " ".join(m for m in {watch!r} if m in sys.modules), "CODE", code)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("LOADED")][-1]
    loaded, rc = line[len("LOADED"):].split("CODE")
    return int(rc), set(loaded.split()), out.stdout


@pytest.mark.parametrize("args", [["--help"], ["simulate", "--help"], ["registry", "--help"]])
def test_help_imports_no_heavy_library(args):
    rc, loaded, out = _loaded_after(args)
    assert rc == 0
    assert not loaded & {"numba", "dask", "distributed", "scipy.stats"}, loaded
    if args == ["--help"]:
        # every command is listed with its help, none imported
        for name in COMMANDS:
            assert name in out


def test_a_command_runs_and_unknown_is_one_line(cli, tmp_path):
    r = cli("simulate", "sine", "--out", tmp_path, "--seed", "1")
    assert r.code == 0, r.err
    r = cli("fit", tmp_path / "sine.csv", "--freq", "12.5", "--json")
    assert r.code == 0 and '"channels"' in r.out
    r = cli("fitt", "x")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "fitt" in r.err


def test_version(cli):
    from senscal import __version__

    r = cli("--version")
    assert r.code == 0 and r.out.strip() == f"senscal {__version__}"


# What start-up must not pay for: help is plain Click text (no Rich), values convert without pydantic.
STARTUP = ("pydantic", "rich", "numpy", "pandas")


@pytest.mark.parametrize("args", [["--help"], ["fit", "--help"], ["registry", "--help"]])
def test_help_imports_neither_pydantic_nor_rich_nor_numpy(args):
    rc, loaded, out = _loaded_after(args, STARTUP)
    assert rc == 0 and "Usage: senscal" in out
    assert not loaded, loaded


def test_a_fit_converts_its_options_without_pydantic(tmp_path):
    path = tmp_path / "small.csv"
    path.write_text("t,x\n" + "".join(f"{i / 100},{math.sin(2 * math.pi * 5 * i / 100) + (i * 7 % 11 - 5) / 100}\n"
                                       for i in range(300)))
    rc, loaded, out = _loaded_after(["fit", str(path), "--harmonics", "1", "--freq", "5", "--json"], STARTUP)
    assert rc == 0 and '"channels"' in out, out
    assert "pydantic" not in loaded and "numpy" in loaded, loaded  # numpy: the fit did run


def test_lazy_console_survives_monkeypatch_restore():
    # pytest >= 9.2 restores an instance attribute from the target's own __dict__ (and deletes it when it
    # is absent there): the proxy must expose the console's __dict__, or undo() deletes the real
    # console's attribute and every later CLI run in the process fails.
    import pytest
    from rich.console import Console

    from senscal.cli.common import LazyConsole

    real = Console(width=77)
    proxy = LazyConsole(lambda: real)
    before = real.__dict__["_width"]
    mp = pytest.MonkeyPatch()
    mp.setattr(proxy, "_width", 400)
    assert real.__dict__["_width"] == 400 and proxy.width == 400
    mp.undo()
    assert real.__dict__["_width"] == before
    assert proxy.width == 77
    # The restore path pytest takes with the attribute absent: delete, then set again.
    mp.setattr(proxy, "record", True)
    mp.undo()
    assert "record" in real.__dict__
