"""Units end to end in the vibration commands (issue 32 item 2): mV, mm, g are converted, V against a
position or an acceleration is refused in one line, and a reference channel that cannot be what it claims
(swapped position and velocity, a position in mm read as m) is named."""

from __future__ import annotations

import json

import numpy as np
import pytest

from senscal.io import Recording, write_recording


def _rescaled(recs, folder, changes):
    """The recordings written to ``folder`` with channel ``name`` multiplied by ``scale`` and its header unit
    set (``changes``: name -> (scale, unit or None))."""
    folder.mkdir(exist_ok=True)
    out = []
    for i, rec in enumerate(recs):
        chans = {n: rec[n] * changes.get(n, (1.0, None))[0] for n in rec.names}
        units = {n: u for n, (_, u) in changes.items() if u}
        out.append(str(write_recording(Recording(chans, t=rec.time, units=units), folder / f"r{i}.csv",
                                       units_in_header=True)))
    return out


@pytest.fixture(scope="module")
def centrifuge(tmp_path_factory):
    from senscal.simulate.vibration import simulate_centrifuge

    recs, truth = simulate_centrifuge(frequencies=(0.1, 1.0, 5.0), seed=7)
    return tmp_path_factory.mktemp("cf"), recs, truth


@pytest.fixture(scope="module")
def hydraulic(tmp_path_factory):
    from senscal.simulate.vibration import simulate_hydraulic

    recs, truth = simulate_hydraulic(frequencies=(1.0, 2.0, 3.0), seed=7)
    return tmp_path_factory.mktemp("hyd"), recs, truth


def _response(cli, files, *extra):
    r = cli("response", *files, "--output", "output", "--angle", "angle", "--json", *extra)
    assert r.code == 0, r.err
    return json.loads(r.out)


def test_response_output_in_mv_gives_s_over_s0_of_one(cli, centrifuge):
    """``output [mV]`` with ``--static-sensitivity 0.05`` (V/(m/s^2)): S/S0 ~ 1, not 999.99."""
    folder, recs, truth = centrifuge
    volts = _rescaled(recs, folder / "v", {})
    millivolts = _rescaled(recs, folder / "mv", {"output": (1e3, "mV")})
    s0 = truth["static_sensitivity"]
    a = _response(cli, volts, "--input-amplitude", "100", "--static-sensitivity", str(s0))
    b = _response(cli, millivolts, "--input-amplitude", "100", "--static-sensitivity", str(s0))
    assert a["unit"] == b["unit"] == "V/(m/s^2)"
    for pa, pb in zip(a["points"], b["points"]):
        assert pb["normalized_sensitivity"] == pytest.approx(pa["normalized_sensitivity"], rel=1e-9)
        assert pb["sensitivity"] == pytest.approx(pa["sensitivity"], rel=1e-9)
        assert pb["U_sensitivity"] == pytest.approx(pa["U_sensitivity"], rel=1e-6)
    # The lowest point is static: S/S0 within its U of 1.
    low = b["points"][0]
    assert abs(low["normalized_sensitivity"] - 1.0) < low["U_normalized_sensitivity"]
    # Options with a unit are converted: S0 in mV/(m/s^2), the input in g.
    c = _response(cli, millivolts, "--input-amplitude", f"{100 / 9.80665!r} g",
                  "--static-sensitivity", f"{1e3 * s0!r} mV/(m/s^2)")
    for pa, pc in zip(a["points"], c["points"]):
        assert pc["normalized_sensitivity"] == pytest.approx(pa["normalized_sensitivity"], rel=1e-9)
    assert c["static_sensitivity"] == pytest.approx(s0)


@pytest.mark.parametrize("args,fragments", [
    (("--static-sensitivity", "0.05 V/(m/s)"), ("--static-sensitivity", "cannot be converted", "V/(m/s^2)")),
    (("--static-sensitivity", "0.05 parsecs"), ("--static-sensitivity", "cannot be converted")),
    (("--input-amplitude", "100 V"), ("--input-amplitude", "'V' (a voltage)", "an acceleration")),
    (("--output-unit", "V"), ("--output-unit V contradicts", "mV")),
    (("--output-unit", "blorbs"), ("--output-unit", "not a unit senscal knows")),
])
def test_response_refuses_units_that_do_not_fit_in_one_line(cli, centrifuge, args, fragments):
    folder, recs, _ = centrifuge
    files = _rescaled(recs, folder / "mv2", {"output": (1e3, "mV")})
    base = ["--input-amplitude", "100"] if "--input-amplitude" not in args else []
    r = cli("response", *files, "--output", "output", "--angle", "angle", *base, *args)
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1, r.err
    for frag in fragments:
        assert frag in r.err, r.err


