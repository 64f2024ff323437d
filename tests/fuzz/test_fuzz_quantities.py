"""Hostile quantities on the options that take units (issue 32): a result or one clean line, never a wrong number.

Each option draws a number (hostile ones included: NaN, inf, 1e308, subnormals)
and a unit (the right dimension, another dimension, pint syntax it may choke
on: huge powers, offsets, percent, garbage, markup). A differential property
checks that a quantity and its bare value in the documented unit give the same
answer: '0.0125 kHz' must fit exactly as '12.5' does, '500 ms' cut exactly as
'0.5'. ``SENSCAL_FUZZ=long`` runs many more examples.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from _fuzz_harness import CASE_TIMEOUT_S, LONG, TALLY, run_case
from senscal.io import Recording, write_recording

NUMBERS = st.one_of(st.sampled_from(["0", "-0", "-1", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "1e400",
                                     "12.5", "0.5", ".5", "5.", "1,5", "1_0", "0x10", ""]),
                    st.floats(allow_nan=True, allow_infinity=True).map(repr))
UNITS = st.one_of(st.sampled_from(["", " ", "Hz", "kHz", "s", "ms", "us", "µs", "min", "h", "m", "mm", "V", "mV",
                                   "g", "m/s^2", "nT", "uT", "G", "degC", "K", "%", "deg", "rad", "rpm", "1/s",
                                   "/h", "m/s^999999", "m^-17", "s**2", "mm mm", "1/0", "kg*", "[/]", "e3", "e",
                                   "\u202e", "m s-2", "V/(m/s^2)", "Hz Hz", "(", ")", "*", "^", "inf", "nan m"]),
                  st.text(alphabet="abcmsHzkV/^*()-_ 0123456789µ°", max_size=8))
QUANTITY = st.tuples(NUMBERS, st.sampled_from(["", " "]), UNITS).map(lambda p: "".join(p).strip() or "1")



def qty(*valid: str):
    """Usually a valid spelling (bare or with a unit), so that cases reach past the first check to the others."""
    return st.one_of(st.sampled_from(valid), st.sampled_from(valid), QUANTITY)


EXAMPLES = 200 if LONG else 15
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("qty")
    t = np.arange(600) / 300.0
    sine = write_recording(Recording(channels={"x": np.sin(2 * np.pi * 7 * t) + 0.01 * np.cos(t * 99)}, t=t),
                           d / "s.csv")
    rng = np.random.default_rng(0)
    v = rng.normal(size=(120, 3))
    v = 50.0 * v / np.linalg.norm(v, axis=1)[:, None] + [3.0, -2.0, 1.0]
    mag = write_recording(Recording(channels=dict(zip("xyz", v.T)), fs=10.0, units={c: "uT" for c in "xyz"}),
                          d / "m.csv", units_in_header=True)
    return sine, mag


def _check(cli, args, inputs, label):
    kind, detail = run_case(cli, [str(a) for a in args], inputs, CASE_TIMEOUT_S)
    TALLY.add(label, kind, detail)
    assert detail is None, detail


@SETTINGS
@given(freq=qty("7", "7 Hz", "0.007 kHz"), start=qty("0.1", "100 ms", "0"), stop=qty("1.9", "1900 ms"))
def test_fit_quantities(cli, files, freq, start, stop):
    sine, _ = files
    _check(cli, ["fit", sine, "--freq", freq, "--start", start, "--stop", stop], [sine], "quantities: fit")


@SETTINGS
@given(field=qty("50", "50 uT", "0.5 G", "5e4 nT"), window=qty("0.5", "500 ms"))
def test_triaxial_quantities(cli, files, field, window):
    _, mag = files
    _check(cli, ["triaxial", "calibrate", mag, "--channels", "x,y,z", "--field", field, "--static-window", window],
           [mag], "quantities: triaxial calibrate")


@SETTINGS
@given(taus=st.lists(qty("0.1", "100 ms", "1 s"), min_size=1, max_size=3).map(",".join), fs=qty("300", "0.3 kHz"))
def test_allan_quantities(cli, files, taus, fs):
    sine, _ = files
    _check(cli, ["allan", sine, "-c", "x", "--taus", taus, "--fs", fs, "--time-column", "none"], [sine],
           "quantities: allan")


@SETTINGS
@given(value=st.floats(min_value=1e-3, max_value=50.0), prefix=st.sampled_from([("k", 1e-3), ("m", 1e3), ("", 1.0)]))
def test_a_quantity_fits_as_its_bare_value(cli, files, value, prefix):
    # Differential: '<f/1000> kHz' and '<f>' are one frequency; the fits must agree to the last digit.
    sine, _ = files
    p, scale = prefix
    bare = cli("fit", sine, "--freq", repr(value), "--json")
    with_unit = cli("fit", sine, "--freq", f"{value * scale!r} {p}Hz", "--json")
    assert bare.code == with_unit.code, (bare.err, with_unit.err)
    if bare.code == 0:
        a, b = json.loads(bare.out)["channels"]["x"], json.loads(with_unit.out)["channels"]["x"]
        assert b["frequency_hz"] == pytest.approx(a["frequency_hz"], rel=1e-12)
        assert b["amplitude"] == pytest.approx(a["amplitude"], rel=1e-9)
