"""Issue 32's mutation campaign as fuzz regressions: each case a result or one clean line, never a hang.

Two parts: (1) every corpus target run with each of its command's output
options naming the (mutated) input it reads: always a clean refusal, the input
unchanged; (2) the campaign's internal errors and hangs, each one command
line classified by the harness (exit 2, or 3 for tampering; one line; no
traceback; within the case time limit).  tests/qa/test_qa_issue32.py checks
the messages themselves.
"""

from __future__ import annotations

import shutil
import sqlite3
import zlib

import numpy as np
import pytest

from _fuzz_harness import CASE_TIMEOUT_S, TALLY, mutate, run_case

# Output options a target's command has (the harness targets are single command lines).
_OUTPUTS = {"fit": [], "velocity": ["--report", "--plot", "--dcc"], "response": ["--report", "--plot", "--dcc",
            "--save-response"], "shaft calibrate": ["--out", "--plot"], "shaft compensate": ["--out", "--plot"],
            "triaxial calibrate": ["--out", "--plot"], "triaxial apply": ["--out"], "gfimu": ["--out", "--plot"],
            "drift": ["--out", "--plot", "--state"], "registry import": [], "fit-array": ["--out"]}


def _command(target: str) -> str:
    words = target.split()
    base = " ".join(w for w in words if not w.startswith("-"))
    return "fit" if base.startswith("fit") and not base.startswith("fit-array") else base


def _drop(args: list[str], opt: str) -> list[str]:
    """``args`` without ``opt`` and its value (the harness' own --out)."""
    out, skip = [], False
    for a in args:
        if skip:
            skip = False
            continue
        if a == opt:
            skip = True
            continue
        out.append(a)
    return out


def test_every_target_output_naming_its_mutated_input_is_refused(cli, corpus, tmp_path):
    cases = 0
    rng = np.random.default_rng(zlib.crc32(b"issue32-outputs"))
    for name, tg in corpus.items():
        for opt in _OUTPUTS[_command(name)]:
            f = tmp_path / f"in{cases}{tg.suffix}"
            f.write_bytes(mutate(tg.seed_file.read_bytes(), rng) if cases % 2 else tg.seed_file.read_bytes())
            o = tmp_path / f"o{cases}"
            o.mkdir()
            args = _drop([str(a) for a in tg.args(f, o)], opt) + [opt, str(f)]
            kind, detail = run_case(cli, args, [f], CASE_TIMEOUT_S)
            TALLY.add(f"outputs: {name}", kind, detail)
            assert detail is None, detail
            r = cli(*args)
            assert r.code == 2, f"senscal {' '.join(args)} -> {r.code}: {r.err}"
            cases += 1
    assert cases >= 25


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    """Files for the campaign's command lines."""
    from senscal.io import Recording, write_recording

    d = tmp_path_factory.mktemp("issue32")
    t = np.arange(200, dtype=float)
    rng = np.random.default_rng(3)
    files = {"huge": write_recording(Recording({"x": rng.uniform(1, 9, t.size) * 1e300}, t=t), d / "huge.csv")}
    from _fuzz_harness import quiet_main

    def sim(*args):
        code, _, err = quiet_main([str(a) for a in args])
        assert code == 0, err

    sim("simulate", "drift", "--out", d / "dr", "--seed", "1", "--samples", "200")
    files["drift"] = d / "dr" / "drift.csv"
    head = files["drift"].read_text().splitlines()[0].split(",")
    files["chans"] = [h for h in head if h not in ("t", "temperature")]
    sim("simulate", "magnetometer", "--out", d / "mag", "--seed", "1", "--n", "120")
    sim("triaxial", "calibrate", d / "mag" / "magnetometer.csv", "--channels", "x,y,z", "--out", d / "mag" / "p.json")
    lines = (d / "mag" / "magnetometer.csv").read_text().splitlines()
    row = lines[3].split(",")
    row[1] = "1e308"
    lines[3] = ",".join(row)
    (d / "mag" / "huge.csv").write_text("\n".join(lines) + "\n")
    files["mag_huge"], files["params"] = d / "mag" / "huge.csv", d / "mag" / "p.json"
    sim("simulate", "shaft", "--out", d / "shaft", "--seed", "1", "--fs", "200", "--cal-duration", "6",
        "--test-duration", "3")
    files["shaft"] = d / "shaft" / "shaft_cal.csv"
    sim("simulate", "registry", "--out", d / "reg", "--seed", "1")
    sim("registry", "import", d / "reg" / "history.json", "--db", d / "reg" / "reg.sqlite")
    files["db"] = d / "reg" / "reg.sqlite"
    files["dir"] = d
    return files


def _tampered_copy(src, dst, sql: str):
    shutil.copy(src, dst)
    con = sqlite3.connect(dst)
    for (trigger,) in con.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'").fetchall():
        con.execute(f"DROP TRIGGER {trigger}")
    con.execute(sql)
    con.commit()
    con.close()
    return dst