def test_response_refuses_an_output_that_is_an_acceleration_against_a_voltage_run(cli, centrifuge):
    """A second file whose output is in m/s^2 cannot join a run in V: refused, naming the file."""
    folder, recs, _ = centrifuge
    files = _rescaled(recs[:1], folder / "a", {"output": (1e3, "mV")})
    files += _rescaled(recs[1:2], folder / "b", {"output": (1.0, "m/s^2")})
    r = cli("response", *files, "--output", "output", "--angle", "angle", "--input-amplitude", "100")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "'m/s^2' (an acceleration)" in r.err and "'V' (a voltage)" in r.err and "b/r0.csv" in r.err


def test_angle_in_rad_header_is_converted(cli, centrifuge):
    folder, recs, _ = centrifuge
    deg = _rescaled(recs, folder / "deg", {})
    rad = _rescaled(recs, folder / "rad", {"angle": (np.pi / 180, "rad")})
    a = _response(cli, deg, "--input-amplitude", "100")
    b = _response(cli, rad, "--input-amplitude", "100")
    for pa, pb in zip(a["points"], b["points"]):
        assert pb["sensitivity"] == pytest.approx(pa["sensitivity"], rel=1e-9)
        assert pb["phase_delay_deg"] == pytest.approx(pa["phase_delay_deg"], abs=1e-9)


def _velocity(cli, files, *extra):
    return cli("velocity", *files, "--position", "position", "--velocity", "velocity", "--json", *extra)


def test_velocity_position_in_mm(cli, hydraulic):
    """``position [mm]``: S in V/(m/s) as from metres, and position_amplitude_m 0.020 for 20 mm."""
    folder, recs, truth = hydraulic
    metres = _rescaled(recs, folder / "m", {})
    millimetres = _rescaled(recs, folder / "mm", {"position": (1e3, "mm"), "velocity": (1e3, "mV")})
    a = json.loads(_velocity(cli, metres).out)
    r = _velocity(cli, millimetres)
    assert r.code == 0, r.err
    b = json.loads(r.out)
    assert b["unit"] == "V/(m/s)" and b["sensitivity"] == pytest.approx(a["sensitivity"], rel=1e-9)
    assert abs(b["sensitivity"] - truth["sensitivity"]) < b["U_sensitivity"] * 3
    for p in b["points"]:
        assert p["position_amplitude_m"] == pytest.approx(0.020, rel=2e-3)
    assert not [w for w in b["warnings"] if w.startswith(("velocity-not-derivative", "position-amplitude"))]


def test_velocity_position_in_mm_without_unit_is_named(cli, hydraulic):
    """The same millimetres under a bare header: read as 20 m, which no exciter moves; named, --strict exits 3."""
    folder, recs, _ = hydraulic
    files = _rescaled(recs, folder / "mm_bare", {"position": (1e3, None)})
    r = _velocity(cli, files, "--strict")
    assert r.code == 3
    assert any(w.startswith("position-amplitude-implausible:") and "mm" in w for w in json.loads(r.out)["warnings"])


def test_velocity_swapped_channels_are_named(cli, hydraulic):
    """Position and velocity swapped: phase about -180 deg; named velocity-not-derivative, --strict exits 3."""
    folder, recs, _ = hydraulic
    files = _rescaled(recs, folder / "swap", {})
    r = cli("velocity", *files, "--position", "velocity", "--velocity", "position", "--json", "--strict")
    assert r.code == 3
    doc = json.loads(r.out)
    assert all(abs(abs(p["phase_deg"]) - 180) < 5 for p in doc["points"])
    assert any(w.startswith("velocity-not-derivative:") and "swapped" in w for w in doc["warnings"])
    # With units in the header the swap is refused outright: the "sensor output" is a length.
    files = _rescaled(recs, folder / "swap_units", {"position": (1.0, "m"), "velocity": (1.0, "V")})
    r = cli("velocity", *files, "--position", "velocity", "--velocity", "position")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1
    assert "(a voltage)" in r.err and "swapped" in r.err


def test_velocity_polarity_inverted_is_named_and_a_good_sensor_is_not(cli, hydraulic):
    folder, recs, _ = hydraulic
    good = json.loads(_velocity(cli, _rescaled(recs, folder / "good", {})).out)
    assert not [w for w in good["warnings"] if w.startswith("velocity-not-derivative")]
    inverted = json.loads(_velocity(cli, _rescaled(recs, folder / "inv", {"velocity": (-1.0, None)})).out)
    assert any(w.startswith("velocity-not-derivative:") for w in inverted["warnings"])


