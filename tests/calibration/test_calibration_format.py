"""One saved-calibration format: type + format_version, JSON or real HDF5, one loader, apply().

The files in ``data/`` were written by senscal before this format (version 1:
shaft models tagged ``kind``, triaxial files ``format``, a response saved to
``.h5`` as JSON text); they must keep loading.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import senscal
from senscal.errors import FileFormatError, InputError
from senscal.persist import FORMAT_VERSION, TYPES, read_document
from senscal.shaft import GravityModel, load_model
from senscal.triaxial import TriaxialCalibration, load_calibration as load_triaxial
from senscal.vibration import FrequencyResponse, load_response, save_response

DATA = Path(__file__).with_name("data")
LEGACY = {
    "shaft_model_v1.json": GravityModel,
    "triaxial_params_v1.json": TriaxialCalibration,   # 'triaxial calibrate --out': the report, calibration inside
    "triaxial_cal_api_v1.json": TriaxialCalibration,  # TriaxialCalibration.save: flat
    "response_v1.json": FrequencyResponse,
    "response_v1.h5": FrequencyResponse,              # JSON text in a .h5 file
}


def _save(obj, path):
    return save_response(obj, path) if isinstance(obj, FrequencyResponse) else obj.save(path)


@pytest.mark.parametrize("name", sorted(LEGACY))
def test_version_1_files_load_as_their_type(name):
    obj = senscal.load_calibration(DATA / name)
    assert type(obj) is LEGACY[name]


@pytest.mark.parametrize("name", sorted(LEGACY))
def test_version_1_without_format_version_still_loads(name, tmp_path):
    doc = json.loads((DATA / name).read_text())
    doc.pop("format_version", None)
    if isinstance(doc.get("calibration"), dict):
        doc["calibration"].pop("format_version", None)
    p = tmp_path / "old.json"
    p.write_text(json.dumps(doc))
    assert senscal.load_calibration(p).to_dict() == senscal.load_calibration(DATA / name).to_dict()


@pytest.mark.parametrize("name", sorted(LEGACY))
@pytest.mark.parametrize("suffix", [".json", ".h5", ".hdf5"])
def test_round_trip_json_and_real_hdf5(name, suffix, tmp_path):
    obj = senscal.load_calibration(DATA / name)
    p = _save(obj, tmp_path / f"cal{suffix}")
    head = p.read_bytes()[:8]
    if suffix == ".json":
        doc = json.loads(p.read_text())
    else:
        import h5py

        assert head == b"\x89HDF\r\n\x1a\n"  # a real HDF5 file, not JSON text
        with h5py.File(p) as fh:
            doc = {k: fh.attrs[k] for k in ("type", "format_version")}
    assert doc["type"] in TYPES and TYPES[doc["type"]][1] == LEGACY[name].__name__
    assert int(doc["format_version"]) == FORMAT_VERSION
    back = senscal.load_calibration(p)
    assert type(back) is type(obj) and back.to_dict() == obj.to_dict()
    # The HDF5 file holds the same document as the JSON one.
    if suffix != ".json":
        assert read_document(p) == json.loads(_save(obj, tmp_path / "same.json").read_text())


def test_hdf5_layout_is_readable_without_senscal(tmp_path):
    import h5py

    cal = senscal.load_calibration(DATA / "triaxial_cal_api_v1.json")
    p = cal.save(tmp_path / "cal.h5")
    with h5py.File(p) as fh:
        m = fh["calibration/matrix"][()]
        assert fh.attrs["type"] == "senscal.triaxial.TriaxialCalibration"
    np.testing.assert_array_equal(m, cal.matrix)


def test_specific_loaders_refuse_other_types(tmp_path):
    with pytest.raises(FileFormatError, match="not a senscal shaft gravity model.*holds a triaxial calibration"):
        load_model(DATA / "triaxial_cal_api_v1.json")
    with pytest.raises(FileFormatError, match="not a senscal triaxial calibration.*holds a frequency response"):
        load_triaxial(DATA / "response_v1.h5")
    with pytest.raises(FileFormatError, match="not a senscal frequency response.*holds a shaft gravity model"):
        load_response(DATA / "shaft_model_v1.json")


def _one_line(exc_info, *fragments):
    msg = str(exc_info.value)
    assert "\n" not in msg
    for f in fragments:
        assert f in msg, msg


def test_newer_version_unknown_type_and_corrupt_files_say_what_to_do(tmp_path):
    cal = senscal.load_calibration(DATA / "shaft_model_v1.json")
    p = cal.save(tmp_path / "m.json")
    doc = json.loads(p.read_text())
    newer = tmp_path / "newer.json"
    newer.write_text(json.dumps({**doc, "format_version": FORMAT_VERSION + 1}))
    with pytest.raises(FileFormatError) as e:
        senscal.load_calibration(newer)
    _one_line(e, str(newer), f"format version {FORMAT_VERSION + 1}", "upgrade senscal")
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"type": "imucal.FerrarisCalibrationInfo", "format_version": 1}))
    with pytest.raises(FileFormatError) as e:
        senscal.load_calibration(other)
    _one_line(e, str(other), "not a senscal calibration", "imucal.FerrarisCalibrationInfo")
    bad = tmp_path / "bad.json"
    bad.write_text('{"type": "senscal.shaft.GravityModel", ')
    with pytest.raises(FileFormatError) as e:
        senscal.load_calibration(bad)
    _one_line(e, str(bad), "not valid JSON")
    h5 = cal.save(tmp_path / "m.h5")
    cut = tmp_path / "cut.h5"
    cut.write_bytes(h5.read_bytes()[:300])
    with pytest.raises(FileFormatError) as e:
        senscal.load_calibration(cut)
    _one_line(e, str(cut), "damaged HDF5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"\x00\x01binary")
    with pytest.raises(FileFormatError) as e:
        senscal.load_calibration(junk)
    _one_line(e, str(junk), "neither an HDF5 file nor JSON")
    damaged = tmp_path / "damaged.json"
    damaged.write_text(json.dumps({"type": "senscal.triaxial.TriaxialCalibration", "format_version": 2,
                                   "calibration": {"model": "full", "method": "ml", "matrix": [[1, 0], [0, 1]],
                                                   "offsets": [0, 0, 0], "field": 1.0}}))
    with pytest.raises(FileFormatError, match="malformed matrix"):
        senscal.load_calibration(damaged)
    with pytest.raises(FileFormatError, match="not found"):
        senscal.load_calibration(tmp_path / "missing.h5")


def test_cli_refuses_a_calibration_of_another_type_in_one_line(cli, tmp_path):
    from senscal.io import Recording, write_recording

    f = write_recording(Recording({"x": [1.0, 2], "y": [0.0, 1], "z": [3.0, 1]}, fs=1.0), tmp_path / "r.csv")
    r = cli("triaxial", "apply", f, "--params", DATA / "shaft_model_v1.json", "--channels", "x,y,z",
            "--out", tmp_path / "o.csv")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "shaft_model_v1.json is not a senscal triaxial calibration" in r.err


# --- apply() -------------------------------------------------------------------

def test_triaxial_apply_inverts_the_sensor_model_and_checks_units():
    cal = senscal.load_calibration(DATA / "triaxial_cal_api_v1.json")
    rng = np.random.default_rng(3)
    h = rng.normal(size=(3, 50)) * 5e4
    raw = cal.matrix @ h + cal.offsets[:, None]
    np.testing.assert_allclose(cal.apply(raw), h, rtol=1e-10, atol=1e-6)
    with_unit = TriaxialCalibration(model=cal.model, method=cal.method, matrix=cal.matrix, offsets=cal.offsets,
                                    field=cal.field, unit="m/s^2")
    np.testing.assert_array_equal(with_unit.apply(raw, unit="m/s²"), cal.apply(raw))
    np.testing.assert_array_equal(with_unit.apply(raw, unit="m s-2"), cal.apply(raw))
    # Another scale of the same dimension is converted (g -> m/s^2), another dimension refused.
    np.testing.assert_allclose(with_unit.apply(raw / 9.80665, unit="g"), cal.apply(raw), rtol=1e-12)
    with pytest.raises(InputError, match="'V' \\(a voltage\\) but the sensor was calibrated in 'm/s\\^2'"):
        with_unit.apply(raw, unit="V")


def test_shaft_apply_leaves_the_non_gravity_acceleration():
    model = senscal.load_calibration(DATA / "shaft_model_v1.json")
    theta = np.linspace(0.0, 40 * np.pi, 2000)
    a_true = 0.3 * np.sin(0.7 * theta)
    accel = model.sensitivity * a_true + model.gravity(theta)
    np.testing.assert_allclose(model.apply(accel, theta), a_true, atol=1e-12)
    np.testing.assert_allclose(model.apply(accel, np.degrees(theta), angle_unit="deg", unit="m/s²"), a_true,
                               atol=1e-9)
    with pytest.raises(InputError, match="calibrated in 'm/s\\^2'"):
        model.apply(accel, theta, unit="mV")


def test_response_apply_interpolates_between_points_and_refuses_outside():
    resp = senscal.load_calibration(DATA / "response_v1.json")
    f, s, u = resp.frequency, resp.sensitivity, resp.u_sensitivity
    for fi, si, ui in zip(f, s, u):
        assert resp.sensitivity_at(fi) == pytest.approx((si, ui), rel=1e-12)
    # Half-way in log frequency between two points: half-way between their sensitivities.
    mid = float(np.sqrt(f[1] * f[2]))
    s_mid, _ = resp.sensitivity_at(mid)
    assert s_mid == pytest.approx(0.5 * (s[1] + s[2]), rel=1e-12)
    amplitude = np.array([1.0, 2.5])
    np.testing.assert_allclose(resp.apply(amplitude * s_mid, mid, unit="V"), amplitude, rtol=1e-12)
    dev, u_dev = resp.compare(1.01 * s[2], f[2])
    assert dev == pytest.approx(0.01, rel=1e-9) and u_dev == pytest.approx(u[2] / s[2])
    with pytest.raises(InputError, match="outside the calibrated range"):
        resp.sensitivity_at(2 * f.max())
    np.testing.assert_allclose(resp.apply(1e3 * amplitude * s_mid, mid, unit="mV"), amplitude, rtol=1e-12)
    with pytest.raises(InputError, match="'m/s' \\(a velocity\\) but the sensor was calibrated in 'V'"):
        resp.apply(amplitude, mid, unit="m/s")


def test_old_h5_response_converts_to_a_real_hdf5_file(tmp_path):
    work = tmp_path / "resp.h5"
    shutil.copy(DATA / "response_v1.h5", work)
    assert work.read_bytes()[:1] == b"{"
    resp = load_response(work)
    save_response(resp, work)
    assert work.read_bytes()[:4] == b"\x89HDF"
    assert load_response(work).to_dict() == resp.to_dict()


def _response_with(template, sens, u_a, u_b):
    """The template's points with new sensitivities and budgets (type A own, type B 'input amplitude')."""
    from dataclasses import replace

    from senscal.vibration.budget import make_budget

    pts = []
    for p, s, ua, ub in zip(template.points, sens, u_a, u_b):
        b = make_budget("sensitivity", s, template.unit, [("output fit (type A)", "A", ua), ("input amplitude", "B", ub)])
        pts.append(replace(p, sensitivity=float(s), u_sensitivity=b.combined, sensitivity_budget=b))
    return replace(template, points=tuple(pts))


