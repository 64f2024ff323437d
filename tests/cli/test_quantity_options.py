"""Options with a physical dimension take quantities (issue 32): '80 mm' is 0.08 m, '80 V' is refused.

A bare number keeps the option's documented unit; a unit of the right
dimension is converted; another dimension is one line on stderr and exit 2.
The table test walks every command, so a new dimensioned option declared as a
float (Click would refuse '80 mm' with a usage box) or a table entry naming no
option fails here.
"""

from __future__ import annotations

import json
import math

import pytest
import typer

from senscal.cli import _prepare, load_commands
from senscal.cli._quantities import COMMON, ListOf, convert_options, option_units
from senscal.cli.app import app
from senscal.errors import InputError


def _commands():
    load_commands()
    out = []

    def walk(cmd, path):
        subs = getattr(cmd, "commands", None)
        if subs:
            for name, sub in subs.items():
                walk(sub, f"{path} {name}")
        elif cmd.callback is not None:
            out.append((path, cmd))

    walk(_prepare(typer.main.get_command(app)), "senscal")
    return out


COMMANDS = _commands()
QUANTITY_OPTIONS = [(path, cmd, name, unit) for path, cmd in COMMANDS
                    for name, unit in option_units(cmd.callback, {p.name: None for p in cmd.params}).items()]


def test_the_table_names_options_that_exist_and_take_text():
    assert len(QUANTITY_OPTIONS) > 80  # every reading command's --fs/--start/--stop and the dimensioned options
    for path, cmd, name, _ in QUANTITY_OPTIONS:
        params = {p.name: p for p in cmd.params}
        assert name in params, (path, name)
        ann = params[name].type_descriptor.annotation
        assert ann is str or "str" in repr(ann), f"{path} --{name} is {ann!r}: Click would refuse '80 mm'; declare it text and name it in @units (senscal.cli._quantities)"
    named = {(path, name) for path, _, name, _ in QUANTITY_OPTIONS}
    for path, cmd in COMMANDS:
        for p in cmd.params:
            if p.name in COMMON and p.param_type_name == "option":
                assert (path, p.name) in named, (path, p.name)


@pytest.mark.parametrize("path, cmd, name, unit", QUANTITY_OPTIONS,
                         ids=[f"{p} --{n}" for p, _, n, _ in QUANTITY_OPTIONS])
def test_every_quantity_option_converts_and_refuses(path, cmd, name, unit):
    flag = "--" + name.replace("_", "-")
    base = unit.unit if isinstance(unit, ListOf) else unit
    # A bare number is in the documented unit; the same number with that unit is the same value.
    got = convert_options(cmd.callback, {name: "2.5"})[name]
    same = convert_options(cmd.callback, {name: f"2.5 {base}"})[name]
    assert got == same == ("2.5" if isinstance(unit, ListOf) else 2.5) or float(str(got)) == 2.5
    # No option of senscal is a mass: the refusal names the option and both dimensions, on one line.
    with pytest.raises(InputError) as exc:
        convert_options(cmd.callback, {name: "3 kg"})
    msg = str(exc.value)
    assert flag in msg and "\n" not in msg and "kg" in msg, msg


@pytest.mark.parametrize("unit, text, expected", [
    ("m", "80 mm", 0.08), ("m", "0.08", 0.08), ("Hz", "2 kHz", 2000.0), ("s", "500 ms", 0.5),
    ("m/s^2", "1 g", 9.80665), ("rev/s", "60 rpm", 1.0), ("1/h", "1e-4 /h", 1e-4), ("1/h", "2.4/day", 0.1),
    ("day", "36 h", 1.5), ("rad/s", "180 deg/s", math.pi), ("nm", "0.6328 um", 632.8), ("g", "9.80665 m/s^2", 1.0),
])
def test_conversions(unit, text, expected):
    from senscal.units import parse_quantity

    assert parse_quantity(text, unit, option="--x") == pytest.approx(expected, rel=1e-12)


def test_lists_take_the_unit_on_every_value_or_none():
    from senscal.cli._quantities import _list

    assert _list("1 g,2 g", "m/s^2", "--a") == "9.80665,19.6133"
    assert _list("1,2", "m/s^2", "--a") == "1.0,2.0"
    assert _list(("1,2", "3 kHz"), "Hz", "--freq") == ["1.0,2.0", "3000.0"]
    with pytest.raises(InputError, match="on some values only"):
        _list("10,20,50 g", "m/s^2", "--a")  # would read 10 and 20 m/s^2, silently
    with pytest.raises(InputError, match="--a 1 V"):
        _list("1 g,1 V", "m/s^2", "--a")


# --- end to end ------------------------------------------------------------------------------------------------

def _one_line(r, *words):
    assert r.code == 2, (r.code, r.out, r.err)
    assert len(r.err.strip().splitlines()) == 1 and "Traceback" not in r.err, r.err
    for w in words:
        assert w in r.err, r.err


@pytest.fixture(scope="module")
def shaft_dir(tmp_path_factory):
    from senscal.cli import main

    out = tmp_path_factory.mktemp("shaft_qty")
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "shaft", "--out", str(out), "--seed", "3", "--cal-duration", "6000 ms",
              "--test-duration", "4", "--radius", "100 mm"])
    assert exc.value.code in (0, None)
    return out


