"""The velocity, response and linearity jobs: the Python API gives the numbers the CLI prints and saves."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from senscal.errors import InputError
from senscal.jobs import vibration as jv


@pytest.fixture(scope="module")
def hydraulic_dir(tmp_path_factory):
    from senscal.simulate.common import write_simulation
    from senscal.simulate.vibration import simulate_hydraulic

    d = tmp_path_factory.mktemp("hydraulic")
    recs, truth = simulate_hydraulic(frequencies=[1.0, 2.0, 3.5], seed=21)
    write_simulation(recs, truth, d, "hydraulic")
    return d


@pytest.fixture(scope="module")
def centrifuge_dir(tmp_path_factory):
    """Three turntable frequencies, a repeat at 5 Hz, and a start-up run for phi_0 (encoder zero 3 deg off)."""
    from senscal.io import write_recording
    from senscal.simulate.common import write_simulation
    from senscal.simulate.vibration import simulate_centrifuge

    d = tmp_path_factory.mktemp("centrifuge")
    recs, truth = simulate_centrifuge(frequencies=[1.0, 5.0, 5.0, 10.0], encoder_zero_deg=3.0, seed=22)
    write_simulation(recs, truth, d, "centrifuge")
    ref, _ = simulate_centrifuge(frequencies=[0.25], encoder_zero_deg=3.0, seed=23)
    write_recording(ref[0], d / "phaseref.csv")
    return d


@pytest.fixture(scope="module")
def levels_dir(tmp_path_factory):
    from senscal.simulate.common import write_simulation
    from senscal.simulate.vibration import simulate_centrifuge

    d = tmp_path_factory.mktemp("levels")
    recs, truth = simulate_centrifuge(frequencies=[2.0], accelerations=[20.0, 60.0, 100.0, 140.0], cubic=1e-6,
                                      seed=24)
    write_simulation(recs, truth, d, "centrifuge")
    return d


def _files(d, stem):
    return sorted(str(p) for p in d.glob(f"{stem}_[0-9]*.csv"))


def _json(cli, *args):
    r = cli(*args, "--json")
    assert r.code == 0, r.err
    return json.loads(r.out)


def _same_document(api: dict, printed: dict):
    """The API document, through JSON as the CLI prints it, equals the printed one exactly."""
    assert json.loads(json.dumps(api)) == printed


def _registry_quantities(cli, db, serial):
    h = cli("registry", "history", serial, "--db", db, "--json")
    assert h.code == 0, h.err
    return {(r["quantity"], r["unit"]): (r["value"], r["uncertainty"], r["k"]) for r in json.loads(h.out)["records"]}


def _as_table(quantities):
    return {(q.name, q.unit): (q.value, q.uncertainty, q.k) for q in quantities}


def test_velocity_api_equals_cli(cli, hydraulic_dir, tmp_path):
    files = _files(hydraulic_dir, "hydraulic")
    words = ["--position", "position", "--velocity", "velocity", "--freq", "1,2,3.5", "--u-position", "0.1%"]
    printed = _json(cli, "velocity", *files, *words)
    opts = jv.VelocityOptions(position="position", velocity="velocity", freq=(1.0, 2.0, 3.5), u_position=0.001)
    res = jv.velocity(files, opts)
    _same_document(res.to_dict(), printed)
    assert res.calibration.sensitivity == printed["sensitivity"]
    # what --save stores is result.quantities(): the names, units and numbers the registry had before
    db = tmp_path / "reg.sqlite"
    assert cli("velocity", *files, *words, "--save", "--sensor", "V-1", "--create-sensor", "velocity sensor",
               "--db", db).code == 0
    stored = _registry_quantities(cli, db, "V-1")
    assert stored == _as_table(res.quantities())
    assert stored == {("sensitivity", printed["unit"]): (printed["sensitivity"], printed["u_sensitivity"], 2.0)}
    frame = res.to_dataframe()
    assert list(frame["frequency_hz"]) == [p["frequency_hz"] for p in printed["points"]]
    assert list(frame["sensitivity"]) == [p["sensitivity"] for p in printed["points"]]


def _response_quantities_from_document(doc):
    """The registry's response quantities as the command stored them before the job layer (from its document)."""
    out = {}
    for p in doc["points"]:
        tag = f"{p['frequency_hz']:.4g}Hz"
        out[(f"sensitivity@{tag}", doc["unit"])] = (p["sensitivity"], p["u_sensitivity"], 2.0)
        if p.get("normalized_sensitivity") is not None:
            out[(f"normalized_sensitivity@{tag}", "1")] = (p["normalized_sensitivity"], p["u_normalized_sensitivity"], 2.0)
        if p.get("phase_delay_deg") is not None:
            out[(f"phase_delay@{tag}", "deg")] = (p["phase_delay_deg"], p["u_phase_delay_deg"], 2.0)
    return out


