"""Units in the header are quantities for ``imu calibrate/apply``, ``primary`` and ``shock``.

The same session written with other units (gyro in deg/s or mrad/s, accelerometer in g or mg,
time in ms or us, temperature in degF or K, output in mV) must give the same result in SI; a unit of
the wrong dimension, or units that cannot be put on one scale across files, is refused in one line
(exit 2); a unit assumed on one side only is a named warning (--strict exits 3).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from senscal.io import Recording, write_recording

G0 = 9.80665


def _relabel(rec: Recording, path, *, scale=None, names=None, t_scale=1.0, t_name="t", offset=None):
    """Write ``rec`` as CSV with each channel multiplied by scale[c] (+ offset[c]) under the header names[c]."""
    scale, names, offset = scale or {}, names or {}, offset or {}
    df = pd.DataFrame({t_name: rec.time * t_scale})
    for c in rec.names:
        df[names.get(c, c)] = rec[c] * scale.get(c, 1.0) + offset.get(c, 0.0)
    df.to_csv(path, index=False, float_format="%.17g")
    return path


@pytest.fixture(scope="module")
def imu_rec():
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=3, n_poses=14, fs=50.0, init_s=10.0)
    return rec


def _calibrate(cli, path, *extra):
    r = cli("imu", "calibrate", path, "--json", *extra)
    assert r.code == 0, r.err
    return json.loads(r.out)


def test_imu_calibrate_units_in_header_are_quantities(cli, imu_rec, tmp_path):
    si = {c: f"{c} [{u}]" for c, u in imu_rec.units.items()}
    ref = _calibrate(cli, _relabel(imu_rec, tmp_path / "si.csv", names=si, t_name="t [s]"))
    d2r = math.pi / 180
    variants = {
        "deg/s, time in ms": dict(scale={g: 1 / d2r for g in ("gx", "gy", "gz")}, t_scale=1e3, t_name="t [ms]",
                                  names={**si, **{g: f"{g} [deg/s]" for g in ("gx", "gy", "gz")}}),
        "g, mrad/s, time in us": dict(scale={**{a: 1 / G0 for a in ("ax", "ay", "az")},
                                             **{g: 1e3 for g in ("gx", "gy", "gz")}},
                                      t_scale=1e6, t_name="t [us]",
                                      names={**{a: f"{a} [g]" for a in ("ax", "ay", "az")},
                                             **{g: f"{g} [mrad/s]" for g in ("gx", "gy", "gz")}}),
    }
    for label, kw in variants.items():
        doc = _calibrate(cli, _relabel(imu_rec, tmp_path / "v.csv", **kw))
        g, g0 = doc["gyroscope"], ref["gyroscope"]
        assert g["scale_unit"] == "rad/s per rad/s" and g["bias_unit"] == "rad/s", label
        np.testing.assert_allclose(g["scale"], g0["scale"], rtol=1e-7, err_msg=label)
        np.testing.assert_allclose(g["bias"], g0["bias"], rtol=1e-6, atol=1e-12, err_msg=label)
        np.testing.assert_allclose(g["u_scale"], g0["u_scale"], rtol=1e-5, err_msg=label)
        a, a0 = doc["accelerometer"], ref["accelerometer"]
        k = 1 / G0 if a["bias_unit"] == "g" else 1.0  # the accelerometer is quoted in its reading's unit
        np.testing.assert_allclose(a["scale"], np.multiply(a0["scale"], k), rtol=1e-7, err_msg=label)
        np.testing.assert_allclose(a["bias"], np.multiply(a0["bias"], k), rtol=1e-6, err_msg=label)
        # the still start's noise in SI whatever the file's units; the residuals in deg likewise
        np.testing.assert_allclose(doc["noise"]["gyro_noise_density"], ref["noise"]["gyro_noise_density"], rtol=1e-6)
        assert doc["gravity_direction_residual_deg"]["rms_before"] == pytest.approx(
            ref["gravity_direction_residual_deg"]["rms_before"], rel=1e-6), label


def test_imu_triad_in_the_wrong_dimension_is_refused(cli, imu_rec, tmp_path):
    si = {c: f"{c} [{u}]" for c, u in imu_rec.units.items()}
    p = _relabel(imu_rec, tmp_path / "si.csv", names=si)
    r = cli("imu", "calibrate", p, "--accel-channels", "gx,gy,gz", "--gyro-channels", "ax,ay,az")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "swapped --accel-channels and --gyro-channels" in r.err and "Traceback" not in r.err
    p = _relabel(imu_rec, tmp_path / "m.csv", names={**si, **{a: f"{a} [uT]" for a in ("ax", "ay", "az")}})
    r = cli("imu", "calibrate", p)
    assert r.code == 2 and "a magnetic flux density" in r.err and len(r.err.strip().splitlines()) == 1


@pytest.fixture(scope="module")
def imu_temp_rec():
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=2, n_poses=16, fs=50.0, init_s=10.0, temperature=(20.0, 35.0),
                          gyro_bias_tc=(1e-4, 0.0, 0.0))
    return rec


def test_imu_temperature_unit_is_a_quantity(cli, imu_temp_rec, tmp_path):
    """degF or K data give the degC calibration; apply converts the data's temperature to the calibration's."""
    rec = imu_temp_rec
    names = {c: f"{c} [{u}]" for c, u in rec.units.items() if c != "temp"}
    pc = _relabel(rec, tmp_path / "c.csv", names={**names, "temp": "temp [degC]"})
    pf = _relabel(rec, tmp_path / "f.csv", names={**names, "temp": "temp [degF]"}, scale={"temp": 1.8},
                  offset={"temp": 32.0})
    pk = _relabel(rec, tmp_path / "k.csv", names={**names, "temp": "temp [K]"}, offset={"temp": 273.15})
    dc = _calibrate(cli, pc, "--temperature-channel", "temp", "--out", tmp_path / "cal_c.json")
    df = _calibrate(cli, pf, "--temperature-channel", "temp")
    te_c, te_f = dc["temperature"], df["temperature"]
    assert te_f["unit"] == "degC" and te_f["reference"] == pytest.approx(te_c["reference"], rel=1e-9)
    assert te_f["gyroscope"]["degree"] == te_c["gyroscope"]["degree"] >= 1
    np.testing.assert_allclose(te_f["gyroscope"]["bias"], te_c["gyroscope"]["bias"], rtol=1e-6, atol=1e-12)
    outs = {}
    for label, p in (("degC", pc), ("degF", pf), ("K", pk)):
        o = tmp_path / f"out_{label}.csv"
        r = cli("imu", "apply", p, "--params", tmp_path / "cal_c.json", "--out", o, "--strict")
        assert r.code == 0, r.err
        outs[label] = pd.read_csv(o)[["gx [rad/s]", "gy [rad/s]", "gz [rad/s]"]].to_numpy()
    np.testing.assert_allclose(outs["degF"], outs["degC"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(outs["K"], outs["degC"], rtol=0, atol=1e-12)


def test_imu_apply_unit_on_one_side_only_is_named(cli, imu_rec, tmp_path):
    """A calibration from a deg/s file applied to a file without units reads them as rad/s: named, --strict 3."""
    d2r = math.pi / 180
    gy = ("gx", "gy", "gz")
    p = _relabel(imu_rec, tmp_path / "degs.csv", scale={g: 1 / d2r for g in gy},
                 names={**{c: f"{c} [{u}]" for c, u in imu_rec.units.items()}, **{g: f"{g} [deg/s]" for g in gy}})
    r = cli("imu", "calibrate", p, "--out", tmp_path / "cal.json")
    assert r.code == 0, r.err
    # the same data in deg/s with the unit stated: converted, no warning
    r = cli("imu", "apply", p, "--params", tmp_path / "cal.json", "--out", tmp_path / "o1.csv", "--strict")
    assert r.code == 0, r.err
    bare = _relabel(imu_rec, tmp_path / "bare.csv", scale={g: 1 / d2r for g in gy})
    r = cli("imu", "apply", bare, "--params", tmp_path / "cal.json", "--out", tmp_path / "o2.csv", "--strict")
    assert r.code == 3 and "imu-units-assumed" in r.err and "gx,gy,gz without a unit" in r.err
    assert "Traceback" not in r.err


# --- primary --------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def pri_recs():
    from senscal.simulate.interferometer import simulate_interferometer

    return [simulate_interferometer(freq=f, fs=50_000.0, duration=0.1, seed=8 + i)[0]
            for i, f in enumerate((160.0, 1000.0))]


def test_primary_output_units_across_files(cli, pri_recs, tmp_path):
    a = _relabel(pri_recs[0], tmp_path / "a.csv", names={"out": "out [V]"})
    b_mv = _relabel(pri_recs[1], tmp_path / "b_mv.csv", names={"out": "out [mV]"}, scale={"out": 1e3})
    b_v = _relabel(pri_recs[1], tmp_path / "b_v.csv", names={"out": "out [V]"})
    docs = []
    for b in (b_v, b_mv):
        r = cli("primary", a, b, "--json")
        assert r.code == 0, r.err
        docs.append(json.loads(r.out))
    assert docs[1]["sensitivity_unit"] == "V per m/s^2"
    np.testing.assert_allclose([p["sensitivity"] for p in docs[1]["points"]],
                               [p["sensitivity"] for p in docs[0]["points"]], rtol=1e-9)
    np.testing.assert_allclose([p["u_sensitivity"] for p in docs[1]["points"]],
                               [p["u_sensitivity"] for p in docs[0]["points"]], rtol=1e-6)
    bare = _relabel(pri_recs[1], tmp_path / "bare.csv")
    r = cli("primary", a, bare)
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "in every file's header" in r.err


def test_primary_time_in_ms_and_output_unit_contradiction(cli, pri_recs, tmp_path):
    from senscal.errors import InputError
    from senscal.jobs.primary import primary

    s = _relabel(pri_recs[0], tmp_path / "s.csv", names={"out": "out [mV]"}, scale={"out": 1e3})
    ms = _relabel(pri_recs[0], tmp_path / "ms.csv", names={"out": "out [mV]"}, scale={"out": 1e3}, t_scale=1e3,
                  t_name="t [ms]")
    d = [json.loads(cli("primary", p, "--json").out)["points"][0] for p in (s, ms)]
    assert d[1]["frequency_hz"] == pytest.approx(d[0]["frequency_hz"], rel=1e-9)
    assert d[1]["sensitivity"] == pytest.approx(d[0]["sensitivity"], rel=1e-9)
    res = primary(s)
    assert res.response("mV").unit == "mV/(m/s^2)"
    with pytest.raises(InputError, match="--output-unit V contradicts"):
        res.response("V")


# --- shock ----------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def shock_rec():
    from senscal.simulate.shock import simulate_shock

    return simulate_shock(duration_ms=1.0, peak=1000.0, seed=1)[0]


def test_shock_output_and_reference_units_across_files(cli, shock_rec, tmp_path):
    v = _relabel(shock_rec, tmp_path / "v.csv", names={"ref": "ref [V]", "out": "out [V]"})
    mv = _relabel(shock_rec, tmp_path / "mv.csv", names={"ref": "ref [mV]", "out": "out [mV]"},
                  scale={"ref": 1e3, "out": 1e3})
    r = cli("shock", v, mv, "--reference", "ref", "--reference-sensitivity", "1e-4 V/(m/s^2)", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    s = [p["sensitivity"] for p in doc["pulses"]]
    assert doc["sensitivity_unit"] == "V per m/s^2" and s[1] == pytest.approx(s[0], rel=1e-9)
    # a bare reference sensitivity is in the first file's reference unit, for every file
    r = cli("shock", mv, v, "--reference", "ref", "--reference-sensitivity", "0.1", "--json")
    doc = json.loads(r.out)
    s2 = [p["sensitivity"] for p in doc["pulses"]]
    assert doc["sensitivity_unit"] == "mV per m/s^2" and s2 == pytest.approx([1e3 * s[0]] * 2, rel=1e-9)
    bare = _relabel(shock_rec, tmp_path / "bare.csv")
    r = cli("shock", v, bare, "--reference", "ref", "--reference-sensitivity", "1e-4")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "in every file's header" in r.err
    r = cli("shock", bare, "--reference", "ref", "--reference-sensitivity", "0.1 mV/(m/s^2)", "--strict")
    assert r.code == 3 and "reference-unit-assumed" in r.err


def test_primary_quadrature_pair_in_one_unit(cli, pri_recs, tmp_path):
    """Q in mV beside I in V: converted, so the Heydemann gain ratio and offsets are the interferometer's."""
    v = _relabel(pri_recs[0], tmp_path / "v.csv", names={"I": "I [V]", "Q": "Q [V]", "out": "out [V]"})
    mv = _relabel(pri_recs[0], tmp_path / "qmv.csv", names={"I": "I [V]", "Q": "Q [mV]", "out": "out [V]"},
                  scale={"Q": 1e3})
    h = [json.loads(cli("primary", p, "--json").out)["points"][0]["heydemann"] for p in (v, mv)]
    assert h[1]["gain_ratio"] == pytest.approx(h[0]["gain_ratio"], rel=1e-9)
    assert h[1]["offset_q"] == pytest.approx(h[0]["offset_q"], rel=1e-9)
    bad = _relabel(pri_recs[0], tmp_path / "qacc.csv", names={"I": "I [V]", "Q": "Q [m/s^2]", "out": "out [V]"})
    r = cli("primary", bad)
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "one interferometer" in r.err
