"""``senscal shock`` (ISO 16063-22 comparison, ISO 16063-13 laser primary): exactness, the linear algebra of the
uncertainty propagation, named warnings and bad input.  Coverage against simulated truth is in
test_coverage_shock.py."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from senscal.diagnostics import has_warning
from senscal.errors import DataError, InputError
from senscal.shock import differentiate, lowpass, shock_pulses
from senscal.shock.core import _Chain, _differentiate_adjoint
from senscal.simulate.shock import simulate_shock


def _cmp(**kw):
    rec, tr = simulate_shock(**kw)
    return rec.channels, rec.fs, tr


@pytest.mark.parametrize("T", [0.05, 1.0, 10.0])
def test_noise_free_comparison_is_exact(T):
    c, fs, tr = _cmp(duration_ms=T, reference_noise_rel=0.0, output_noise_rel=0.0, sensitivity=2e-4, seed=1)
    (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)
    assert p.sensitivity == pytest.approx(2e-4, rel=1e-9)
    assert np.allclose(p.transfer_function.magnitude, 2e-4, rtol=1e-9)
    assert np.allclose(p.transfer_function.phase_deg, 0.0, atol=1e-7)
    assert p.duration_ms == pytest.approx(T, rel=0.05)


@pytest.mark.parametrize("laser", ["velocity", "displacement"])
def test_noise_free_primary_is_exact(laser):
    """The five-point stencils' error on a 200-sample half-sine is far below the u any real laser gives."""
    c, fs, tr = _cmp(duration_ms=1.0, mode="primary", laser=laser, laser_noise=0.0, output_noise_rel=0.0, seed=2)
    (p,) = shock_pulses(c["laser"], c["out"], fs, laser=laser, cutoff_hz=10e3)
    assert p.sensitivity == pytest.approx(1e-4, rel=2e-5)
    assert p.peak_acceleration == pytest.approx(1000.0, rel=2e-3)  # the filter lowers both peaks alike


def test_adjoints_are_transposes():
    """The u propagation pushes weights back through differentiation and filter: <A x, w> = <x, A' w>."""
    rng = np.random.default_rng(0)
    n = 4000
    x = rng.standard_normal(n)
    w = np.zeros(n)
    w[1500:2500] = rng.standard_normal(1000)
    for order in (1, 2):
        assert np.dot(differentiate(x, 1e5, order), w) == pytest.approx(
            np.dot(x, _differentiate_adjoint(w, 1e5, order)), rel=1e-10)
    ch = _Chain(1e5, 2, 5e3, 4)
    assert np.dot(ch.apply(x), w) == pytest.approx(np.dot(x, ch.adjoint(w)), rel=1e-9)
    assert np.dot(lowpass(x, 1e5, 5e3), w) == pytest.approx(np.dot(x, lowpass(w, 1e5, 5e3)), rel=1e-9)


def test_several_pulses_found_in_order():
    c, fs, tr = _cmp(duration_ms=1.0, pulses=3, seed=3)
    ps = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)
    assert [p.index for p in ps] == [0, 1, 2]
    assert [round(p.t_peak_s, 4) for p in ps] == [round(q["t_peak_s"], 4) for q in tr["pulses"]]
    assert [p.peak_acceleration for p in ps] == pytest.approx([q["peak_acceleration"] for q in tr["pulses"]],
                                                              rel=3e-3)


def test_ringing_is_named_and_a_filter_below_the_resonance_removes_it():
    c, fs, tr = _cmp(duration_ms=0.05, peak=1e5, resonance_hz=30e3, seed=4)
    (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)
    assert has_warning(p.warnings, "shock-ringing")
    c, fs, tr = _cmp(duration_ms=1.0, resonance_hz=30e3, seed=4)
    (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4, cutoff_hz=5e3)
    assert not has_warning(p.warnings, "shock-ringing")


