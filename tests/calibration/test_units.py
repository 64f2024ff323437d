"""Units as quantities (pint): spellings of one unit agree, scales convert, other dimensions are refused."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from senscal.errors import InputError
from senscal.persist.units import check_unit, numerator, same_unit, unit_factor
from senscal.units import STANDARD_GRAVITY, compatible, convert, dimension_of, factor, parse_quantity, parse_unit

SAME = [
    ("m/s^2", "m/s²"), ("m/s^2", "m s-2"), ("m/s^2", "m*s**-2"), ("m/s^2", "m·s⁻²"),
    ("m/s^2", "m/s/s"), ("m/s^2", " m/s^2 "), ("deg", "°"), ("deg", "degrees"), ("rad/s", "rad s-1"),
    ("V/(m/s^2)", "V s^2/m"), ("V/(m/s^2)", "V s² m⁻¹"), ("V/(m/s)", "V s/m"), ("µT", "uT"), ("μT", "uT"),
    ("Ω", "ohm"), ("°C", "degC"), ("℃", "degC"), ("s", "sec"), ("", "1"), ("LSB", "counts"), ("g", "gn"),
]
# Another scale of one dimension: the factor that takes the first into the second.
SCALES = [
    ("mV", "V", 1e-3), ("mm", "m", 1e-3), ("ms", "s", 1e-3), ("um/s", "m/s", 1e-6), ("µm", "m", 1e-6),
    ("g", "m/s^2", STANDARD_GRAVITY), ("mg", "m/s^2", 1e-3 * STANDARD_GRAVITY), ("uT", "nT", 1e3),
    ("G", "T", 1e-4), ("deg", "rad", np.pi / 180), ("V/g", "V/(m/s^2)", 1 / STANDARD_GRAVITY),
    ("mV/(m/s^2)", "V/(m/s^2)", 1e-3), ("pC/(m/s^2)", "pC/g", STANDARD_GRAVITY), ("kHz", "Hz", 1e3),
]
# Other dimensions: never converted.
REFUSED = [("V", "m/s^2"), ("m", "V"), ("deg", "%"), ("deg", "count"), ("m/s", "m/s^2"), ("V/(m/s^2)", "V/(m/s)"),
           ("T", "V"), ("s", "Hz")]


@pytest.mark.parametrize("a,b", SAME)
def test_spellings_of_one_unit_are_the_same_unit(a, b):
    assert same_unit(a, b) and same_unit(b, a)
    assert unit_factor(a, b, what="x", fix="y") == pytest.approx(1.0)


@pytest.mark.parametrize("a,b,f", SCALES)
def test_scales_convert(a, b, f):
    assert not same_unit(a, b) and compatible(a, b)
    assert factor(a, b) == pytest.approx(f, rel=1e-12)
    assert unit_factor(a, b, what="x", fix="y") == pytest.approx(f, rel=1e-12)
    np.testing.assert_allclose(convert([1.0, -2.5], a, b), [f, -2.5 * f], rtol=1e-12)


@pytest.mark.parametrize("a,b", REFUSED)
def test_other_dimensions_are_refused_in_one_line(a, b):
    assert not compatible(a, b) and not same_unit(a, b)
    with pytest.raises(InputError) as exc:
        factor(a, b, what="channel 'x'", fix="convert it")
    msg = str(exc.value)
    assert "\n" not in msg and f"in '{a}'" in msg and "cannot be converted" in msg and msg.endswith("convert it")
    with pytest.raises(InputError, match=re.escape(f"is in '{b}'") + ".* but the sensor was calibrated in"):
        check_unit(b, a, what="channel 'x'", fix="convert it")


def test_words_for_dimensions():
    assert dimension_of("mV") == "a voltage" and dimension_of("g") == "an acceleration"
    assert dimension_of("deg") == "an angle" and dimension_of("rpm") == "an angular velocity"


def test_offsets_convert_values_but_are_no_factor():
    np.testing.assert_allclose(convert([0.0, 100.0], "degC", "K"), [273.15, 373.15])
    with pytest.raises(InputError, match="offset"):
        factor("degC", "K")


def test_unknown_units_pass_when_missing_and_unknown_text_is_refused():
    assert unit_factor("", "m/s^2", what="x", fix="y") == 1.0 and unit_factor("m/s^2", None, what="x", fix="y") == 1.0
    assert unit_factor("counts ??", "counts ??", what="x", fix="y") == 1.0
    with pytest.raises(InputError, match="'blorbs' is not a unit senscal knows"):
        unit_factor("blorbs", "V", what="x", fix="y")
    with pytest.raises(InputError, match="is not a unit senscal knows"):
        parse_unit("blorbs", what="--unit")


def test_option_quantities():
    assert parse_quantity("0.05", "V/(m/s^2)", option="--s") == 0.05
    assert parse_quantity(0.05, "V/(m/s^2)", option="--s") == 0.05
    assert parse_quantity("50 mV/(m/s^2)", "V/(m/s^2)", option="--s") == pytest.approx(0.05)
    assert parse_quantity("1 g", "m/s^2", option="--a") == pytest.approx(STANDARD_GRAVITY)
    assert parse_quantity("5 pC/g", "pC/(m/s^2)", option="--s") == pytest.approx(5 / STANDARD_GRAVITY)
    with pytest.raises(InputError, match="--a 5 V is in 'V'.*cannot be converted to 'm/s\\^2'"):
        parse_quantity("5 V", "m/s^2", option="--a")
    with pytest.raises(InputError, match="--a must be a number"):
        parse_quantity("lots", "m/s^2", option="--a")


def test_numerator():
    assert numerator("V/(m/s^2)") == "V" and numerator("m/s") == "m" and numerator("V") == "V"


def test_triaxial_apply_cli_converts_units(cli, tmp_path):
    """A recording in m/s² or m s-2 is the calibration's m/s^2; one in g is converted; one in V is refused."""
    from senscal.io import Recording, read_recording, write_recording
    from senscal.triaxial import TriaxialCalibration

    cal = TriaxialCalibration(model="offsets", method="ml", matrix=np.eye(3), offsets=np.array([0.1, -0.2, 0.3]),
                              field=9.80665, unit="m/s^2")
    params = cal.save(tmp_path / "p.json")
    data = {c: np.linspace(-9.0, 9.0, 20) + i for i, c in enumerate("xyz")}
    for unit, scale in (("m/s²", 1.0), ("m s-2", 1.0), ("g", STANDARD_GRAVITY)):
        given = {c: v / scale for c, v in data.items()}
        f = write_recording(Recording(given, fs=10.0, units={c: unit for c in "xyz"}), tmp_path / "r.csv",
                            units_in_header=True)
        r = cli("triaxial", "apply", f, "--params", params, "--channels", "x,y,z", "--out", tmp_path / f"o{scale}.csv")
        assert r.code == 0, r.err
        out = read_recording(tmp_path / f"o{scale}.csv")
        np.testing.assert_allclose(out["x"], data["x"] - 0.1, rtol=1e-12, atol=1e-12)
    f = write_recording(Recording(data, fs=10.0, units={c: "V" for c in "xyz"}), tmp_path / "v.csv",
                        units_in_header=True)
    r = cli("triaxial", "apply", f, "--params", params, "--channels", "x,y,z", "--out", tmp_path / "ov.csv")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "is in 'V' (a voltage) but the sensor was calibrated in 'm/s^2' (an acceleration)" in r.err


