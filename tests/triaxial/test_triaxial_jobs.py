"""The triaxial jobs (``senscal.jobs.triaxial``): the Python API, the CLI and the registry agree."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal import jobs
from senscal.errors import InputError
from senscal.io import read_recording
from senscal.jobs.triaxial import (TriaxialApplyOptions, TriaxialApplyResult, TriaxialCalibrateOptions,
                                   TriaxialCalibrateResult, triaxial_apply, triaxial_calibrate)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.cli import main

    d = tmp_path_factory.mktemp("trijobs")
    for motion in ("sphere", "planar"):
        try:
            main(["simulate", "magnetometer", "--out", str(d / motion), "--motion", motion, "--seed", "8"])
        except SystemExit as exc:
            assert not exc.code
    return d


def _same_document(a, b):
    """Document ``a`` equals ``b`` exactly: same keys in the same order, every number equal."""
    assert list(a) == list(b)
    assert a == b


@pytest.mark.parametrize("motion, words, opts", [
    ("sphere", ["--field", "50000"], dict(field=50000.0)),
    ("planar", ["--field", "50000", "--outlier-sigma", "0"], dict(field=50000.0, outlier_sigma=0.0)),
    ("sphere", ["--method", "lms", "--epochs", "20"], dict(method="lms", epochs=20)),
])
def test_calibrate_api_equals_cli_json_and_out_file(cli, sim, tmp_path, motion, words, opts):
    f = sim / motion / "magnetometer.csv"
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--json", "--out", tmp_path / "p.json", *words)
    assert r.code == 0, r.err
    res = triaxial_calibrate(f, TriaxialCalibrateOptions(channels="x,y,z", **opts))
    assert isinstance(res, TriaxialCalibrateResult)
    doc = res.to_dict()
    _same_document(doc, json.loads(r.out))
    # The --out parameter file carries the same report and a calibration that corrects the same way.
    from senscal.triaxial import load_calibration

    assert json.loads((tmp_path / "p.json").read_text())["parameters"] == doc["parameters"]
    h = read_recording(f).data(["x", "y", "z"])
    np.testing.assert_allclose(load_calibration(tmp_path / "p.json").apply(h), res.calibration.calibration.apply(h),
                               rtol=1e-12)


def test_quantities_are_the_identified_parameters_the_registry_stores(cli, sim, tmp_path):
    f = sim / "planar" / "magnetometer.csv"
    db = tmp_path / "reg.sqlite"
    r = cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--field", "50000", "--json", "--save",
            "--sensor", "MAG-7", "--create-sensor", "magnetometer", "--db", db)
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    qs = triaxial_calibrate(f, TriaxialCalibrateOptions(field=50000.0)).quantities()
    # What the registry has always stored: each parameter of the document with a value and a u, in its unit.
    want = [(n, p["value"], p["u"], p["unit"]) for n, p in doc["parameters"].items()
            if p["value"] is not None and p["u"] is not None]
    assert [(q.name, q.value, q.uncertainty, q.unit) for q in qs] == want
    assert "alpha_deg" not in {q.name for q in qs}  # unidentifiable on the planar turn: not quoted
    hist = json.loads(cli("registry", "history", "MAG-7", "--db", db, "--json").out)["records"]
    stored = {x["quantity"]: x for x in hist}
    assert set(stored) == {q.name for q in qs}
    for q in qs:
        assert stored[q.name]["unit"] == q.unit
        assert stored[q.name]["value"] == pytest.approx(q.value, rel=1e-12)


def test_angles_are_quoted_in_degrees(sim):
    res = triaxial_calibrate(sim / "sphere" / "magnetometer.csv", TriaxialCalibrateOptions(field=50000.0))
    q = {x.name: x for x in res.quantities()}
    assert q["alpha_deg"].unit == "deg"
    assert q["alpha_deg"].value == pytest.approx(math.degrees(res.calibration.value("alpha")), rel=1e-12)
    df = res.to_dataframe().set_index("parameter")
    assert df.loc["alpha_deg", "U"] == pytest.approx(2 * q["alpha_deg"].uncertainty, rel=1e-12)


def test_apply_api_equals_cli(cli, sim, tmp_path):
    f = sim / "sphere" / "magnetometer.csv"
    params = tmp_path / "p.json"
    assert cli("triaxial", "calibrate", f, "--channels", "x,y,z", "--field", "50000", "--out", params).code == 0
    out = tmp_path / "fixed.csv"
    r = cli("triaxial", "apply", f, "--params", params, "--channels", "x,y,z", "--out", out, "--json")
    assert r.code == 0, r.err
    cli_doc = json.loads(r.out)
    res = jobs.run("triaxial-apply", f, jobs.options("triaxial-apply", params=params, channels=("x", "y", "z")))
    assert isinstance(res, TriaxialApplyResult)
    doc = res.to_dict()
    assert doc.pop("out") is None and cli_doc.pop("out") == str(out)
    _same_document(doc, cli_doc)
    written = read_recording(out)
    for c in ("x", "y", "z"):
        np.testing.assert_allclose(written[c], res.recording[c], rtol=1e-12)
    assert abs(doc["corrected_norm_mean"] - 50000) < 3 * doc["corrected_norm_std"]


def test_apply_with_a_calibration_in_memory(sim):
    f = sim / "sphere" / "magnetometer.csv"
    cal = triaxial_calibrate(f, TriaxialCalibrateOptions(field=50000.0)).calibration.calibration
    res = triaxial_apply(f, TriaxialApplyOptions(params=cal))
    assert res.recording.metadata["triaxial_calibration"].endswith("from <calibration>")
    np.testing.assert_allclose(res.corrected_norm, np.linalg.norm(cal.apply(read_recording(f).data(["x", "y", "z"])),
                                                                  axis=0))


def test_options_builders_match_the_command_words(tmp_path):
    from senscal.cli.cmd_triaxial import JOB_OPTIONS

    o = JOB_OPTIONS["triaxial-calibrate"](channels="a,b,c", field=1.0, static=True, json_out=True, out=None,
                                          plot=None, save=False)
    assert o == TriaxialCalibrateOptions(channels="a,b,c", field=1.0, static=True)
    o = JOB_OPTIONS["triaxial-apply"](params=tmp_path / "p.json", channels="x,y,z", out=tmp_path / "o.csv")
    assert o == TriaxialApplyOptions(params=tmp_path / "p.json", channels="x,y,z")


@pytest.mark.parametrize("job, opts, msg", [
    (triaxial_calibrate, TriaxialCalibrateOptions(channels="x,y"), "--channels needs exactly three"),
    (triaxial_calibrate, TriaxialCalibrateOptions(accel_channels=("x", "y", "z")), "not the calibrated ones"),
    (triaxial_apply, TriaxialApplyOptions(), "needs the calibration"),
    (triaxial_apply, TriaxialApplyOptions(params=1.5), "parameter file or a TriaxialCalibration"),
])
def test_incomplete_options_are_refused(sim, job, opts, msg):
    with pytest.raises(InputError, match=msg):
        job(sim / "sphere" / "magnetometer.csv", opts)


def test_apply_converts_another_scale_and_refuses_another_dimension(sim):
    from senscal.io import Recording

    rec = read_recording(sim / "sphere" / "magnetometer.csv")
    tagged = Recording(channels=rec.channels, t=rec.t, units={c: "nT" for c in "xyz"})
    cal = triaxial_calibrate(tagged, TriaxialCalibrateOptions(field=50000.0)).calibration.calibration
    assert cal.unit == "nT"
    in_nt = triaxial_apply(tagged, TriaxialApplyOptions(params=cal))
    assert in_nt.corrected_norm.size == rec.n_samples
    # The same field in uT (values / 1000) is converted to the calibration's nT: the same correction.
    in_ut = Recording(channels={c: v / 1000.0 for c, v in rec.channels.items()}, t=rec.t,
                      units={c: "uT" for c in "xyz"})
    res = triaxial_apply(in_ut, TriaxialApplyOptions(params=cal))
    np.testing.assert_allclose(res.corrected_norm, in_nt.corrected_norm, rtol=1e-12)
    assert res.recording.unit("x") == "nT"
    with pytest.raises(InputError, match="'V' \\(a voltage\\) but the sensor was calibrated in 'nT'"):
        triaxial_apply(Recording(channels=rec.channels, t=rec.t, units={c: "V" for c in "xyz"}),
                       TriaxialApplyOptions(params=cal))
