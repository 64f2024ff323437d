"""``senscal shock`` (ISO 16063-22 comparison, ISO 16063-13 laser primary): exactness, the linear algebra of the
uncertainty propagation, named warnings and bad input.  Coverage against simulated truth is in
test_coverage_shock.py."""

from __future__ import annotations

import json

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
