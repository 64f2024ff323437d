"""The shaft jobs (``senscal.jobs.shaft``): the Python API, the CLI and the registry agree."""

from __future__ import annotations

import json

import numpy as np
import pytest

from senscal import jobs
from senscal.errors import InputError
from senscal.io import read_recording
from senscal.jobs.shaft import (ShaftCalibrateOptions, ShaftCompensateOptions, ShaftCalibrateResult,
                                ShaftCompensateResult, shaft_calibrate, shaft_compensate)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from senscal.cli import main

    out = tmp_path_factory.mktemp("shaftjobs")
    try:
        main(["simulate", "shaft", "--out", str(out), "--seed", "5", "--cal-duration", "6", "--test-duration", "4"])
    except SystemExit as exc:
        assert exc.code in (0, None)
    return out


def _same_document(a, b):
    """Document ``a`` equals ``b`` exactly: same keys in the same order, every number equal."""
    assert list(a) == list(b)
    assert a == b


def test_calibrate_api_equals_cli_json(cli, sim):
    r = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel",
            "--max-speed-variation", "20%", "--json")
    assert r.code == 0, r.err
    res = shaft_calibrate(sim / "shaft_cal.csv", ShaftCalibrateOptions(max_speed_variation=0.2))
    assert isinstance(res, ShaftCalibrateResult)
    # The document goes through JSON exactly as the CLI prints it.
    _same_document(res.to_dict(), json.loads(r.out))
    assert res.warnings == tuple(json.loads(r.out)["warnings"])


def test_calibrate_on_a_recording_in_memory_equals_the_file(sim):
    rec = read_recording(sim / "shaft_cal.csv")
    a = shaft_calibrate(sim / "shaft_cal.csv").model
    b = shaft_calibrate(rec).model
    assert (a.amplitude, a.phase, a.offset) == (b.amplitude, b.phase, b.offset)


def test_options_builder_matches_the_command_words(sim):
    from senscal.cli.cmd_shaft import JOB_OPTIONS

    o = JOB_OPTIONS["shaft-calibrate"](angle="angle", accel="accel", max_speed_variation="5%", radius=0.1,
                                       json_out=True, plot=None, save=False)
    assert o == ShaftCalibrateOptions(max_speed_variation=0.05, radius=0.1)
    o = JOB_OPTIONS["shaft-compensate"](model_path=sim / "m.json", angle="angle", accel="accel", radius=0.1,
                                        centripetal=True, out=None)
    assert o == ShaftCompensateOptions(model=sim / "m.json", radius=0.1, centripetal=True)
    with pytest.raises(InputError, match="max-speed-variation"):
        JOB_OPTIONS["shaft-calibrate"](max_speed_variation="fast")


def test_quantities_are_what_the_registry_stores(cli, sim, tmp_path):
    db = tmp_path / "r.sqlite"
    r = cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel", "--json",
            "--save", "--sensor", "SH-9", "--create-sensor", "accelerometer", "--db", db)
    assert r.code == 0, r.err
    qs = shaft_calibrate(sim / "shaft_cal.csv").quantities()
    # The names and units the registry has always stored for a shaft calibration.
    assert [(q.name, q.unit) for q in qs] == [("gravity_amplitude", "m/s^2"), ("bias", "m/s^2")]
    doc = json.loads(r.out)
    assert [(q.value, q.uncertainty) for q in qs] == [(doc["amplitude"], doc["u_amplitude"]),
                                                      (doc["offset"], doc["u_offset"])]
    hist = json.loads(cli("registry", "history", "SH-9", "--db", db, "--json").out)["records"]
    stored = {x["quantity"]: x for x in hist}
    assert set(stored) == {q.name for q in qs}
    for q in qs:
        assert stored[q.name]["value"] == pytest.approx(q.value, rel=1e-12)
        assert stored[q.name]["unit"] == q.unit


def test_compensate_api_equals_cli_json_and_out(cli, sim, tmp_path):
    model = tmp_path / "model.json"
    assert cli("shaft", "calibrate", sim / "shaft_cal.csv", "--angle", "angle", "--accel", "accel",
               "--out", model).code == 0
    out = tmp_path / "comp.csv"
    r = cli("shaft", "compensate", sim / "shaft_test.csv", "--model", model, "--angle", "angle", "--accel", "accel",
            "--radius", "0.1", "--centripetal", "--out", out, "--json")
    assert r.code == 0, r.err
    cli_doc = json.loads(r.out)
    assert cli_doc.pop("out") == str(out)
    res = jobs.run("shaft-compensate", sim / "shaft_test.csv",
                   jobs.options("shaft-compensate", model=model, radius=0.1, centripetal=True))
    assert isinstance(res, ShaftCompensateResult)
    _same_document(res.to_dict(), cli_doc)
    # --out holds the job's arrays; the data frame is the same table.
    written = read_recording(out)
    np.testing.assert_allclose(written["angular_acceleration"], res.compensation.angular_acceleration, rtol=1e-12)
    df = res.to_dataframe()
    assert list(df.columns) == ["t", *res.output_recording().names]
    np.testing.assert_array_equal(df["tangential_acceleration"], res.compensation.tangential_acceleration)


def test_compensate_takes_a_model_in_memory(sim):
    cal = shaft_calibrate(sim / "shaft_cal.csv")
    a = shaft_compensate(sim / "shaft_test.csv", ShaftCompensateOptions(model=cal.model, radius=0.1))
    assert a.to_dict()["model"] == "<model>"
    assert np.isfinite(a.compensation.rms_difference)


@pytest.mark.parametrize("opts, msg", [
    (ShaftCompensateOptions(radius=0.1), "needs the gravity model"),
    (ShaftCompensateOptions(model="m.json"), "needs the sensor radius"),
    (ShaftCompensateOptions(model=3.0, radius=0.1), "MODEL.json path or a GravityModel"),
])
def test_compensate_refuses_incomplete_options(sim, opts, msg):
    with pytest.raises(InputError, match=msg):
        shaft_compensate(sim / "shaft_test.csv", opts)


def test_calibrate_refuses_a_bad_angle_unit_and_source(sim):
    with pytest.raises(InputError, match="contradicts the file"):
        shaft_calibrate(sim / "shaft_cal.csv", ShaftCalibrateOptions(angle_unit="rad"))
    with pytest.raises(InputError, match="recording file or a senscal.io.Recording"):
        shaft_calibrate(42, ShaftCalibrateOptions())


def test_calibrate_dataframe_rows(sim):
    res = shaft_calibrate(sim / "shaft_cal.csv")
    df = res.to_dataframe()
    assert list(df["quantity"]) == ["amplitude", "phase", "offset", "tilt", "bias"]
    row = df.set_index("quantity").loc["amplitude"]
    assert row["value"] == res.model.amplitude and row["U"] == 2 * res.model.u_amplitude
