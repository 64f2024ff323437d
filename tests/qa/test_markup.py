"""QA: user strings that look like Rich markup are printed literally (issue 20 item 3).

A '[/' in a serial, quantity, unit, note, file name or plot name crashed the
terminal output after the registry write had committed; '[bold red]x[/]'
lost its brackets and '[link=...]' became a hyperlink. Every field a user
types goes through every command here and must come back verbatim.
"""

from __future__ import annotations

import json
import shutil

import pytest

BROKEN = "[/]"                      # closing tag with nothing open: MarkupError in Rich
STYLED = "[bold red]x[/]"           # would print as 'x'
LINK = "[link=file:///etc/passwd]c[/link]"
EMOJI = ":smile:"                   # would print as an emoji
TEX = "$\\frac{$"                   # would start matplotlib mathtext in a plot


@pytest.fixture(autouse=True)
def _wide_consoles(monkeypatch):
    # Wide enough that no cell of these tests is folded or cut.
    from senscal.cli import common

    for con in (common.console, common.err_console):
        monkeypatch.setattr(con, "_width", 400)


def _compact(text: str) -> str:
    # Tables pad and may break lines: compare without whitespace.
    return "".join(text.split())


def _shown(text: str, out: str) -> bool:
    # A cell may wrap at a space: every word must appear, brackets included.
    return all(word in _compact(out) for word in text.split())


def _clean(r, code=0):
    assert r.code == code, (r.out, r.err)
    for bad in ("Traceback", "internal error", "\x1b]8;"):
        assert bad not in r.out and bad not in r.err, (r.out, r.err)
    return r


@pytest.mark.parametrize("serial", [BROKEN, STYLED, LINK])
def test_registry_fields_round_trip_literally(cli, tmp_path, serial):
    db = str(tmp_path / "reg.sqlite")
    _clean(cli("registry", "add", serial, "--kind", STYLED, "--model", LINK, "--manufacturer", EMOJI,
               "--nominal", f"{BROKEN}q=0.01 V", "--notes", BROKEN, "--db", db))
    out = _clean(cli("registry", "sensors", "--db", db)).out
    for text in (serial, STYLED, EMOJI, BROKEN):
        assert _shown(text, out), (text, out)
    sens = json.loads(_clean(cli("registry", "sensors", "--db", db, "--json")).out)["sensors"][0]
    assert (sens["serial"], sens["kind"], sens["model"], sens["manufacturer"], sens["notes"]) == (
        serial, STYLED, LINK, EMOJI, BROKEN)

    # Units are quantities (pint), not free text: markup is refused as a unit, and shown literally.
    r = _clean(cli("registry", "record", serial, "--quantity", "s", "--value", "1", "--uncertainty", "0.001",
                   "--k", "2", "--unit", f"{STYLED}/g", "--date", "2021-01-01", "--db", db), code=2)
    assert len(r.err.strip().splitlines()) == 1 and STYLED in r.err, r.err
    q, unit = f"{BROKEN}{TEX}", "V/g"
    for year, value in ((2021, 1.0), (2022, 1.001), (2023, 1.002)):
        r = _clean(cli("registry", "record", serial, "--quantity", q, "--value", value, "--uncertainty", "0.001",
                       "--k", "2", "--unit", unit, "--date", f"{year}-01-01", "--note", LINK, "--certificate", BROKEN,
                       "--db", db))
        assert _shown(q, r.out) and _shown(serial, r.out), r.out
    # The table is narrower than the strings (cells are cut with an ellipsis): it must render,
    # and the JSON carries every field verbatim.
    assert _shown(serial, _clean(cli("registry", "history", serial, "--db", db)).out)
    recs = json.loads(_clean(cli("registry", "history", serial, "--db", db, "--json")).out)["records"]
    assert {(p["quantity"], p["unit"], p["note"], p["certificate"]) for p in recs} == {(q, unit, LINK, BROKEN)}
    if serial != BROKEN:
        return  # plots, export and import once (they cost seconds), with the crashing serial
    (tmp_path / "p[").mkdir()
    plot = tmp_path / "p[" / f"]{TEX}.png"
    r = _clean(cli("registry", "history", serial, "--quantity", q, "--plot", plot, "--db", db))
    assert plot.stat().st_size > 0 and _shown(str(plot), r.err), r.err
    r = _clean(cli("registry", "due", serial, "--quantity", q, "--tolerance", "1%", "--plot", plot, "--db", db))
    assert _shown(q, r.out), r.out
    export = tmp_path / "p[" / f"]{STYLED}.json"
    export.parent.mkdir(parents=True, exist_ok=True)  # the '/' of '[/]' makes a folder; writers never invent one
    r = _clean(cli("registry", "export", export, "--db", db))
    assert _shown(str(export), r.err), r.err
    r = _clean(cli("registry", "import", export, "--db", str(tmp_path / "copy.sqlite")))
    assert "imported 1 sensors and 3 records" in r.out
    assert _clean(cli("registry", "verify", "--db", str(tmp_path / "copy.sqlite"))).code == 0
    assert _clean(cli("registry", "verify", "--db", db)).code == 0


