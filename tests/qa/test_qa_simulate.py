"""QA: simulator and demo options out of range are one-line errors."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("args", [
    ["sine", "--fs", "nan"],
    ["sine", "--freq", "nan"],
    ["magnetometer", "--outliers", "-1"],
    ["centrifuge", "--noise", "-1"],
    ["hydraulic", "--noise", "-1"],
    ["drift", "--dt", "nan"],
    ["shaft", "--radius", "nan"],
])
def test_simulate_bad_numbers(cli, tmp_path, args):
    r = cli("simulate", args[0], "--out", tmp_path / "o", *args[1:])
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("sub", ["afile", "afile/x"])
def test_demo_out_that_is_or_is_under_a_file(cli, tmp_path, sub):
    (tmp_path / "afile").write_text("x")
    r = cli("demo", "--out", tmp_path / sub, "--only", "sinefit")
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1, r.err
