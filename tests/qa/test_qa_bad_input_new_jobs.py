"""The bad-input lists of issues 27 and 28 through the command line: one line and exit 2, or a named warning.

Issue 27 (``senscal imu calibrate``): no static window (with the windows found, the windows needed and
the thresholds tried), one pose, rotations too fast for the sample rate, a saturated gyro.
Issue 28 (``senscal primary``): I/Q swapped, a single channel given as quadrature, a wavelength in
metres, too few fringes.  Cases the job and engine tests already run through the CLI (one pose, I/Q
swapped, ``--quadrature I,I``, a bare wavelength in metres) are not repeated here.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from senscal.io import Recording, write_recording


def _one_line(r, *words):
    assert r.code == 2, (r.code, r.err)
    lines = r.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("senscal: "), r.err
    assert "Traceback" not in r.err
    for w in words:
        assert w in r.err, (w, r.err)


# --- imu calibrate (issue 27) ---------------------------------------------------------------------------------

def test_imu_no_static_window_explained(cli, tmp_path):
    rng = np.random.default_rng(0)
    t = np.arange(3000) / 100.0
    # always turning about z: no still window anywhere
    acc = np.stack([9.8 * np.cos(t), 9.8 * np.sin(t), np.zeros_like(t)]) + 0.02 * rng.normal(size=(3, t.size))
    gyr = np.stack([np.zeros_like(t), np.zeros_like(t), np.ones_like(t)])
    p = write_recording(Recording(channels=dict(zip(["ax", "ay", "az", "gx", "gy", "gz"], [*acc, *gyr])), t=t),
                        tmp_path / "turning.csv")
    r = cli("imu", "calibrate", p)
    _one_line(r, "found at most", "needs >= 12", "variance thresholds", "hold the IMU still")


def test_imu_rotations_too_fast_named_and_strict(cli, tmp_path):
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=2, n_poses=14, rotation_s=0.12, fs=50.0, angle_deg=(150.0, 170.0), init_s=10.0)
    p = write_recording(rec, tmp_path / "fast.csv", units_in_header=True)
    r = cli("imu", "calibrate", p, "--json")
    assert r.code == 0, r.err
    assert any(w.startswith("rotation-too-fast") for w in json.loads(r.out)["warnings"])
    assert "warning: rotation-too-fast" in r.err
    r = cli("imu", "calibrate", p, "--json", "--strict")
    assert r.code == 3 and "--strict" in r.err and "Traceback" not in r.err


def test_imu_saturated_gyro_named_and_strict(cli, tmp_path):
    from senscal.simulate.imu import simulate_imu

    rec, _ = simulate_imu(seed=5, n_poses=14, fs=50.0, init_s=10.0)
    peak = max(float(np.max(np.abs(rec[g]))) for g in ("gx", "gy", "gz"))
    ch = {c: (np.clip(rec[c], -0.6 * peak, 0.6 * peak) if c.startswith("g") else rec[c]) for c in rec.names}
    p = write_recording(Recording(channels=ch, t=rec.time, units=rec.units), tmp_path / "clipped.csv",
                        units_in_header=True)
    r = cli("imu", "calibrate", p, "--json", "--strict")
    assert r.code == 3 and "warning: gyro-saturated" in r.err and "Traceback" not in r.err


# --- primary (issue 28) ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def pri(tmp_path_factory):
    from senscal.simulate.interferometer import simulate_interferometer

    d = tmp_path_factory.mktemp("primary_bad")
    rec, _ = simulate_interferometer(freq=160.0, fs=50_000.0, duration=0.1, seed=8)
    ch = dict(rec.channels)
    write_recording(rec, d / "ok.csv", units_in_header=True)
    write_recording(Recording(channels={**ch, "Q": ch["I"].copy()}, t=rec.time), d / "q_is_i.csv")
    write_recording(Recording(channels={**ch, "Q": np.zeros_like(ch["I"])}, t=rec.time), d / "q_dead.csv")
    rec, _ = simulate_interferometer(freq=160.0, fs=50_000.0, duration=0.1, seed=8, acceleration=0.02)
    write_recording(rec, d / "few.csv")  # 20 nm: a fraction of a fringe
    return d


@pytest.mark.parametrize("name, words", [
    ("q_is_i.csv", ["single channel", "--quadrature I,Q"]),  # one output wired to both inputs
    ("q_dead.csv", ["Q channel is constant", "single channel"]),  # the second output not connected
    ("few.csv", ["too few fringes", "raise the vibration amplitude"]),
])
def test_primary_bad_recording_one_line(cli, pri, name, words):
    _one_line(cli("primary", pri / name), name, *words)


def test_primary_wavelength_with_a_unit_is_converted(cli, pri):
    """'632.8e-9 m' is a wavelength in metres stated as such: converted, not refused; a bare 6.328e-7 is refused."""
    r = cli("primary", pri / "ok.csv", "--wavelength-nm", "632.8e-9 m", "--json")
    assert r.code == 0, r.err
    assert json.loads(r.out)["wavelength_nm"] == pytest.approx(632.8, rel=1e-12)
    _one_line(cli("primary", pri / "ok.csv", "--wavelength-nm", "6.328e-7"), "metres")
    _one_line(cli("primary", pri / "ok.csv", "--wavelength-nm", "632.8 V"), "--wavelength-nm")


@pytest.mark.parametrize("option, value", [
    ("--u-gain-rel", "-0.1"), ("--u-gain-rel", "nan"), ("--u-wavelength-rel", "inf"), ("--u-other-rel", "1e308"),
    ("--u-other-rel", "abc"), ("--u-gain-phase-deg", "-1"), ("--u-other-phase-deg", "nan"),
])
def test_primary_type_b_inputs_refused(cli, pri, option, value):
    """A negative, NaN, infinite or huge standard u (it entered the budget as given, or overflowed it)."""
    _one_line(cli("primary", pri / "ok.csv", f"{option}={value}"), option)


def test_primary_type_b_in_percent(cli, pri):
    docs = [json.loads(cli("primary", pri / "ok.csv", "--u-gain-rel", v, "--json").out)["points"][0]
            for v in ("0.1%", "0.001")]
    assert docs[0]["budget"]["output_gain"]["u_rel"] == pytest.approx(1e-3, rel=1e-12)
    assert docs[0]["u_sensitivity"] == pytest.approx(docs[1]["u_sensitivity"], rel=1e-12)


@pytest.mark.parametrize("option", ["--static-window", "--init-static", "--min-pose"])
@pytest.mark.parametrize("value", ["nan", "inf", "1e308", "-1e308"])
def test_imu_time_options_not_finite(cli, tmp_path, option, value):
    """NaN passed the engine's range checks and reached int(): an internal error before."""
    t = np.arange(200) / 50.0
    p = write_recording(Recording(channels={c: np.zeros_like(t) for c in ("ax", "ay", "az", "gx", "gy", "gz")}, t=t),
                        tmp_path / "z.csv")
    _one_line(cli("imu", "calibrate", p, f"{option}={value}"), option, "finite number of seconds")