@pytest.mark.parametrize("text,fragment", [
    ("1,5", "decimal comma"), ("1e400", "beyond the range"), ("1e308 g", "beyond the range"), ("nan", "a number"),
    ("0x10", "not a unit"),
])
def test_option_quantities_refuse_in_one_line(text, fragment):
    with pytest.raises(InputError) as exc:
        parse_quantity(text, "m/s^2", option="--a")
    assert fragment in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(InputError, match="finite"):
        parse_quantity(float("inf"), "m/s^2", option="--a")


_TOKENS = ["m", "s", "V", "mV", "g", "deg", "^", "-2", "2", "**", "/", "(", ")", " ", "1e308", "999999", "nan",
           "degC", "%", "kg", "e", "0.5", "-", "rad", "Hz", "rpm", "\u202e", "\x00", "\u00b2", "\u00b5"]


@given(st.one_of(st.text(max_size=14), st.lists(st.sampled_from(_TOKENS), max_size=8).map("".join)))
def test_any_text_is_a_unit_or_a_one_line_refusal(text):
    """Header and option text is hostile: pint's own exceptions (overflow, syntax) never escape."""
    for call in (lambda: factor(text, "V"), lambda: factor("m/s^2", text), lambda: factor(text, text),
                 lambda: unit_factor(text, "nT", what="x", fix="y"), lambda: parse_quantity(f"1 {text}", "m", option="--o")):
        try:
            call()
        except InputError as exc:
            assert "\n" not in str(exc).replace(text, "")
    assert isinstance(same_unit(text, "m"), bool) and isinstance(compatible(text, "V"), bool)