def test_reference_sanity_limits():
    """The motion limits: 20 mm at 1-5 Hz passes; 20 m, or 1 mm at 2 kHz (158 m/s^2 ... 1.6e5 m/s^2), do not."""
    from senscal.vibration.velocity import reference_sanity

    assert reference_sanity(5.0, 0.02, 0.0, 1e-3) == ()
    assert reference_sanity(1.0, 20.0, 0.0, 1e-3)[0].startswith("position-amplitude-implausible")
    assert reference_sanity(2000.0, 1e-3, 0.0, 1e-3)[0].startswith("position-amplitude-implausible")
    # Quadrature: 100 deg with u = 1 deg is beyond 90 + 3.29 u; with u = 5 deg it is not.
    assert reference_sanity(5.0, 0.02, np.radians(100), np.radians(1))[0].startswith("velocity-not-derivative")
    assert reference_sanity(5.0, 0.02, np.radians(100), np.radians(5)) == ()


def test_velocity_with_a_frequency_the_data_do_not_have_is_named(cli, hydraulic):
    """``--freq`` 30 % off the excitation: frequency-mismatch, --strict exits 3; the right one raises none."""
    folder, recs, _ = hydraulic
    files = _rescaled(recs[:1], folder / "freq", {})
    r = _velocity(cli, files, "--freq", "1.3", "--strict")
    assert r.code == 3
    assert any(w.startswith("frequency-mismatch: channel 'position'") for w in json.loads(r.out)["warnings"])
    ok = json.loads(_velocity(cli, files, "--freq", "1").out)
    assert not [w for w in ok["warnings"] if w.startswith("frequency-mismatch")]


def test_output_unit_names_a_bare_header_and_is_converted(cli, centrifuge):
    """--output-unit mV on a file whose header gives no unit: the mV are converted to V (S in V/(m/s^2))."""
    folder, recs, truth = centrifuge
    volts = _rescaled(recs, folder / "v3", {})
    bare_mv = _rescaled(recs, folder / "bare_mv", {"output": (1e3, None)})
    a = _response(cli, volts, "--input-amplitude", "100")
    b = _response(cli, bare_mv, "--input-amplitude", "100", "--output-unit", "mV")
    assert b["unit"] == "V/(m/s^2)"
    for pa, pb in zip(a["points"], b["points"]):
        assert pb["sensitivity"] == pytest.approx(pa["sensitivity"], rel=1e-9)


def test_linearity_output_in_mv(cli, tmp_path):
    from senscal.simulate.vibration import simulate_centrifuge

    recs, _ = simulate_centrifuge(frequencies=(1.0,), accelerations=(20.0, 60.0, 100.0), seed=3)
    volts = _rescaled(recs, tmp_path / "v", {})
    mv = _rescaled(recs, tmp_path / "mv", {"output": (1e3, "mV")})
    args = ["--output", "output", "--angle", "angle", "--input-amplitudes", "20,60,100", "--json"]
    a, b = (json.loads(cli("linearity", *files, *args).out) for files in (volts, mv))
    assert b["unit"] == "V/(m/s^2)" and b["output_unit"] == "V"
    assert b["slope"] == pytest.approx(a["slope"], rel=1e-9)


def test_back_to_back_reference_in_mv(cli, tmp_path):
    """A reference channel in mV with a bare --reference-sensitivity (V/(m/s^2)) or one in mV/(m/s^2): same S."""
    from senscal.simulate.vibration import simulate_shaker

    recs, truth = simulate_shaker(frequencies=(80.0, 160.0), duration=0.2, seed=2)
    volts = _rescaled(recs, tmp_path / "v", {})
    mv = _rescaled(recs, tmp_path / "mv", {"reference": (1e3, "mV")})
    s_ref = truth["reference_sensitivity"]
    args = ["--output", "dut", "--reference", "reference", "--json"]
    a = json.loads(cli("response", *volts, *args, "--reference-sensitivity", str(s_ref)).out)
    b = json.loads(cli("response", *mv, *args, "--reference-sensitivity", str(s_ref)).out)
    c = json.loads(cli("response", *mv, *args, "--reference-sensitivity", f"{1e3 * s_ref!r} mV/(m/s^2)").out)
    for pa, pb, pc in zip(a["points"], b["points"], c["points"]):
        assert pb["sensitivity"] == pytest.approx(pa["sensitivity"], rel=1e-9)
        assert pc["sensitivity"] == pytest.approx(pa["sensitivity"], rel=1e-9)