CAMPAIGN = [
    # (label, expected exit, builder of the command line from the case files and a work folder)
    ("allan on values near 1e308", 2, lambda c, w: ["allan", c["huge"], "-c", "x"]),
    ("shaft calibrate --window 1e308", 2, lambda c, w: ["shaft", "calibrate", c["shaft"], "--angle", "angle",
                                                       "--accel", "accel", "--window", "1e308"]),
    ("triaxial apply on 1e308 readings", 2, lambda c, w: ["triaxial", "apply", c["mag_huge"], "--params",
                                                          c["params"], "--channels", "x,y,z", "--out", w / "a.csv"]),
    ("fit-array --workers 2^31", 2, lambda c, w: ["fit-array", c["huge"], "--dataset", "y", "--out", w / "f.csv",
                                                  "--workers", "2147483648"]),
    ("batch --workers 2^31", 2, lambda c, w: ["batch", "fit", c["huge"], "--workers", "2147483648"]),
    ("drift-fleet --workers 2^31", 2, lambda c, w: ["drift-fleet", w, "--config", c["params"], "--workers",
                                                    "2147483648"]),
    ("simulate sine --channels 2^31", 2, lambda c, w: ["simulate", "sine", "--out", w / "s", "--channels",
                                                       "2147483648"]),
    ("simulate fleet --channels 2^31", 2, lambda c, w: ["simulate", "fleet", "--out", w / "f", "--channels",
                                                        "2147483648"]),
    ("drift --covariate-reference -1e308", 2, lambda c, w: [
        "drift", c["drift"], "--preset", "redundant", "--trusted", c["chans"][0], "--channels",
        ",".join(c["chans"][:2]), "--covariate", "temperature", "--covariate-reference", "-1e308", "--no-compare"]),
    ("registry due --k nan", 2, lambda c, w: ["registry", "due", "SIM-001", "--quantity", "sensitivity",
                                              "--tolerance", "1%", "--k", "nan", "--db", c["db"]]),
    ("drift model YAML with a string for a number", 2, lambda c, w: [
        "drift", c["drift"], "--preset", "model", "--model", _yaml(w, c, "level: abc"), "--no-compare"]),
    ("drift model YAML with a string in a matrix", 2, lambda c, w: [
        "drift", c["drift"], "--preset", "model", "--model", _yaml(w, c, "kind: matrix, F: [[abc]], Q: [[1]]"),
        "--no-compare"]),
    ("registry with alembic_version ''", 2, lambda c, w: [
        "registry", "verify", "--db", _tampered_copy(c["db"], w / "a.sqlite", "UPDATE alembic_version SET version_num = ''")]),
    ("registry with a tampered recorded_at", 3, lambda c, w: [
        "registry", "verify", "--db", _tampered_copy(c["db"], w / "b.sqlite",
                                                     "UPDATE calibrations SET recorded_at = 'garbage' WHERE id = 1")]),
    ("registry with JSON that is no JSON", 3, lambda c, w: [
        "registry", "history", "SIM-001", "--db", _tampered_copy(c["db"], w / "c.sqlite",
                                                                  "UPDATE calibrations SET result = '{x' WHERE id = 1")]),
    ("registry with a text that is no UTF-8", 3, lambda c, w: [
        "registry", "sensors", "--db", _tampered_copy(c["db"], w / "d.sqlite",
                                                      "UPDATE sensors SET kind = CAST(X'FFFE41' AS TEXT)")]),
    ("registry verify on an empty file", 2, lambda c, w: ["registry", "verify", "--db", _empty(w / "e.sqlite", b"")]),
    ("registry sensors on a 1-byte file", 2, lambda c, w: ["registry", "sensors", "--db", _empty(w / "f.sqlite",
                                                                                                  b"x")]),
]


def _yaml(w, c, signal: str):
    p = w / "m.yaml"
    a, b = c["chans"][:2]
    p.write_text(f"channels: [{a}, {b}]\ntrusted: [{a}]\nsignal: {{kind: random_walk, {signal}}}\n"
                 f"biases:\n  - {{channel: {b}}}\n".replace("kind: random_walk, kind: matrix", "kind: matrix"))
    return p


def _empty(p, data: bytes):
    p.write_bytes(data)
    return p


@pytest.mark.parametrize("label,code,build", CAMPAIGN, ids=[c[0] for c in CAMPAIGN])
def test_campaign_case(cli, cases, tmp_path, label, code, build):
    args = [str(a) for a in build(cases, tmp_path)]
    inputs = [p for p in map(__import__("pathlib").Path, args) if p.is_file()]
    kind, detail = run_case(cli, args, inputs, CASE_TIMEOUT_S)
    TALLY.add("issue 32 campaign", kind, detail)
    assert detail is None, detail
    r = cli(*args)
    assert r.code == code, f"{label}: senscal {' '.join(args)} -> {r.code}: {r.err}"


def test_stdin_with_invalid_utf8_into_drift_state(cli, cases, tmp_path, monkeypatch):
    import io
    import sys

    head = cases["drift"].read_text().splitlines()[0]
    data = (head + "\n").encode() + b"0,1,\xff\xfe,2,3\n"
    fake = io.TextIOWrapper(io.BytesIO(data), encoding="utf-8", errors="surrogateescape")
    monkeypatch.setattr(sys, "stdin", fake)
    r = cli("drift", "-", "--state", tmp_path / "s.json", "--preset", "redundant", "--trusted", cases["chans"][0],
            "--channels", ",".join(cases["chans"][:2]))
    assert r.code == 2 and "UTF-8" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert not (tmp_path / "s.json").exists()


def test_damaged_tdms_prints_one_line(cli, tmp_path):
    from senscal.io import Recording, write_recording

    t = np.arange(400) / 400.0
    good = write_recording(Recording({"x": np.sin(2 * np.pi * 10 * t)}, t=t), tmp_path / "s.tdms").read_bytes()
    (tmp_path / "bad.tdms").write_bytes(good[: len(good) // 2])  # nptdms logs two warnings, then the read fails
    r = cli("fit", tmp_path / "bad.tdms", "--freq", "10")
    lines = [ln for ln in r.err.splitlines() if ln.strip()]
    assert r.code == 2 and len(lines) == 1 and lines[0].startswith("senscal: "), r.err
