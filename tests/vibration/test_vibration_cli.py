"""The ``velocity``, ``response``, ``linearity`` commands and the simulators, end to end."""

from __future__ import annotations

import json
import math

import pytest


@pytest.fixture(scope="module")
def centrifuge_dir(tmp_path_factory):
    from senscal.simulate.common import write_simulation
    from senscal.simulate.vibration import simulate_centrifuge

    d = tmp_path_factory.mktemp("centrifuge")
    recs, truth = simulate_centrifuge(seed=31)
    write_simulation(recs, truth, d, "centrifuge")
    return d


def _files(d, stem):
    return sorted(str(p) for p in d.glob(f"{stem}_[0-9]*.csv"))


def test_simulate_and_response_acceptance(cli, centrifuge_dir, tmp_path):
    # Acceptance of issue 3 through the command line: S_i/S_0 and phase delay
    # of the second-order model within the reported expanded uncertainty.
    files = _files(centrifuge_dir, "centrifuge")
    truth = json.loads((centrifuge_dir / "centrifuge_truth.json").read_text())
    cert = tmp_path / "cert.html"
    r = cli("response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--static-sensitivity", str(truth["static_sensitivity"]), "--u-input", "0.2%", "--json",
            "--report", cert, "--sensor-id", "SN-42", "--model", "QF-1", "--plot", tmp_path / "bode.png",
            "--condition", "temperature=23.1 C", "--save-response", tmp_path / "resp.json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    for key in ("file", "frequency_hz", "sensitivity", "u_sensitivity", "normalized_sensitivity",
                "u_normalized_sensitivity", "phase_deg", "u_phase_deg", "phase_delay_deg"):
        assert key in doc["points"][0]
    by_file = {p["file"]: p for p in truth["points"]}
    for p in doc["points"]:
        tr = by_file[p["file"].split("/")[-1]]
        # the 0.2 % type B input uncertainty dominates here; check against the type A part too
        assert abs(p["normalized_sensitivity"] - tr["normalized_sensitivity"]) < p["U_normalized_sensitivity"]
        assert abs(p["phase_delay_deg"] - tr["phase_delay_deg"]) < p["U_phase_delay_deg"]
        fit_u = p["normalized_budget"]["components"][0]["standard_uncertainty"]
        assert abs(p["normalized_sensitivity"] - tr["normalized_sensitivity"]) < 4 * fit_u
        assert p["u_normalized_sensitivity"] > 0.002 * p["normalized_sensitivity"]
    html = cert.read_text()
    from senscal.vibration import load_response

    assert len(load_response(tmp_path / "resp.json").points) == len(files)
    for needle in ("SN-42", "QF-1", "23.1 C", "Certificate id", "relate only to the item calibrated", "<svg", "k = 2",
                   "Uncertainty budget"):
        assert needle in html
    # self-contained: no scripts, no external resources
    assert "<script" not in html and 'src="http' not in html and "<link" not in html
    assert (tmp_path / "bode.png").stat().st_size > 1000


def test_velocity_command(cli, tmp_path):
    r = cli("simulate", "hydraulic", "--out", tmp_path, "--seed", "7", "--freqs", "1,2,3")
    assert r.code == 0, r.err
    truth = json.loads((tmp_path / "hydraulic_truth.json").read_text())
    files = _files(tmp_path, "hydraulic")
    r = cli("velocity", *files, "--position", "position", "--velocity", "velocity", "--json",
            "--report", tmp_path / "v.html")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert set(doc) >= {"points", "sensitivity", "sensitivity_std", "u_sensitivity", "unit"}
    assert doc["unit"] == "V/(m/s)"
    assert abs(doc["sensitivity"] - truth["sensitivity"]) < 2 * doc["u_sensitivity"]
    p = doc["points"][1]
    assert set(p) >= {"file", "frequency_hz", "sensitivity", "u_sensitivity", "phase_deg", "u_phase_deg"}
    assert abs(p["phase_deg"] - truth["points"][1]["phase_deg"]) < 2 * p["u_phase_deg"]
    # known frequencies, one per file; table output works too
    r = cli("velocity", *files, "--position", "position", "--velocity", "velocity", "--freq", "1,2,3")
    assert r.code == 0, r.err
    assert "mean S" in r.out
    assert "Velocity-sensor sensitivity" in (tmp_path / "v.html").read_text()


