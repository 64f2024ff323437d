"""``senscal primary --heterodyne`` (ISO 16063-41 style carrier): demodulation, its filter's bound, bad input.

Coverage against simulated truth (the ``heterodyne-*`` cases of senscal.validation.primary) runs in
test_coverage_primary.py with a few seeds, and with 200 in ``benchmarks/bench_coverage.py primary --only
heterodyne``. Here: on noise-free carriers the error stays inside the bound the ``demodulation_filter``
term states (the derivation is in senscal.primary.heterodyne), the decimated noise stays white, the carrier's
offset and drift are removed, and the refusals are one line.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.errors import DataError, InputError
from senscal.primary.heterodyne import _demodulate, calibrate_heterodyne, demodulate_heterodyne
from senscal.simulate.interferometer import simulate_interferometer

FS = 500_000.0


def _het(freq=160.0, **kw):
    kw.setdefault("fs", FS)
    kw.setdefault("duration", 0.1)
    rec, tr = simulate_interferometer(freq=freq, heterodyne=True, carrier_hz=kw["fs"] / 4, **kw)
    return rec, tr, rec.channels


@pytest.mark.parametrize("freq, acc, reference", [(10.0, 0.5, True), (160.0, None, False), (1000.0, None, True),
                                                  (5000.0, None, False)])
def test_noise_free_error_inside_the_filter_bound(freq, acc, reference):
    # no noise, carrier 0.2 % off and drifting: what is left is the demodulation's own error, which the
    # budget's demodulation_filter term bounds (sqrt 3 times its u: a rectangular bound)
    fs = 1_000_000.0 if freq > 2000 else FS
    rec, tr, c = _het(freq, acceleration=acc, fs=fs, duration=0.2 if freq < 100 else 0.05, laser_noise=0.0,
                      output_noise_rel=0.0, carrier_offset_hz=0.002 * fs / 4, carrier_drift_hz=10.0, seed=3)
    p, dem = calibrate_heterodyne(c["H"], c["out"], fs, carrier_hz=fs / 4, reference=c["ref"] if reference else None,
                                  freq=freq)
    b = p.budget["demodulation_filter"]
    assert 0 < b["u_rel"] < 1e-5 and dem.ripple < 2e-5
    assert abs(p.sensitivity / tr["sensitivity"] - 1) <= math.sqrt(3) * b["u_rel"]
    assert abs(p.phase_deg - tr["phase_deg"]) <= math.sqrt(3) * b["u_phase_deg"]


def test_decimated_noise_is_white():
    # kappa = 1 / (D sum h^2): the noise density at low frequency over the white equivalent of its variance;
    # the power-complementary transition keeps it at 1, so the sine fit's white-noise u holds
    rec, tr, c = _het(1000.0, seed=4)
    *_, dem, _w = demodulate_heterodyne(c["H"], FS, carrier_hz=FS / 4, reference=c["ref"], freq=1000.0)
    assert dem.decimation > 1 and abs(dem.kappa - 1) < 0.01
    # and measured: the demodulated phase of a carrier without motion, lag-one autocorrelation within chance
    rng = np.random.default_rng(5)
    n = 200_000
    k = np.arange(n)
    sig = np.cos(2 * np.pi * 0.25 * k + 0.3 * np.sin(2 * np.pi * 2e-4 * k)) + 0.05 * rng.standard_normal(n)
    i, q, _, d2, _ = demodulate_heterodyne(sig, 1.0, carrier_hz=0.25, freq=2e-4, harmonics=1)
    ph = np.unwrap(np.arctan2(q, i))
    r = ph - np.polyval(np.polyfit(np.arange(ph.size), ph, 2), np.arange(ph.size))
    t = np.arange(ph.size)
    A = np.column_stack([np.sin(2 * np.pi * 2e-4 * d2.decimation * t), np.cos(2 * np.pi * 2e-4 * d2.decimation * t)])
    r = r - A @ np.linalg.lstsq(A, r, rcond=None)[0]
    lag1 = float(r[1:] @ r[:-1] / (r @ r))
    assert abs(lag1) < 4.0 / math.sqrt(r.size)  # white: |r1| ~ N(0, 1/N); 4 sigma


def test_carrier_offset_and_drift_are_removed_without_reference():
    rec, tr, c = _het(160.0, duration=0.25, carrier_offset_hz=300.0, carrier_drift_hz=40.0, seed=5)
    p, dem = calibrate_heterodyne(c["H"], c["out"], FS, carrier_hz=FS / 4)
    assert dem.carrier_offset_hz == pytest.approx(300.0 + 40.0 / 2, abs=5.0)  # at the record's centre
    assert dem.carrier_drift_hz == pytest.approx(40.0, abs=2.0)
    assert abs(p.sensitivity - tr["sensitivity"]) <= 4 * p.u_sensitivity
    assert abs(p.phase_deg - tr["phase_deg"]) <= 4 * p.u_phase_deg
    assert p.frequency_hz == pytest.approx(160.0, rel=1e-5)  # estimated, not given
    assert not any(w.startswith("carrier-offset") for w in p.warnings)


def test_carrier_far_from_nominal_is_named():
    rec, tr, c = _het(160.0, carrier_offset_hz=0.03 * FS / 4, seed=6)
    p, dem = calibrate_heterodyne(c["H"], c["out"], FS, carrier_hz=FS / 4, freq=160.0)
    assert any(w.startswith("carrier-offset:") for w in p.warnings)
    assert abs(p.sensitivity - tr["sensitivity"]) <= 4 * p.u_sensitivity


def test_carrier_above_nyquist_is_refused():
    rec, tr, c = _het(160.0, seed=7)
    with pytest.raises(InputError, match="Nyquist"):
        calibrate_heterodyne(c["H"], c["out"], FS, carrier_hz=0.6 * FS)


def test_carrier_below_twice_the_doppler_shift_is_refused():
    # 10 Hz at 0.5 m/s^2: a 25 kHz Doppler shift on a 40 kHz carrier
    rec, tr = simulate_interferometer(freq=10.0, acceleration=0.5, fs=FS, duration=0.2, heterodyne=True,
                                      carrier_hz=40_000.0, seed=8)
    c = rec.channels
    with pytest.raises(DataError, match="below twice the largest Doppler shift"):
        _demodulate(c["H"], FS, 40_000.0, None, 10.0, 3, 1, 1e-6)


def test_reversed_doppler_sign():
    rec, tr, c = _het(160.0, seed=9)
    # the other arm shifted: the phase runs against the displacement (conjugate carrier about the reference)
    k = np.arange(c["H"].size)
    mirrored = c["H"] * np.cos(2 * np.pi * 0.5 * k)  # f_c -> fs/2 - f_c flips the Doppler sign; fs/4 stays
    with pytest.raises(DataError, match="carrier-sign -1"):
        calibrate_heterodyne(mirrored, c["out"], FS, carrier_hz=FS / 4, freq=160.0)
    p, _ = calibrate_heterodyne(mirrored, c["out"], FS, carrier_hz=FS / 4, freq=160.0, sign=-1)
    assert abs(p.sensitivity - tr["sensitivity"]) <= 4 * p.u_sensitivity


@pytest.fixture(scope="module")
def het_dir(tmp_path_factory):
    from senscal.io import write_recording

    d = tmp_path_factory.mktemp("heterodyne")
    rec, tr = simulate_interferometer(freq=160.0, fs=FS, duration=0.1, seed=10, heterodyne=True, carrier_hz=FS / 4)
    write_recording(rec, d / "h160.npz")
    # 10 Hz at 0.5 m/s^2: a 25 kHz Doppler shift on a 40 kHz carrier
    rec, tr = simulate_interferometer(freq=10.0, acceleration=0.5, fs=FS, duration=0.2, seed=12, heterodyne=True,
                                      carrier_hz=40_000.0)
    write_recording(rec, d / "h10_low_carrier.npz")
    return d


def test_cli_heterodyne_json(cli, het_dir):
    for extra in (["--carrier-hz", "125 kHz"], ["--carrier-channel", "ref"]):
        r = cli("primary", het_dir / "h160.npz", "--heterodyne", "H", *extra, "--json")
        assert r.code == 0, r.err
        doc = json.loads(r.out)
        (p,) = doc["points"]
        assert "heterodyne" in doc["method"]
        assert p["demodulation"]["decimation"] >= 1 and "demodulation_filter" in p["budget"]
        assert p["sensitivity"] == pytest.approx(0.01, rel=1e-4)


@pytest.mark.parametrize("args, words", [
    (["--heterodyne", "H"], "--carrier-hz"),
    (["--heterodyne", "H", "--carrier-hz", "300000"], "Nyquist"),
    (["--heterodyne", "H", "--carrier-hz", "125000", "--output", "H"], "accelerometer"),
    (["--heterodyne", "H", "--carrier-channel", "H"], "reference carrier"),
])
def test_cli_heterodyne_bad_input_one_line_exit_2(cli, het_dir, args, words):
    r = cli("primary", het_dir / "h160.npz", *args)
    assert r.code == 2, r.err
    assert len(r.err.strip().splitlines()) == 1 and words in r.err


def test_cli_carrier_below_twice_the_doppler_shift(cli, het_dir, tmp_path):
    r = cli("primary", het_dir / "h10_low_carrier.npz", "--heterodyne", "H", "--carrier-hz", "40000")
    assert r.code == 2, r.err
    assert len(r.err.strip().splitlines()) == 1 and "below twice the largest Doppler shift" in r.err
    r = cli("simulate", "interferometer", "--out", tmp_path / "s", "--freqs", "160", "--fs", "100000",
            "--heterodyne", "--carrier-hz", "60000")
    assert r.code == 2 and len(r.err.strip().splitlines()) == 1 and "Nyquist" in r.err


@pytest.mark.parametrize("mutate, words", [
    (lambda h: h[:3000], "demodulated samples"),
    (lambda h: h[:500], "at least 1000"),
    (lambda h: 0.0 * h, "constant"),
    (lambda h: 1e300 * h, "overflow"),
])
def test_unusable_carrier_is_refused(mutate, words):
    rec, tr, c = _het(160.0, duration=0.05, seed=11)
    h = mutate(c["H"])
    with pytest.raises(DataError, match=words):
        calibrate_heterodyne(h, c["out"][:h.size], FS, carrier_hz=FS / 4, freq=160.0)