# --- the simulators -------------------------------------------------------------------------------------------

@pytest.mark.parametrize("args, option", [
    (["imu", "--pose=nan"], "--pose"),  # NaN reached int(): an internal error
    (["imu", "--rotation=nan"], "--rotation"),
    (["imu", "--init=-5"], "--init"),  # a negative array size: an internal error
    (["imu", "--accel-noise=-1"], "--accel-noise"),  # used as given
    (["imu", "--gyro-ar1=1"], "--gyro-ar1"),
    (["imu", "--poses=2000000"], "--poses"),  # 4.5e8 samples
    (["interferometer", "--laser-noise=-1"], "--laser-noise"),
    (["interferometer", "--sensitivity=nan"], "--sensitivity"),
    (["interferometer", "--acceleration=1e308"], "alias"),  # NaN channels before
    (["shock", "--laser-noise=nan"], "--laser-noise"),
    (["shock", "--resonance-hz=-5"], "--resonance-hz"),
    (["shock", "--resonance-q=0"], "--resonance-q"),
    (["shock", "--reference-sensitivity=0"], "--reference-sensitivity"),
])
def test_simulator_options_refused(cli, tmp_path, args, option):
    _one_line(cli("simulate", args[0], "--out", tmp_path / "sim", *args[1:]), option)
    assert not (tmp_path / "sim").exists() or not any((tmp_path / "sim").iterdir())