def test_zero_shift_is_named_and_corrected():
    c, fs, tr = _cmp(duration_ms=1.0, zero_shift_rel=0.02, seed=5)
    (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)
    assert has_warning(p.warnings, "zero-shift")
    assert p.zero_shift == pytest.approx(0.02 * 1e-4 * 1000.0, rel=0.05)
    assert abs(p.sensitivity - 1e-4) < 2 * p.u_sensitivity
    c, fs, tr = _cmp(duration_ms=1.0, seed=5)
    (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)
    assert not has_warning(p.warnings, "zero-shift") and p.zero_shift == 0.0


def test_pulse_outside_iso_range_is_named():
    c, fs, tr = _cmp(duration_ms=20.0, fs=2e4, seed=6)
    (p,) = shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)
    assert has_warning(p.warnings, "pulse-duration")


# --- bad input: one line, the fix named ---------------------------------------------------------------------

def test_refusals_of_the_engine():
    c, fs, tr = _cmp(duration_ms=1.0, seed=7)
    with pytest.raises(InputError, match="either"):
        shock_pulses(c["ref"], c["out"], fs)
    with pytest.raises(InputError, match="Nyquist"):
        shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4, cutoff_hz=fs)
    with pytest.raises(DataError, match="no shock pulse"):
        shock_pulses(np.random.default_rng(0).standard_normal(c["out"].size), c["out"], fs, reference_sensitivity=1e-4)
    clipped = np.minimum(c["out"], 0.8 * c["out"].max())
    with pytest.raises(DataError, match="clipped"):
        shock_pulses(c["ref"], clipped, fs, reference_sensitivity=1e-4)
    c, fs, tr = _cmp(duration_ms=1.0, fs=2e4, seed=7)  # 20 samples a pulse
    with pytest.raises(DataError, match="raise the sample rate"):
        shock_pulses(c["ref"], c["out"], fs, reference_sensitivity=1e-4)


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory):
    from senscal.io import write_recording

    d = tmp_path_factory.mktemp("shock")
    rec, tr = simulate_shock(duration_ms=1.0, pulses=2, seed=8)
    write_recording(rec, d / "cmp.csv", units_in_header=True)
    rec, tr = simulate_shock(duration_ms=1.0, mode="primary", laser="displacement", seed=8)
    write_recording(rec, d / "laser.csv", units_in_header=True)
    write_recording(rec, d / "laser_nounit.csv")
    return d