def test_shaker_back_to_back_command(cli, tmp_path):
    assert cli("simulate", "shaker", "--out", tmp_path, "--seed", "2", "--freqs", "80,160").code == 0
    truth = json.loads((tmp_path / "shaker_truth.json").read_text())
    r = cli("response", *_files(tmp_path, "shaker"), "--output", "dut", "--reference", "reference",
            "--reference-sensitivity", str(truth["reference_sensitivity"]), "--u-reference", "0.5%", "--json")
    assert r.code == 0, r.err
    for p, tr in zip(json.loads(r.out)["points"], truth["points"]):
        assert abs(p["sensitivity"] - tr["sensitivity"]) < p["U_sensitivity"]
        assert p["normalized_sensitivity"] is None
        assert abs(p["phase_delay_deg"] - tr["phase_delay_deg"]) < p["U_phase_delay_deg"]
        assert p["u_sensitivity"] == pytest.approx(0.005 * p["sensitivity"], rel=0.05)


def test_linearity_command(cli, tmp_path):
    levels = "20,50,80,110"
    assert cli("simulate", "centrifuge", "--out", tmp_path, "--seed", "3", "--freqs", "2",
               "--accelerations", levels, "--cubic", "1e-6").code == 0
    r = cli("linearity", *_files(tmp_path, "centrifuge"), "--output", "output", "--input-amplitudes", levels,
            "--angle", "angle", "--harmonics", "3", "--json", "--report", tmp_path / "lin.html")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert set(doc) >= {"points", "slope", "intercept", "linearity_percent", "full_scale_output"}
    assert doc["linearity_percent"] > 10 * doc["u_linearity_percent"]
    assert "<svg" in (tmp_path / "lin.html").read_text()


@pytest.mark.parametrize("args, message", [
    (["--output", "output"], "--input-amplitude"),
    (["--output", "output", "--input-amplitude", "100", "--reference", "x", "--reference-sensitivity", "1"], "either"),
    (["--output", "nope", "--input-amplitude", "100"], "no channel 'nope'"),
    (["--output", "output", "--input-amplitude", "100", "--freq", "1,2,3"], "one per file"),
    (["--output", "output", "--input-amplitude", "100", "--u-input", "abc"], "percentage"),
    (["--output", "output", "--input-amplitude", "-1"], "m/s^2"),
    (["--output", "output", "--input-amplitude", "1", "--report", "x.html", "--condition", "oops"], "KEY=VALUE"),
])
def test_response_user_errors_are_one_line(cli, centrifuge_dir, args, message):
    r = cli("response", *_files(centrifuge_dir, "centrifuge")[:2], *args)
    assert r.code == 2
    assert message in r.err
    assert "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1


def test_too_short_for_a_revolution_is_an_error(cli, tmp_path):
    from senscal.io import read_recording, write_recording

    assert cli("simulate", "centrifuge", "--out", tmp_path, "--seed", "4", "--freqs", "0.1").code == 0
    rec = read_recording(tmp_path / "centrifuge_01.csv")
    write_recording(rec.slice(0, 900), tmp_path / "short.csv")  # 9 s of a 10 s revolution
    r = cli("response", tmp_path / "short.csv", "--output", "output", "--input-amplitude", "100", "--angle", "angle")
    assert r.code == 2
    assert "fewer than one whole turntable revolution" in r.err


def test_linearity_needs_one_amplitude_per_file(cli, centrifuge_dir):
    r = cli("linearity", *_files(centrifuge_dir, "centrifuge")[:3], "--output", "output", "--input-amplitudes", "1,2")
    assert r.code == 2 and "one input amplitude per file" in r.err


def test_input_files_are_not_modified(cli, centrifuge_dir):
    files = _files(centrifuge_dir, "centrifuge")
    before = [open(f, "rb").read() for f in files]
    assert cli("response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle").code == 0
    assert [open(f, "rb").read() for f in files] == before


def test_response_and_velocity_save_to_registry(cli, centrifuge_dir, tmp_path):
    files = _files(centrifuge_dir, "centrifuge")
    db = tmp_path / "reg.sqlite"
    r = cli("response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle",
            "--static-sensitivity", "0.01", "--json", "--save", "--sensor", "ACC-1", "--create-sensor", "accelerometer",
            "--db", db, "--date", "2026-01-05")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    h = cli("registry", "history", "ACC-1", "--db", db, "--json")
    assert h.code == 0, h.err
    recs = json.loads(h.out)["records"]
    f0 = doc["points"][0]
    q = f"sensitivity@{f0['frequency_hz']:.4g}Hz"
    saved = [x for x in recs if x["quantity"] == q]
    assert saved and saved[0]["value"] == pytest.approx(f0["sensitivity"])
    assert saved[0]["uncertainty"] == pytest.approx(f0["u_sensitivity"])
    # Registry options without --save are a user error, not silently ignored.
    r = cli("response", *files, "--output", "output", "--input-amplitude", "100", "--sensor", "ACC-1")
    assert r.code == 2 and "--save" in r.err


