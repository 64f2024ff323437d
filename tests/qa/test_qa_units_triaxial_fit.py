"""Units of ``triaxial apply`` as quantities, and ``fit`` refusing a time column beyond the fits' float64 range.

``triaxial apply`` converts data to the saved calibration's unit when both state one (uT data, nT calibration;
g data, m/s^2 calibration), refuses another dimension in one line (exit 2), names a unit stated on one side
only (``triaxial-units-assumed``, --strict exits 3) and writes ``name [unit]`` headers.  ``fit`` on a time
column scaled by 1e300 was an internal error (LinAlgError in the sine fit's solver); it is refused in one line
by the 1e150 rule of :mod:`senscal.jobs._units` (exit 2).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

G0 = 9.80665
XYZ = ("x", "y", "z")


def _write(rec, path, *, unit=None, scale=1.0):
    """The three field channels of ``rec`` as CSV, times ``scale``, headed ``x [unit]`` (bare names for None)."""
    df = pd.DataFrame({"t": rec.time})
    for c in XYZ:
        df[c if unit is None else f"{c} [{unit}]"] = np.asarray(rec[c]) * scale
    df.to_csv(path, index=False, float_format="%.17g")
    return path


def _corrected(path, unit):
    return pd.read_csv(path)[[f"{c} [{unit}]" for c in XYZ]].to_numpy()


@pytest.fixture(scope="module")
def mag():
    from senscal.simulate.triaxial import simulate_magnetometer

    return simulate_magnetometer(seed=1)[0]  # field 50000 (nT), readings without units


def _calibrate(cli, path, out):
    r = cli("triaxial", "calibrate", path, "--channels", "x,y,z", "--out", out)
    assert r.code == 0, r.err
    return out


def test_triaxial_apply_converts_units_names_one_side_and_writes_them(cli, mag, tmp_path):
    nt = _write(mag, tmp_path / "nt.csv", unit="nT")
    cal_nt = _calibrate(cli, nt, tmp_path / "cal_nt.json")
    r = cli("triaxial", "apply", nt, "--params", cal_nt, "--channels", "x,y,z", "--out", tmp_path / "o_nt.csv",
            "--strict")
    assert r.code == 0, r.err
    ref = _corrected(tmp_path / "o_nt.csv", "nT")  # the header carries the unit
    assert np.median(np.linalg.norm(ref, axis=1)) == pytest.approx(50000, rel=0.01)
    # the same field in uT (and in G): converted to the calibration's nT, no warning
    for unit, k in (("uT", 1e-3), ("G", 1e-5)):
        p = _write(mag, tmp_path / f"{unit}.csv", unit=unit, scale=k)
        o = tmp_path / f"o_{unit}.csv"
        r = cli("triaxial", "apply", p, "--params", cal_nt, "--channels", "x,y,z", "--out", o, "--strict")
        assert r.code == 0, (unit, r.err)
        np.testing.assert_allclose(_corrected(o, "nT"), ref, rtol=1e-9, atol=1e-6)
    # uT data without their unit against the nT calibration: read as nT (a factor of 1000), so named
    bare = _write(mag, tmp_path / "bare_ut.csv", scale=1e-3)
    r = cli("triaxial", "apply", bare, "--params", cal_nt, "--channels", "x,y,z", "--out", tmp_path / "o_b.csv")
    assert r.code == 0 and "triaxial-units-assumed" in r.err and "x,y,z without a unit" in r.err, r.err
    r = cli("triaxial", "apply", bare, "--params", cal_nt, "--channels", "x,y,z", "--out", tmp_path / "o_b2.csv",
            "--strict")
    assert r.code == 3 and "triaxial-units-assumed" in r.err and "Traceback" not in r.err
    assert _corrected(tmp_path / "o_b2.csv", "nT").shape == ref.shape  # written first, for inspection
    # a calibration without a unit applied to data that state one: named the other way round
    cal_bare = _calibrate(cli, _write(mag, tmp_path / "bare.csv"), tmp_path / "cal_bare.json")
    r = cli("triaxial", "apply", tmp_path / "uT.csv", "--params", cal_bare, "--channels", "x,y,z",
            "--out", tmp_path / "o_c.csv", "--strict")
    assert r.code == 3 and "x,y,z in uT read as the calibration's unknown unit" in r.err
    # another dimension: one line, exit 2, nothing written
    ms2 = _write(mag, tmp_path / "ms2.csv", unit="m/s^2")
    r = cli("triaxial", "apply", ms2, "--params", cal_nt, "--channels", "x,y,z", "--out", tmp_path / "o_d.csv")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "m/s^2" in r.err and "nT" in r.err, r.err
    assert not (tmp_path / "o_d.csv").exists()


def test_triaxial_apply_accelerometer_in_g(cli, tmp_path):
    from senscal.simulate.triaxial import simulate_magnetometer

    acc = simulate_magnetometer(motion="tumble", seed=2)[0]  # field 9.80665 (m/s^2)
    p = _write(acc, tmp_path / "ms2.csv", unit="m/s^2")
    cal = tmp_path / "cal.json"
    r = cli("triaxial", "calibrate", p, "--channels", "x,y,z", "--static", "--out", cal)
    assert r.code == 0, r.err
    outs = []
    for unit, k in (("m/s^2", 1.0), ("g", 1 / G0)):
        q = _write(acc, tmp_path / f"a_{unit[0]}.csv", unit=unit, scale=k)
        o = tmp_path / f"o_{unit[0]}.csv"
        r = cli("triaxial", "apply", q, "--params", cal, "--channels", "x,y,z", "--out", o, "--strict")
        assert r.code == 0, (unit, r.err)
        outs.append(_corrected(o, "m/s^2"))
    np.testing.assert_allclose(outs[1], outs[0], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("scale", [1e300, 1e160])
def test_fit_time_column_beyond_float_range_is_one_line(cli, tmp_path, scale):
    t = np.arange(1000) / 1000.0
    y = np.sin(2 * np.pi * 12.5 * t) + 0.01 * np.random.default_rng(0).normal(size=t.size)
    p = tmp_path / "big_t.csv"
    pd.DataFrame({"t": t * scale, "ch1": y}).to_csv(p, index=False, float_format="%.17g")
    for extra in ((), ("--freq", "1")):
        r = cli("fit", p, *extra)
        assert r.code == 2, r.err
        assert len(r.err.strip().splitlines()) == 1 and "time column" in r.err and "1e150" in r.err, r.err
        assert "internal error" not in r.err and "Traceback" not in r.err


def test_triaxial_apply_names_a_corrected_field_no_place_on_earth_explains(cli, mag, tmp_path):
    """A corrected field 100x the calibration's (data mislabelled, or another sensor's file) is named; a field
    half or twice the calibration's (another place: the geomagnetic field spans 22-67 uT) is not."""
    nt = _write(mag, tmp_path / "nt.csv", unit="nT")
    cal = _calibrate(cli, nt, tmp_path / "cal.json")
    for k, named in ((0.5, False), (2.0, False), (0.01, True), (100.0, True)):
        p = _write(mag, tmp_path / f"s{k}.csv", unit="nT", scale=k)
        r = cli("triaxial", "apply", p, "--params", cal, "--channels", "x,y,z", "--out", tmp_path / f"o{k}.csv",
                "--strict")
        if named:
            assert r.code == 3 and "triaxial-field-mismatch" in r.err and "Traceback" not in r.err, (k, r.err)
            assert (tmp_path / f"o{k}.csv").exists()  # written first, for inspection
        else:
            assert r.code == 0 and "triaxial-field-mismatch" not in r.err, (k, r.err)