def test_cli_json_comparison_and_primary(cli, sim_dir):
    r = cli("shock", sim_dir / "cmp.csv", "--reference", "ref", "--reference-sensitivity", "0.1 mV/(m/s^2)",
            "--u-reference", "0.5%", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert len(doc["pulses"]) == 2 and doc["sensitivity_unit"] == "V per m/s^2"
    p = doc["pulses"][0]
    assert p["sensitivity"] == pytest.approx(1e-4, rel=2e-2)
    assert p["budget"]["reference_sensitivity"]["u_rel"] == pytest.approx(0.005)
    assert set(p["transfer_function"]) == {"frequency_hz", "magnitude", "u_magnitude", "phase_deg", "u_phase_deg"}
    r = cli("shock", sim_dir / "laser.csv", "--laser", "laser", "--lowpass-hz", "10 kHz", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert "displacement" in doc["method"] and doc["pulses"][0]["sensitivity"] == pytest.approx(1e-4, rel=1e-2)


@pytest.mark.parametrize("args, words", [
    (["cmp.csv", "--reference", "ref"], "--reference-sensitivity"),
    (["cmp.csv"], "either --reference"),
    (["cmp.csv", "--reference", "ref", "--reference-sensitivity", "1e-4", "--laser", "out"], "either"),
    (["cmp.csv", "--reference", "ref", "--reference-sensitivity", "0.1 m/s"], "--reference-sensitivity"),
    (["cmp.csv", "--reference", "out", "--reference-sensitivity", "1e-4"], "also the reference"),
    (["cmp.csv", "--laser", "ref"], "laser gives velocity"),
    (["laser_nounit.csv", "--laser", "laser", "--lowpass-hz", "10000"], "--laser-quantity"),
    (["laser.csv", "--laser", "laser"], "--lowpass-hz"),
    (["cmp.csv", "--reference", "ref", "--reference-sensitivity", "1e-4", "--lowpass-hz", "1e9"], "Nyquist"),
])
def test_cli_bad_input_one_line_exit_2(cli, sim_dir, args, words):
    r = cli("shock", sim_dir / args[0], *args[1:])
    assert r.code == 2, r.out
    assert len(r.err.strip().splitlines()) == 1 and words in r.err, r.err


def test_cli_strict_exits_3_on_ringing(cli, tmp_path):
    from senscal.io import write_recording

    rec, tr = simulate_shock(duration_ms=0.05, peak=1e5, resonance_hz=30e3, seed=9)
    write_recording(rec, tmp_path / "ring.csv", units_in_header=True)
    r = cli("shock", tmp_path / "ring.csv", "--reference", "ref", "--reference-sensitivity", "1e-4", "--strict")
    assert r.code == 3 and "shock-ringing" in r.err


def test_simulate_shock_cli(cli, tmp_path):
    r = cli("simulate", "shock", "--out", tmp_path / "s", "--durations-ms", "0.5", "--mode", "primary", "--seed", "1")
    assert r.code == 0, r.err
    truth = json.loads((tmp_path / "s" / "shock_truth.json").read_text())
    assert truth["points"][0]["file"] == "shock_01.csv"
    r = cli("shock", tmp_path / "s" / "shock_01.csv", "--laser", "laser", "--lowpass-hz", "20000", "--json")
    assert r.code == 0, r.err


# --- certificates, DCC and the registry, through the code every job uses ------------------------------------

_LAB = """name = "Shock Lab Nord"
address = "Hafenstr. 7, 20457 Hamburg"
country = "DE"
email = "lab@example.org"
approvers = [{name = "Dr. Ada Pruefer", role = "Head of laboratory"}]

[[standards]]
name = "Reference accelerometer (back to back)"
serial = "REF-0042"
certificate = "PTB-1.21-0816"
traceability = "PTB"
due = "2099-12-31"
u_relative = 0.002

[run]
location = "Laboratory hall 2"
customer = "ACME"
customer_email = "qa@acme.example"
customer_address = "Am Markt 1, 10115 Berlin"
manufacturer = "Qfab"
item = "shock accelerometer"
"""

SHARED_SCHEMAS = Path(__file__).resolve().parents[3] / "shared" / "schemas" / "dcc"


def _cert_env(tmp_path, monkeypatch):
    monkeypatch.delenv("SENSCAL_LAB", raising=False)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    lab = tmp_path / "lab.toml"
    lab.write_text(_LAB)
    return lab


def test_cli_report_dcc_and_save(cli, sim_dir, tmp_path, monkeypatch):
    """--report, --dcc, --save: the pulses, their ISO 16063-22 budget by name, the DCC's values as in --json."""
    import xml.etree.ElementTree as ET
    from html import unescape

    lab = _cert_env(tmp_path, monkeypatch)
    db = tmp_path / "reg.db"
    r = cli("shock", sim_dir / "cmp.csv", "--reference", "ref", "--reference-sensitivity", "0.1 mV/(m/s^2)",
            "--u-reference", "0.5%", "--u-other", "0.3%", "--json", "--report", tmp_path / "cert.html", "--dcc",
            tmp_path / "cert.xml", "--lab", lab, "--sensor-id", "SN-7", "--calibration-date", "2026-11-27",
            "--env", "temperature=23.0+-0.3 degC", "--save", "--sensor", "SN-7", "--create-sensor",
            "shock accelerometer", "--db", db)
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    assert doc["report"].endswith("cert.html")
    assert not [w for w in doc["warnings"] if w.startswith(("certificate-draft", "budget-zero-component",
                                                               "u-below-reference"))], doc["warnings"]
    html = (tmp_path / "cert.html").read_text()
    assert "ISO 16063-22" in html and "reference accelerometer's sensitivity" in unescape(html)
    assert "Accelerometer shock sensitivity" in html
    root = ET.parse(tmp_path / "cert.xml").getroot()
    si = "{https://ptb.de/si}"
    sens = [q for q in root.iter("{https://ptb.de/dcc}quantity") if q.get("refType") == "senscal_sensitivity"]
    vals = [float(v) for v in sens[0].find(f"{si}realListXMLList/{si}valueXMLList").text.split()]
    assert vals == pytest.approx([p["sensitivity"] for p in doc["pulses"]], rel=1e-11)
    U = [float(v) for v in sens[0].find(f"{si}realListXMLList/{si}expandedUncXMLList/{si}uncertaintyXMLList").text
         .split()]
    assert U == pytest.approx([2 * p["u_sensitivity"] for p in doc["pulses"]], rel=1e-9)
    assert len([r_ for r_ in root.iter("{https://ptb.de/dcc}result")
                if r_.get("refType") == "senscal_shockTransferFunction"]) == len(doc["pulses"])
    r = cli("registry", "history", "SN-7", "--db", db, "--json")
    assert r.code == 0, r.err
    assert "shock_sensitivity@" in r.out


def test_cli_laser_certificate_names_iso_16063_13_and_zero_inputs(cli, sim_dir, tmp_path, monkeypatch):
    """A laser calibration has no reference sensitivity in its budget; --u-other left at 0 is named."""
    lab = _cert_env(tmp_path, monkeypatch)
    r = cli("shock", sim_dir / "laser.csv", "--laser", "laser", "--lowpass-hz", "10 kHz", "--report",
            tmp_path / "cert.html", "--lab", lab, "--sensor-id", "SN-8", "--calibration-date", "2026-11-27",
            "--env", "temperature=23.0+-0.3 degC", "--json")
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    zero = [w for w in doc["warnings"] if w.startswith("budget-zero-component")]
    assert len(zero) == 1 and "--u-other" in zero[0] and "reference accelerometer" not in zero[0]
    html = (tmp_path / "cert.html").read_text()
    assert "ISO 16063-13" in html and "zero-phase Butterworth" in html


@pytest.mark.skipif(not (SHARED_SCHEMAS / "dcc.xsd").is_file(), reason="../shared/schemas/dcc not present")
def test_dcc_is_valid_against_the_shared_schema(sim_dir):
    import xmlschema

    from senscal.jobs.shock import ShockOptions, shock
    from senscal.report.dcc import dcc_xml
    from senscal.report.lab import CertificateInfo, Condition, LabProfile, Person, RunInfo, Standard

    lab = LabProfile(name="Shock Lab", address="Hafenstr. 7\n20457 Hamburg", email="lab@example.org", country="DE",
                     approvers=(Person("A. Approver", "Head of laboratory"),),
                     standards=(Standard("Reference accelerometer", "REF-1", "PTB-1.21-0816", "PTB", "2099-12-31",
                                         0.002),))
    run = RunInfo(certificate_id="SHK-1", customer="ACME", customer_address="1 Main St", customer_email="qa@acme.example",
                  item="shock accelerometer", manufacturer="Qfab", model="S-1", serial="SN-9",
                  calibration_date="2026-11-27", issue_date="2026-11-27", location="laboratory",
                  conditions=(Condition("temperature", 23.1, 0.5, "degC"),))
    d = SHARED_SCHEMAS
    si = d / "SI_Format.xsd" if (d / "SI_Format.xsd").is_file() else d.parent / "SI_Format.xsd"
    schema = xmlschema.XMLSchema(str(d / "dcc.xsd"), locations={"https://ptb.de/si": str(si)}, allow="local")
    for opts in (ShockOptions(reference="ref", reference_sensitivity=1e-4, u_reference=0.005, u_other=0.003),):
        res = shock(sim_dir / "cmp.csv", opts)
        schema.validate(dcc_xml("shock", res, CertificateInfo(lab, run)).decode())  # unit from the result: V
    res = shock(sim_dir / "laser.csv", ShockOptions(laser="laser", lowpass_hz=10_000.0, u_other=0.003))
    schema.validate(dcc_xml("shock", res, CertificateInfo(lab, run), unit="V/(m/s^2)").decode())