def test_response_api_equals_cli(cli, centrifuge_dir, tmp_path):
    files = _files(centrifuge_dir, "centrifuge")
    ref = str(centrifuge_dir / "phaseref.csv")
    words = ["--output", "output", "--input-amplitude", "100", "--angle", "angle", "--static-sensitivity", "0.05",
             "--u-input", "0.2%", "--u-static-sensitivity", "0.05%", "--phase-reference", ref]
    printed = _json(cli, "response", *files, *words)
    opts = jv.ResponseOptions(output="output", input_amplitude=100.0, angle="angle", static_sensitivity=0.05,
                              u_input=0.002, u_static_sensitivity=0.0005, phase_reference=ref)
    res = jv.response(files, opts)
    _same_document(res.to_dict(), printed)
    assert "repeats" in printed and res.repeated  # 5 Hz twice
    assert res.phase_reference_run is not None and "phaseref.csv" in printed["phase_reference"]
    db = tmp_path / "reg.sqlite"
    assert cli("response", *files, *words, "--save", "--sensor", "A-1", "--create-sensor", "accelerometer",
               "--db", db).code == 0
    stored = _registry_quantities(cli, db, "A-1")
    assert stored == _as_table(res.quantities())
    # one set per frequency: the 5 Hz repeats are stored once, combined, with their own coverage factor
    expect = _response_quantities_from_document({"unit": printed["unit"], "points": printed["repeats"]})
    assert set(stored) == set(expect) and len(stored) == 3 * len(printed["repeats"]) == 9
    for g in printed["repeats"]:
        tag = f"{g['frequency_hz']:.4g}Hz"
        assert stored[(f"sensitivity@{tag}", printed["unit"])] == (g["sensitivity"], g["u_sensitivity"],
                                                                    g["coverage_factor"])
    assert [g["n_repeats"] for g in printed["repeats"]] == [1, 2, 1]
    # without repeats each record's point is stored, quoted with k = 2, as before the job layer
    single = jv.response(files[:2], opts)
    assert _as_table(single.quantities()) == _response_quantities_from_document(single.to_dict())
    assert len(res.to_dataframe()) == len(files)


def test_response_back_to_back_api_equals_cli(cli, tmp_path):
    assert cli("simulate", "shaker", "--out", tmp_path, "--seed", "5", "--freqs", "80,315").code == 0
    files = _files(tmp_path, "shaker")
    printed = _json(cli, "response", *files, "--output", "dut", "--reference", "reference",
                    "--reference-sensitivity", "0.0102", "--u-reference", "0.5%")
    res = jv.response(files, jv.ResponseOptions(output="dut", reference="reference", reference_sensitivity=0.0102,
                                                u_reference=0.005))
    _same_document(res.to_dict(), printed)
    # no S0: no normalised sensitivity to store
    assert {q.name.split("@")[0] for q in res.quantities()} == {"sensitivity", "phase_delay"}


def test_linearity_api_equals_cli(cli, levels_dir, tmp_path):
    files = _files(levels_dir, "centrifuge")
    words = ["--output", "output", "--input-amplitudes", "20,60,100,140", "--angle", "angle", "--u-input", "0.05%"]
    printed = _json(cli, "linearity", *files, *words)
    res = jv.linearity(files, jv.LinearityOptions(output="output", input_amplitudes=(20, 60, 100, 140), angle="angle",
                                                  u_input=0.0005))
    _same_document(res.to_dict(), printed)
    db = tmp_path / "reg.sqlite"
    assert cli("linearity", *files, *words, "--save", "--sensor", "A-2", "--create-sensor", "accelerometer",
               "--db", db).code == 0
    stored = _registry_quantities(cli, db, "A-2")
    assert stored == _as_table(res.quantities())
    assert stored == {("linearity_slope", printed["unit"]): (printed["slope"], printed["u_slope"], 2.0),
                      ("linearity_percent", "%"): (printed["linearity_percent"], printed["u_linearity_percent"], 2.0)}
    assert list(res.to_dataframe()["input_amplitude"]) == [20.0, 60.0, 100.0, 140.0]


def test_job_options_builders_match_the_command_words():
    """`senscal batch` builds options from the command's parameters with JOB_OPTIONS: same as written by hand."""
    from senscal.cli.cmd_vibration import JOB_OPTIONS

    assert set(JOB_OPTIONS) == {"velocity", "response", "linearity"}
    got = JOB_OPTIONS["response"](output="out", input_amplitude=100.0, angle="angle", freq=["1,2", "3"],
                                  u_input="0.2%", u_static=None, names="t,out,angle", json_out=True, report=None)
    assert got == jv.ResponseOptions(output="out", input_amplitude=100.0, angle="angle", freq=(1.0, 2.0, 3.0),
                                     u_input=0.002, names=("t", "out", "angle"))
    assert JOB_OPTIONS["linearity"](output="o", input_amplitudes="1,2", u_input="1%").input_amplitudes == (1.0, 2.0)
    assert JOB_OPTIONS["velocity"](position="p", velocity="v").drift is True
    from senscal import jobs

    for name in JOB_OPTIONS:
        assert jobs.get(name) is getattr(jv, name)


def test_recordings_in_memory_give_the_numbers_of_their_files(hydraulic_dir):
    from senscal.io import read_recording

    files = _files(hydraulic_dir, "hydraulic")
    opts = jv.VelocityOptions(position="position", velocity="velocity")
    from_files = jv.velocity(files, opts)
    from_recs = jv.velocity([read_recording(f) for f in files], opts)
    a, b = from_files.calibration, from_recs.calibration
    assert a.sensitivity == b.sensitivity and a.u_sensitivity == b.u_sensitivity
    assert all(p.source for p in b.points)


@pytest.mark.parametrize("job, opts, message", [
    ("velocity", jv.VelocityOptions(velocity="velocity"), "--position"),
    ("response", jv.ResponseOptions(output="output"), "--input-amplitude"),
    ("response", jv.ResponseOptions(output="output", input_amplitude=1.0, freq=(1.0, 2.0)), "one --freq"),
    ("linearity", jv.LinearityOptions(output="output", input_amplitudes=(1.0,)), "one input amplitude per file"),
])
def test_bad_options_are_input_errors(hydraulic_dir, job, opts, message):
    files = _files(hydraulic_dir, "hydraulic")
    with pytest.raises(InputError, match=message):
        getattr(jv, job)(files, opts)


def test_results_are_frozen(hydraulic_dir):
    res = jv.velocity(_files(hydraulic_dir, "hydraulic")[:2], jv.VelocityOptions(position="position",
                                                                                 velocity="velocity"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.unit = "x"
    assert all(math.isfinite(q.value) for q in res.quantities())
