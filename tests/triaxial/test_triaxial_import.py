"""`senscal triaxial import`: a third-party calibration in the plain form (matrix A and offset B of A h + B)
becomes a senscal parameter file whose `apply` gives the tool's own corrected values.

The QMC5883L authors publish their Dorveaux calibration as 12 numbers (tests/data, credit beside it); applied
to the readings after the 60 s static start it gives a field-norm spread of about 3.9 % (shared data README)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from senscal.errors import FileFormatError, InputError
from senscal.triaxial import load_calibration
from senscal.triaxial.models import from_third_party, parse_plain_parameters

DATA = Path(__file__).resolve().parents[1] / "data"
PARAMS = DATA / "mag_tomisuarez2_authors_parameters.csv"


def _qmc():
    d = pd.read_csv(DATA / "mag_tomisuarez2_qmc5883l_dec5.csv", skiprows=2)
    return d[["mx", "my", "mz"]].to_numpy(float).T[:, 600:]  # 10 Hz after decimation: 60 s = 600 rows


def test_authors_parameters_round_trip_through_the_cli(cli, tmp_path):
    out = tmp_path / "qmc.json"
    r = cli("triaxial", "import", PARAMS, "--out", out, "--unit", "", "--channels", "mx,my,mz")
    assert r.code == 0, r.err
    cal = load_calibration(out)
    assert cal.model == "imported" and cal.method == "affine" and cal.channels == ("mx", "my", "mz")
    raw = np.loadtxt(PARAMS)
    a, b = raw[:9].reshape(3, 3), raw[9:]
    h = _qmc()
    # senscal's apply gives the authors' own A h + B, to rounding.
    np.testing.assert_allclose(cal.apply(h), a @ h + b[:, None], rtol=0, atol=1e-12)
    n = np.linalg.norm(cal.apply(h), axis=0)
    assert 100 * n.std() / n.mean() == pytest.approx(3.9, abs=0.2)
    # `triaxial apply` reads the imported file like any other.
    rec = tmp_path / "corr.csv"
    r = cli("triaxial", "apply", DATA / "mag_tomisuarez2_qmc5883l_dec5.csv", "--params", out,
            "--channels", "mx,my,mz", "--out", rec, "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["field"] == 1.0


def test_centred_form_and_layouts():
    a = np.array([[1.1, 0.02, 0.0], [0.0, 0.9, 0.01], [0.0, 0.0, 1.0]])
    b = np.array([3.0, -2.0, 1.0])
    text = "# A row by row\n1.1, 0.02, 0\n0 0.9 0.01\n0;0;1\n3 -2 1\n"
    a2, b2 = parse_plain_parameters(text)
    np.testing.assert_array_equal(a2, a)
    np.testing.assert_array_equal(b2, b)
    cal = from_third_party(a, b, form="centred")
    h = np.random.default_rng(0).normal(size=(3, 5))
    np.testing.assert_allclose(cal.apply(h), a @ (h - b[:, None]), atol=1e-12)


@pytest.mark.parametrize("text, msg", [("1 2 3", "holds 3 numbers"), ("1 2 x 4 5 6 7 8 9 10 11 12", "'x'"),
                                       ("0 0 0 0 0 0 0 0 0 1 2 3", None)])
def test_bad_plain_files_are_one_line(text, msg):
    with pytest.raises((FileFormatError, InputError)) as e:
        a, b = parse_plain_parameters(text)
        from_third_party(a, b)
    assert "\n" not in str(e.value)
    if msg:
        assert msg in str(e.value)
    else:
        assert "singular" in str(e.value)


def test_cli_refuses_overwriting_its_input_and_unknown_form(cli, tmp_path):
    p = tmp_path / "p.txt"
    p.write_text(PARAMS.read_text())
    r = cli("triaxial", "import", p, "--out", p)
    assert r.code == 2 and "refusing to overwrite" in r.err
    assert p.read_text() == PARAMS.read_text()
    r = cli("triaxial", "import", p, "--out", tmp_path / "o.json", "--form", "weird")
    assert r.code == 2 and "affine" in r.err
    r = cli("triaxial", "import", tmp_path / "missing.txt", "--out", tmp_path / "o.json")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
