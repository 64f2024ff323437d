"""Units compared as units: spellings of one unit agree, other units (or scales) never do."""

from __future__ import annotations

import re

import numpy as np
import pytest

from senscal.errors import InputError
from senscal.persist.units import canonical_unit, check_unit, numerator, parse_unit, same_unit

SAME = [
    ("m/s^2", "m/s²"), ("m/s^2", "m s-2"), ("m/s^2", "m*s**-2"), ("m/s^2", "m.s^-2"), ("m/s^2", "m·s⁻²"),
    ("m/s^2", "m/s/s"), ("m/s^2", " m/s^2 "), ("deg", "°"), ("deg", "degrees"), ("rad/s", "rad s-1"),
    ("V/(m/s^2)", "V s^2/m"), ("V/(m/s^2)", "V s² m⁻¹"), ("V/(m/s)", "V s/m"), ("µT", "uT"), ("μT", "uT"),
    ("Ω", "Ohm"), ("°C", "degC"), ("s", "sec"), ("", "1"),
]
DIFFERENT = [
    ("m/s^2", "g"), ("m/s^2", "m/s"), ("V", "mV"), ("nT", "uT"), ("deg", "rad"), ("V/(m/s^2)", "V/g"),
    ("V/(m/s^2)", "mV/(m/s^2)"), ("m/s^2", "s^2/m"), ("T", "gauss"),
]


@pytest.mark.parametrize("a,b", SAME)
def test_spellings_of_one_unit_are_the_same_unit(a, b):
    assert same_unit(a, b) and same_unit(b, a)
    check_unit(a, b, what="x", fix="y")


@pytest.mark.parametrize("a,b", DIFFERENT)
def test_other_units_and_scales_differ(a, b):
    assert not same_unit(a, b) and not same_unit(b, a)
    with pytest.raises(InputError, match=re.escape(f"is in '{b}' but the sensor was calibrated in")):
        check_unit(b, a, what="channel 'x'", fix="convert it")


def test_unknown_units_pass_and_unparsable_text_compares_as_text():
    check_unit("", "m/s^2", what="x", fix="y")
    check_unit("m/s^2", None, what="x", fix="y")
    assert same_unit("counts ??", "counts ??") and not same_unit("counts ??", "V")


def test_powers_add_up():
    # Symbol order and grouping do not matter; the powers do.
    assert parse_unit("kg m^2 / (s^2 A)") == parse_unit("m m kg/A/s/s") == {"A": -1, "kg": 1, "m": 2, "s": -2}
    assert canonical_unit("m/s^2") == "m s^-2"
    assert numerator("V/(m/s^2)") == "V" and numerator("m/s") == "m" and numerator("V") == "V"


def test_triaxial_apply_cli_compares_units_as_units(cli, tmp_path):
    """A recording in m/s² corrected with a calibration made in m/s^2 is accepted; one in g is refused."""
    from senscal.io import Recording, read_recording, write_recording
    from senscal.triaxial import TriaxialCalibration

    cal = TriaxialCalibration(model="offsets", method="ml", matrix=np.eye(3), offsets=np.array([0.1, -0.2, 0.3]),
                              field=9.80665, unit="m/s^2")
    params = cal.save(tmp_path / "p.json")
    data = {c: np.linspace(-9.0, 9.0, 20) + i for i, c in enumerate("xyz")}
    for unit, code in (("m/s²", 0), ("m s-2", 0), ("g", 2)):
        f = write_recording(Recording(data, fs=10.0, units={c: unit for c in "xyz"}), tmp_path / "r.csv",
                            units_in_header=True)
        r = cli("triaxial", "apply", f, "--params", params, "--channels", "x,y,z", "--out", tmp_path / "o.csv")
        assert r.code == code, r.err
        if code:
            assert "is in 'g' but the sensor was calibrated in 'm/s^2'" in r.err
            assert len(r.err.strip().splitlines()) == 1
        else:
            out = read_recording(tmp_path / "o.csv")
            np.testing.assert_allclose(out["x"], data["x"] - 0.1)