def test_interpolated_sensitivity_uncertainty_covers_95_percent():
    """Monte Carlo: between two points, |S(f) - truth| <= 2 u(S(f)) in 95 % of calibrations.

    Each simulated calibration has independent type A noise per point and one common input-amplitude
    error (type B, the same reference for every point); the truth is linear in log frequency, so any
    miss is the uncertainty's, not the interpolation's.
    """
    from senscal.validation import check_coverage, coverage_row, mc_seeds

    template = senscal.load_calibration(DATA / "response_v1.json")
    f = template.frequency
    truth = 0.05 * (1.0 + 0.01 * np.log(f / f[0]))
    u_a = truth * np.array([4e-4, 1e-4, 2.5e-4, 6e-4])[: f.size]
    u_rel_b = 3e-4
    rng = np.random.default_rng(20261123)
    rows = []
    for case, (lo, hi) in {"A and B": (1, 2), "A only": (2, 3)}.items():
        n = mc_seeds(2000, 400)
        mids = np.exp(np.linspace(np.log(f[lo]), np.log(f[hi]), 5)[1:-1])
        est, u, tr = [], [], []
        for _ in range(n):
            b = u_rel_b if case == "A and B" else 0.0
            meas = truth * (1.0 + b * rng.standard_normal()) + u_a * rng.standard_normal(f.size)
            resp = _response_with(template, meas, u_a, truth * b)
            for fm in mids:
                s, us = resp.sensitivity_at(fm)
                est.append(s)
                u.append(us)
                tr.append(0.05 * (1.0 + 0.01 * np.log(fm / f[0])))
        rows.append(coverage_row("response", case, "sensitivity_at", est, u, tr))
    check_coverage(rows)