def test_markup_in_error_messages_is_literal(cli, tmp_path):
    db = str(tmp_path / "reg.sqlite")
    r = _clean(cli("registry", "history", STYLED, "--db", db, "--create"), code=2)
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and STYLED in lines[0], r.err


def test_markup_in_file_and_sensor_names_of_a_calibration_command(cli, tmp_path):
    _clean(cli("simulate", "sine", "--out", tmp_path / "d", "--seed", "1"))
    # A '/' is a path separator, so '[/' in a path is a folder ending in '[' (the path prints '...[/]...').
    src = tmp_path / "[bold red]x[" / "]y.csv"
    src.parent.mkdir()
    shutil.copy(tmp_path / "d" / "sine.csv", src)
    db = str(tmp_path / "reg.sqlite")
    r = _clean(cli("fit", src, "--save", "--sensor", LINK, "--create-sensor", BROKEN, "--date", "2024-01-01",
                   "--db", db))
    assert _shown(str(src), r.out), r.out
    assert f"of sensor {LINK}" in r.err, r.err
    # The same evidence saved again (a retry after a failed terminal, say) adds nothing.
    r = _clean(cli("fit", src, "--save", "--sensor", LINK, "--db", db))
    assert "nothing added" in r.err, r.err
    sens = json.loads(_clean(cli("registry", "sensors", "--db", db, "--json")).out)["sensors"]
    assert [(s["serial"], s["kind"], s["n_calibrations"]) for s in sens] == [(LINK, BROKEN, 1)]


def test_emit_warnings_prints_markup_literally(capsys):
    from senscal.cli.common import emit_warnings

    emit_warnings([f"odd-name: file {STYLED} {BROKEN} {LINK}"])
    err = capsys.readouterr().err
    assert f"file {STYLED} {BROKEN} {LINK}" in err and "warning:" in err


def test_markup_in_vibration_options_and_outputs(cli, tmp_path):
    _clean(cli("simulate", "hydraulic", "--out", tmp_path / "h", "--seed", "1"))
    folder = tmp_path / "out["
    folder.mkdir()
    files = sorted((tmp_path / "h").glob("hydraulic_0[1-2].csv"))
    r = _clean(cli("velocity", *files, "--position", "position", "--velocity", "velocity", "--output-unit", STYLED),
               code=2)
    assert len(r.err.strip().splitlines()) == 1 and STYLED in r.err, r.err   # not a unit, shown literally
    r = _clean(cli("velocity", *files, "--position", "position", "--velocity", "velocity", "--output-unit", "pC",
                   "--sensor-id", BROKEN, "--model", LINK, "--condition", f"{EMOJI}={BROKEN}",
                   "--report", folder / "]c.html", "--plot", folder / f"]{TEX}.png"))
    assert _shown("pC/(m/s)", r.out) and _shown(str(folder / "]c.html"), r.out), r.out
    html = (folder / "]c.html").read_text()
    assert LINK in html and BROKEN in html                  # the certificate quotes them verbatim too
    r = _clean(cli("velocity", files[0], "--position", BROKEN, "--velocity", "velocity"), code=2)
    assert len(r.err.strip().splitlines()) == 1 and BROKEN in r.err, r.err
