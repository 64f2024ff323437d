"""Issue 32: no command may write an output over one of its inputs, and a failing command writes nothing.

The commands are enumerated from the Typer app itself: every leaf command that
has an output option (``--out``, ``--plot``, ``--report``, ``--dcc``,
``--save-response``, ``--state``, or the FILE of ``registry export``) gets each
of them pointed at each input of a valid command line, and must refuse with
one line, exit 2, leaving the input byte for byte as it was.  A new command
with an output fails :func:`test_every_command_with_an_output_has_a_command_line`
until a valid command line for it is added to ``INVOCATIONS``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from senscal.cli.common import _output_params

# Command lines that run (with {name} replaced by corpus files).  Options naming outputs are left out: the test
# adds them.  Commands whose outputs are folders of fresh files and that read no file are in NO_INPUTS.
INVOCATIONS: dict[str, list[str]] = {
    "allan": ["{sine}", "-c", "ch1"],
    "batch": ["fit", "{sine}", "--workers", "1"],
    "fit-array": ["{h5}", "--dataset", "y", "--time-dataset", "t"],
    "drift": ["{drift}", "--preset", "model", "--model", "{model}", "--no-compare"],
    "drift-fleet": ["{fleet}", "--config", "{fleet_config}", "--workers", "0"],
    "gfimu": ["{gf}", "--layout", "{layout}", "--method", "integration", "--truth", "{gf_truth}"],
    "velocity": ["{hy1}", "{hy2}", "--position", "position", "--velocity", "velocity"],
    "response": ["{sh1}", "{sh2}", "--output", "dut", "--reference", "reference", "--reference-sensitivity",
                 "0.0102"],
    "linearity": ["{lin1}", "{lin2}", "{lin3}", "--output", "velocity", "--input-amplitudes", "1,2,3", "--freq",
                  "5"],
    "registry history": ["{serial}", "--db", "{db}"],
    "registry due": ["{serial}", "--quantity", "{quantity}", "--tolerance", "1%", "--db", "{db}"],
    "registry export": ["--db", "{db}"],
    "shaft calibrate": ["{shaft_cal}", "--angle", "angle", "--accel", "accel"],
    "shaft compensate": ["{shaft_test}", "--model", "{shaft_model}", "--angle", "angle", "--accel", "accel",
                         "--radius", "0.1"],
    "triaxial calibrate": ["{mag}", "--channels", "x,y,z"],
    "triaxial apply": ["{mag}", "--params", "{mag_params}", "--channels", "x,y,z"],
    "triaxial import": ["{ab}"],
    "primary": ["{ifm}"],
    "imu calibrate": ["{imu}"],
    "shock": ["{shock}", "--reference", "ref", "--reference-sensitivity", "0.1 mV/(m/s^2)", "--u-reference",
              "0.5%"],
    "imu apply": ["{imu}", "--params", "{imu_params}"],
}
NO_INPUTS = {"demo"}  # and every simulator: they write a folder from options alone
# Positional outputs (the FILE of 'registry export'): where in the command line they go.
POSITIONAL_OUTPUT = {"registry export": 0}


def _leaf_commands() -> dict[str, object]:
    import typer

    from senscal.cli import load_commands

    root = typer.main.get_command(load_commands())
    out: dict[str, object] = {}

    def walk(cmd, path):
        if getattr(cmd, "commands", None):
            for name, sub in cmd.commands.items():
                walk(sub, [*path, name])
        else:
            out[" ".join(path)] = cmd

    walk(root, [])
    return out


def _outputs_of(path: str, cmd) -> dict[str, str]:
    """``{parameter name: option}`` of the outputs a command has (the table every command's check uses)."""
    table = _output_params(f"senscal {path}")
    names = {p.name: p for p in cmd.params}
    out = {}
    for name, (what, _kind) in table.items():
        if name in names:
            opts = getattr(names[name], "opts", None) or [what]
            out[name] = next((o for o in opts if o.startswith("--")), what)
    return out


def _quiet(*args):
    import contextlib
    import io

    from senscal.cli import main

    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        try:
            main([str(a) for a in args])
            code = 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
    assert code == 0, f"corpus: senscal {' '.join(map(str, args))}: {err.getvalue()}"


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    from senscal.io import Recording, write_recording

    d = tmp_path_factory.mktemp("every_command")
    c: dict[str, str] = {}
    _quiet("simulate", "sine", "--out", d / "sine", "--seed", "1", "--channels", "1")
    c["sine"] = str(d / "sine" / "sine.csv")
    _quiet("simulate", "drift", "--out", d / "dr", "--seed", "1", "--samples", "200")
    c["drift"] = str(d / "dr" / "drift.csv")
    head = Path(c["drift"]).read_text().splitlines()[0].split(",")
    chans = [h for h in head if h not in ("t", "temperature")]
    (d / "dr" / "model.yaml").write_text(f"channels: [{chans[0]}, {chans[1]}]\ntrusted: [{chans[0]}]\n"
                                         "signal: {kind: random_walk}\n"
                                         f"biases:\n  - {{channel: {chans[1]}}}\n")
    c["model"] = str(d / "dr" / "model.yaml")
    _quiet("simulate", "fleet", "--out", d / "fleet", "--seed", "1", "--channels", "2", "--samples", "200")
    c["fleet"], c["fleet_config"] = str(d / "fleet"), str(d / "fleet" / "fleet.json")
    _quiet("simulate", "gfimu", "--out", d / "gf", "--seed", "1", "--duration", "0.5", "--fs", "200")
    c["gf"], c["layout"] = str(d / "gf" / "gfimu.csv"), str(d / "gf" / "layout.csv")
    c["gf_truth"] = str(d / "gf" / "gfimu_truth.csv")
    _quiet("simulate", "hydraulic", "--out", d / "hy", "--seed", "1", "--freqs", "2,4")
    c["hy1"], c["hy2"] = map(str, sorted((d / "hy").glob("hydraulic_*.csv")))
    _quiet("simulate", "shaker", "--out", d / "sh", "--seed", "1", "--freqs", "80,160")
    c["sh1"], c["sh2"] = map(str, sorted((d / "sh").glob("shaker_*.csv")))
    t = np.arange(400) / 100.0
    rng = np.random.default_rng(0)
    for k, a in enumerate((1.0, 2.0, 3.0), start=1):
        rec = Recording({"velocity": 0.3 * a * np.sin(2 * np.pi * 5 * t) + 0.01 * rng.standard_normal(t.size)}, t=t)
        c[f"lin{k}"] = str(write_recording(rec, d / f"lin{k}.csv"))
    _quiet("simulate", "shaft", "--out", d / "shaft", "--seed", "1", "--fs", "200", "--cal-duration", "6",
           "--test-duration", "3")
    c["shaft_cal"], c["shaft_test"] = str(d / "shaft" / "shaft_cal.csv"), str(d / "shaft" / "shaft_test.csv")
    _quiet("shaft", "calibrate", c["shaft_cal"], "--angle", "angle", "--accel", "accel", "--out",
           d / "shaft" / "model.json")
    c["shaft_model"] = str(d / "shaft" / "model.json")
    _quiet("simulate", "magnetometer", "--out", d / "mag", "--seed", "1", "--n", "150")
    c["mag"] = str(d / "mag" / "magnetometer.csv")
    _quiet("triaxial", "calibrate", c["mag"], "--channels", "x,y,z", "--out", d / "mag" / "params.json")
    c["mag_params"] = str(d / "mag" / "params.json")
    _quiet("simulate", "interferometer", "--out", d / "ifm", "--seed", "1", "--freqs", "160", "--duration", "0.05")
    c["ifm"] = str(next((d / "ifm").glob("interferometer_*.csv")))
    _quiet("simulate", "shock", "--out", d / "shk", "--seed", "1", "--durations-ms", "1", "--u-reference", "0.005")
    c["shock"] = str(next((d / "shk").glob("shock_*.csv")))
    _quiet("simulate", "imu", "--out", d / "imu", "--seed", "1")
    c["imu"] = str(d / "imu" / "imu.csv")
    _quiet("imu", "calibrate", c["imu"], "--out", d / "imu" / "cal.json")
    c["imu_params"] = str(d / "imu" / "cal.json")
    (d / "ab.txt").write_text("1 0 0\n0 1 0\n0 0 1\n0 0 0\n")
    c["ab"] = str(d / "ab.txt")
    import h5py

    with h5py.File(d / "array.h5", "w") as fh:
        fh.create_dataset("y", data=np.stack([np.sin(2 * np.pi * 10 * t)] * 2)).attrs["fs"] = 100.0
        fh.create_dataset("t", data=t)
    c["h5"] = str(d / "array.h5")
    _quiet("simulate", "registry", "--out", d / "reg", "--seed", "1")
    doc = json.loads((d / "reg" / "history.json").read_text())
    sensor = doc["sensors"][0]
    c["serial"], c["quantity"] = sensor["serial"], sensor["calibrations"][0]["quantities"][0]["name"]
    _quiet("registry", "import", d / "reg" / "history.json", "--db", d / "reg" / "reg.sqlite")
    c["db"] = str(d / "reg" / "reg.sqlite")
    c["_dir"] = str(d)
    return c


def _fill(args, corpus):
    return [a.format(**corpus) if "{" in a else a for a in args]


def _digest(path: str) -> str:
    p = Path(path)
    if p.is_dir():
        return hashlib.sha256(b"".join(f.read_bytes() for f in sorted(p.rglob("*")) if f.is_file())).hexdigest()
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_every_command_with_an_output_has_a_command_line():
    missing = []
    for path, cmd in _leaf_commands().items():
        outs = _outputs_of(path, cmd)
        if outs and path not in INVOCATIONS and path not in NO_INPUTS and not path.startswith("simulate "):
            missing.append(f"{path} ({', '.join(outs.values())})")
    assert not missing, f"add a valid command line to INVOCATIONS for: {missing}"


def test_every_output_naming_every_input_is_refused(cli, corpus):
    cases = failures = 0
    problems = []
    commands = _leaf_commands()
    for path, base in INVOCATIONS.items():
        cmd = commands[path]
        outs = _outputs_of(path, cmd)
        assert outs, f"{path} has no output option any more; drop it from INVOCATIONS"
        args = _fill(base, corpus)
        inputs = [a for a in args if a.startswith(corpus["_dir"]) and Path(a).exists()]
        assert inputs, path
        for name, opt in outs.items():
            for inp in inputs:
                before = _digest(inp)
                if path in POSITIONAL_OUTPUT:
                    line = [*path.split(), inp, *args]
                else:
                    line = [*path.split(), *args, opt, inp]
                r = cli(*line)
                cases += 1
                lines = [ln for ln in r.err.splitlines() if ln.strip() and not ln.startswith("warning:")]
                ok = (r.code == 2 and len(lines) == 1 and "Traceback" not in r.err
                      and ("input" in lines[0] or "is a file" in lines[0] or "folder" in lines[0]))
                if not ok or _digest(inp) != before:
                    failures += 1
                    problems.append(f"senscal {' '.join(line)} -> exit {r.code}: {r.err.strip()[:200]}")
    assert not problems, "\n".join(problems)
    assert cases >= 40  # every output option of every command against every input it reads


@pytest.mark.parametrize("form", ["same", "dot", "absolute", "dotdot", "symlink"])
def test_allan_out_never_replaces_its_recording(cli, corpus, tmp_path, monkeypatch, form):
    # Issue 32 item 1: allan checked --out before the recording was read, and replaced it (exit 0).
    (tmp_path / "dir").mkdir()
    rec = tmp_path / "dir" / "in.csv"
    rec.write_bytes(Path(corpus["sine"]).read_bytes())
    before = _digest(str(rec))
    monkeypatch.chdir(tmp_path / "dir")
    out = {"same": "in.csv", "dot": "./in.csv", "absolute": str(rec), "dotdot": "../dir/in.csv",
           "symlink": "link.csv"}[form]
    if form == "symlink":
        (tmp_path / "dir" / "link.csv").symlink_to(rec)
    r = cli("allan", "in.csv", "-c", "ch1", "--out", out)
    assert r.code == 2 and "input" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert _digest(str(rec)) == before
    if form == "symlink":
        assert (tmp_path / "dir" / "link.csv").is_symlink()


def test_input_found_only_while_running_is_protected(tmp_path):
    # The last check runs when the command ends, with every input known (a recording named inside a run file).
    from senscal.errors import InputError
    from senscal.io.guard import declare_outputs, note_input, protect_inputs, write_text

    a = tmp_path / "a.csv"
    a.write_text("t,x\n0,1\n")
    with pytest.raises(InputError, match="input"):
        with protect_inputs():
            declare_outputs({str(a): ("--out", "file")})  # not yet known as an input
            note_input(a)
            write_text(a, "overwritten")
    assert a.read_text() == "t,x\n0,1\n"


def test_declared_outputs_are_written_all_or_none(tmp_path):
    from senscal.errors import InputError
    from senscal.io.guard import declare_outputs, protect_inputs, write_text

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    with pytest.raises(InputError):
        with protect_inputs():
            declare_outputs({str(a): ("--out", "file"), str(b): ("--plot", "file")})
            write_text(a, "{}")
            assert not a.exists()  # held back until the command ends
            raise InputError("a later step failed")
    assert not a.exists() and not b.exists()
    assert not list(tmp_path.iterdir())  # no temporary file left behind
    with protect_inputs():
        declare_outputs({str(a): ("--out", "file"), str(b): ("--plot", "file")})
        write_text(a, "{}")
        write_text(b, "[]")
    assert a.read_text() == "{}" and b.read_text() == "[]"


@pytest.mark.parametrize("cmd", [
    ["shaft", "calibrate", "{shaft_cal}", "--angle", "angle", "--accel", "accel", "--out", "{o}/m.json"],
    ["triaxial", "calibrate", "{mag}", "--channels", "x,y,z", "--out", "{o}/p.json"],
    ["drift", "{drift}", "--preset", "model", "--model", "{model}", "--no-compare", "--out", "{o}/c.csv"],
    ["response", "{sh1}", "{sh2}", "--output", "dut", "--reference", "reference", "--reference-sensitivity",
     "0.0102", "--save-response", "{o}/r.json"],
])
@pytest.mark.parametrize("bad", ["BAD", "/dev/full", "{o}/nofolder/p.png"])
def test_a_bad_plot_leaves_no_other_output(cli, corpus, tmp_path, cmd, bad):
    # Issue 32 item 6: --out was written, then the plot failed (exit 2) and the user kept half a result.
    fill = dict(corpus, o=str(tmp_path))
    line = [a.format(**fill) for a in cmd] + ["--plot", bad.format(**fill)]
    r = cli(*line)
    assert r.code == 2 and len([ln for ln in r.err.splitlines() if not ln.startswith("warning:")]) == 1, r.err
    assert not [p for p in tmp_path.rglob("*") if p.is_file()], "an output was written by a failing command"


@pytest.mark.parametrize("cmd", [
    ["shaft", "calibrate", "{shaft_cal}", "--angle", "angle", "--accel", "accel", "--plot", "{o}/p.png"],
    ["response", "{sh1}", "{sh2}", "--output", "dut", "--reference", "reference", "--reference-sensitivity",
     "0.0102", "--plot", "{o}/p.png"],
])
def test_an_unwritable_out_leaves_no_plot(cli, corpus, tmp_path, cmd):
    fill = dict(corpus, o=str(tmp_path))
    opt = "--save-response" if cmd[0] == "response" else "--out"
    r = cli(*[a.format(**fill) for a in cmd], opt, "/dev/full")
    assert r.code == 2, r.err
    assert not (tmp_path / "p.png").exists()


def test_missing_output_folder_is_refused_unless_mkdir(cli, corpus, tmp_path):
    r = cli("allan", corpus["sine"], "-c", "ch1", "--out", tmp_path / "typo" / "a.csv")
    assert r.code == 2 and "--mkdir" in r.err and len(r.err.strip().splitlines()) == 1, r.err
    assert not (tmp_path / "typo").exists()
    r = cli("allan", corpus["sine"], "-c", "ch1", "--out", tmp_path / "typo" / "a.csv", "--mkdir")
    assert r.code == 0, r.err
    assert (tmp_path / "typo" / "a.csv").is_file()


def test_simulate_fleet_to_stdout_makes_no_folder(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = cli("simulate", "fleet", "--out", "-", "--channels", "2", "--samples", "100")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1, r.err
    assert not (tmp_path / "-").exists()