def test_phase_reference_unknown_entered_or_measured(cli, tmp_path):
    # Issue 13 item 3 through the command line: an encoder zero 5 deg off.
    assert cli("simulate", "centrifuge", "--out", tmp_path, "--seed", "11", "--freqs", "1,5,10",
               "--encoder-zero-deg", "5", "--phase-reference-freq", "0.25").code == 0
    truth = json.loads((tmp_path / "centrifuge_truth.json").read_text())
    assert truth["initial_phase_deg"] == 95.0 and (tmp_path / "phaseref.csv").exists()
    files = _files(tmp_path, "centrifuge")
    base = ["response", *files, "--output", "output", "--input-amplitude", "100", "--angle", "angle", "--json"]
    by_file = {p["file"]: p for p in truth["points"]}

    def off_by(doc):
        return [(p["phase_delay_deg"] - by_file[p["file"].split("/")[-1]]["phase_delay_deg"]) / p["U_phase_delay_deg"]
                for p in doc["points"]]

    # neither: the delay is off by the 5 deg (thousands of U), and one named warning says so
    r = cli(*base)
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert all(abs(z) > 100 for z in off_by(doc))
    assert [w.split(":")[0] for w in doc["warnings"]] == ["phase-reference-unknown"]
    assert r.err.count("phase-reference-unknown") == 1
    assert doc["points"][0]["phase_reference"] == "assumed encoder zero"
    # --strict: the result is still printed, then exit 3
    r = cli(*base, "--strict")
    assert r.code == 3 and json.loads(r.out)["points"] and "phase-reference-unknown" in r.err
    # phi_0 measured by a start-up run: covers, no warning, the certificate says how phi_0 was obtained
    # (no lab profile here: the certificate's own warnings, DRAFT and a zero --u-input, are the only ones)
    r = cli(*base, "--phase-reference", tmp_path / "phaseref.csv", "--report", tmp_path / "c.html")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert all(abs(z) < 1 for z in off_by(doc))
    assert [w.split(":")[0] for w in doc["warnings"]] == ["certificate-draft", "budget-zero-component"]
    assert "start-up" in doc["phase_reference"] or "run" in doc["phase_reference"]
    html = (tmp_path / "c.html").read_text()
    assert "Input phase phi_0" in html and "phaseref.csv" in html
    # phi_0 entered with its u: covers, u in the budget
    r = cli(*base, "--initial-phase-deg", "95", "--u-initial-phase-deg", "0.01", "--strict")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert all(abs(z) < 1 for z in off_by(doc))
    comps = {c["source"]: c["standard_uncertainty"] for c in doc["points"][0]["phase_delay_budget"]["components"]}
    assert comps["input phase"] == pytest.approx(math.radians(0.01))
    # the lowest-frequency response record itself can serve as the reference
    r = cli(*base, "--phase-reference", files[0])
    assert r.code == 0, r.err
    d0 = json.loads(r.out)["points"][0]
    assert abs(d0["phase_delay_deg"] - truth["points"][0]["phase_delay_deg"]) < d0["U_phase_delay_deg"]


@pytest.mark.parametrize("args, message", [
    (["--phase-reference", "REF"], "--angle"),
    (["--angle", "angle", "--phase-reference", "REF", "--initial-phase-deg", "90"], "not both"),
    (["--angle", "angle", "--u-initial-phase-deg", "0.1"], "--initial-phase-deg"),
    (["--angle", "angle", "--initial-phase-deg", "90", "--u-initial-phase-deg", "-1"], "--u-initial-phase-deg"),
])
def test_phase_reference_user_errors(cli, centrifuge_dir, args, message):
    files = _files(centrifuge_dir, "centrifuge")
    args = [files[0] if a == "REF" else a for a in args]
    r = cli("response", *files[1:3], "--output", "output", "--input-amplitude", "100", *args)
    assert r.code == 2, r.err
    assert message in r.err and "Traceback" not in r.err and len(r.err.strip().splitlines()) == 1


def test_linearity_of_a_linear_sensor_is_a_bound_and_strict_exits_3(cli, tmp_path):
    levels = "20,40,60,80,100"
    assert cli("simulate", "centrifuge", "--out", tmp_path, "--seed", "5", "--freqs", "1",
               "--accelerations", levels).code == 0
    args = ["linearity", *_files(tmp_path, "centrifuge"), "--output", "output", "--input-amplitudes", levels,
            "--angle", "angle"]
    r = cli(*args, "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["linearity_resolved"] is False
    assert doc["linearity_bound_percent"] > doc["linearity_percent"]
    assert [w.split(":")[0] for w in doc["warnings"]] == ["linearity-not-resolved"]
    assert doc["coverage_factor"] == 2.0 and doc["U_slope"] == pytest.approx(2 * doc["u_slope"])
    r = cli(*args, "--strict")
    assert r.code == 3 and "linearity below" in r.out and "linearity-not-resolved" in r.err