def _shaft_args(d, *extra):
    return [d / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json", *extra]


def test_simulator_quantities_are_the_bare_values(shaft_dir):
    truth = json.loads((shaft_dir / "shaft_truth.json").read_text())
    assert truth["radius"] == pytest.approx(0.1)  # --radius '100 mm'
    import pandas as pd

    cal = pd.read_csv(shaft_dir / "shaft_cal.csv")
    assert cal.iloc[-1, 0] == pytest.approx(6.0, abs=0.01)  # 6000 ms of calibration run


def test_shaft_radius_in_mm_equals_metres(cli, shaft_dir, tmp_path):
    a = cli("shaft", "calibrate", *_shaft_args(shaft_dir, "--radius", "0.1", "--out", tmp_path / "m.json"))
    b = cli("shaft", "calibrate", *_shaft_args(shaft_dir, "--radius", "100 mm"))
    assert a.code == 0 and b.code == 0, a.err + b.err
    da, db = json.loads(a.out), json.loads(b.out)
    assert da["amplitude"] == db["amplitude"] and da["phase_deg"] == db["phase_deg"]
    _one_line(cli("shaft", "calibrate", *_shaft_args(shaft_dir, "--radius", "100 V")), "--radius", "length")
    comp = [shaft_dir / "shaft_test.csv", "--model", tmp_path / "m.json", "--angle", "angle", "--accel", "accel",
            "--json"]
    c = cli("shaft", "compensate", *comp, "--radius", "0.1")
    d = cli("shaft", "compensate", *comp, "--radius", "10 cm")
    assert c.code == 0 and d.code == 0, c.err + d.err
    assert json.loads(c.out)["rms_difference"] == json.loads(d.out)["rms_difference"]
    _one_line(cli("shaft", "compensate", *comp, "--radius", "0.1 s"), "--radius", "'s' (a time)")
    _one_line(cli("shaft", "compensate", *comp, "--radius", "0.1", "--window", "3 m"), "--window")


@pytest.fixture(scope="module")
def mag_nt(tmp_path_factory):
    from senscal.io import Recording, write_recording
    from senscal.simulate.triaxial import simulate_magnetometer

    rec, _ = simulate_magnetometer(seed=5)
    d = tmp_path_factory.mktemp("mag_qty")
    out = Recording(channels=dict(rec.channels), t=rec.t, fs=rec.fs, t0=rec.t0,
                    units={c: "nT" for c in rec.channels})
    return write_recording(out, d / "mag_nt.csv", units_in_header=True), write_recording(rec, d / "mag_plain.csv")


def test_triaxial_field_in_the_readings_unit(cli, mag_nt):
    nt, plain = mag_nt
    args = ["triaxial", "calibrate", "--channels", "x,y,z", "--json", "--field"]
    docs = []
    for f in ("50000", "50 uT", "0.5 G", "5e-5 T"):
        r = cli(*args, f, nt)
        assert r.code == 0, (f, r.err)
        docs.append(json.loads(r.out))
    assert all(d["field"]["value"] == 50000.0 for d in docs), [d["field"]["value"] for d in docs]
    assert len({json.dumps(d["parameters"], sort_keys=True) for d in docs}) == 1
    _one_line(cli(*args, "1 g", nt), "--field", "acceleration", "nT")
    # Readings without a unit: a bare field is in their unit; a field with a unit cannot be converted to them.
    assert cli(*args, "50000", plain).code == 0
    _one_line(cli(*args, "50 uT", plain), "--field", "gives none")


@pytest.fixture(scope="module")
def centrifuge(tmp_path_factory):
    from senscal.cli import main

    d = tmp_path_factory.mktemp("lin_qty")
    with pytest.raises(SystemExit):
        main(["simulate", "centrifuge", "--out", str(d), "--seed", "3", "--freqs", "2", "--accelerations",
              "1 g,2 g,5 g,10 g"])
    return sorted(d.glob("centrifuge_[0-9]*.csv"))


def test_linearity_input_amplitudes_in_g(cli, centrifuge):
    base = ["linearity", *centrifuge, "--output", "output", "--angle", "angle", "--json", "--input-amplitudes"]
    a = cli(*base, "9.80665,19.6133,49.03325,98.0665")
    b = cli(*base, "1 g,2 g,5 g,10 g")
    assert a.code == 0 and b.code == 0, a.err + b.err
    da, db = json.loads(a.out), json.loads(b.out)
    assert db["slope"] == pytest.approx(da["slope"], rel=1e-12)
    assert [p["input_amplitude"] for p in db["points"]] == pytest.approx([9.80665, 19.6133, 49.03325, 98.0665])
    _one_line(cli(*base, "1,2,5,10 g"), "--input-amplitudes", "some values only")
    _one_line(cli(*base, "1 V,2 V,5 V,10 V"), "--input-amplitudes", "voltage")
    _one_line(cli(*base, "1 g,2 g,5 g,10 g", "--freq", "2 m"), "--freq")


def test_fit_freq_fs_and_window_with_units(cli, tmp_path):
    from senscal.cli import main

    with pytest.raises(SystemExit):
        main(["simulate", "sine", "--out", str(tmp_path), "--seed", "2", "--fs", "1 kHz", "--duration", "2 s",
              "--freq", "12.5 Hz"])
    f = tmp_path / "sine.csv"
    a = cli("fit", f, "--freq", "12.5", "--start", "0.5", "--stop", "1.5", "--json")
    b = cli("fit", f, "--freq", "0.0125 kHz", "--start", "500 ms", "--stop", "1500 ms", "--json")
    assert a.code == 0 and b.code == 0, a.err + b.err
    assert json.loads(a.out)["channels"] == json.loads(b.out)["channels"]
    _one_line(cli("fit", f, "--freq", "12.5 m"), "--freq", "frequency")
    _one_line(cli("fit", f, "--start", "1 V"), "--start", "a time")
