"""``senscal fit`` states what the converter did (instrument), handles clipping, names what it cannot handle."""

from __future__ import annotations

import json
import math

import numpy as np

from senscal.diagnostics import warning_names
from senscal.io import Recording, write_recording
from senscal.jobs.fit import fit
from senscal.simulate.sine import adc, simulate_sine


def _rec(y, fs=1000.0):
    t = np.arange(y.size) / fs
    return Recording(channels={"ch1": y}, t=t, units={"ch1": "V"})


def test_clipped_record_is_refitted_on_unclipped_samples_and_covers():
    rng = np.random.default_rng(3)
    t = np.arange(2000) / 1000.0
    y = adc(np.sin(2 * math.pi * 12.5 * t + 0.4) + 0.3 + rng.normal(0, 0.05, t.size), clip=(-5, 1.25))
    res = fit(_rec(y))
    ch = res.channels["ch1"]
    inst = res.to_dict()["channels"]["ch1"]["instrument"]
    assert inst["clipped"] and inst["clipped_high"] and inst["n_clipped"] > 100 and inst["handled"]
    assert abs(ch.amplitude - 1.0) <= 3 * ch.u_amplitude and abs(ch.offset - 0.3) <= 3 * ch.u_offset
    assert ch.n_samples < 2000
    assert "clipped" not in warning_names(res.warnings)


def test_clipping_that_leaves_too_few_samples_is_named_and_strict_exits_3(cli, tmp_path):
    t = np.arange(400) / 1000.0
    rng = np.random.default_rng(4)
    y = adc(3.0 * np.sin(2 * math.pi * 12.5 * t) + rng.normal(0, 0.05, t.size), clip=0.3)
    p = write_recording(_rec(y), tmp_path / "clipped.csv")
    r = cli("fit", p, "--freq", "12.5", "--json", "--strict")
    assert r.code == 3 and "clipped" in r.err
    doc = json.loads(r.out)
    assert "clipped" in warning_names(doc["warnings"]) and doc["channels"]["ch1"]["instrument"]["clipped"]


def test_under_dithered_adc_is_named_and_strict_exits_3(cli, tmp_path):
    rec, _ = simulate_sine(n_channels=1, seed=2, noise=0.0015, clip=2.0, lsb=4 / 256)
    p = write_recording(rec, tmp_path / "adc.csv")
    r = cli("fit", p, "--json", "--strict")
    assert r.code == 3
    doc = json.loads(r.out)
    assert "under-dithered" in warning_names(doc["warnings"])
    inst = doc["channels"]["ch1"]["instrument"]
    assert inst["lsb"] == 4 / 256 and inst["under_dithered"] and inst["noise_lsb"] < 0.3


def test_white_record_has_instrument_and_consistency_and_no_warning(cli, tmp_path):
    rec, _ = simulate_sine(n_channels=2, seed=5)
    p = write_recording(rec, tmp_path / "white.csv")
    r = cli("fit", p, "--freq", "12.5", "--json", "--strict")
    assert r.code == 0, r.err
    d = json.loads(r.out)["channels"]["ch1"]
    assert d["instrument"]["clipped"] is False and d["instrument"]["lsb"] is None
    assert d["consistency"]["consistent"] and d["consistency"]["n_blocks"] == 4


def test_amplitude_step_mid_record_is_inconsistent_blocks():
    rng = np.random.default_rng(6)
    t = np.arange(4000) / 1000.0
    amp = np.where(t < 2.0, 1.0, 1.02)   # a 2 % gain step: 9 u of a block's amplitude
    y = amp * np.sin(2 * math.pi * 12.5 * t) + 0.3 + rng.normal(0, 0.05, t.size)
    res = fit(_rec(y))
    assert "inconsistent-blocks" in warning_names(res.warnings)
    q = {x.name: x for x in res.consistency["ch1"].quantities}
    assert not q["amplitude"].consistent and q["amplitude"].birge_ratio > 3


def test_simulate_sine_instrument_options(cli, tmp_path):
    r = cli("simulate", "sine", "--out", tmp_path, "--seed", "1", "--channels", "1", "--full-scale", "2.5",
            "--adc-bits", "10", "--jitter", "1e-5", "--flicker", "0.001")
    assert r.code == 0, r.err
    truth = json.loads((tmp_path / "sine_truth.json").read_text())
    assert truth["clip"] == 2.5 and truth["lsb"] == 5.0 / 1024 and truth["jitter_s"] == 1e-5
    y = np.loadtxt(tmp_path / "sine.csv", delimiter=",", skiprows=1)[:, 1]
    assert np.all(np.abs(y) <= 2.5) and np.allclose(y / (5.0 / 1024), np.round(y / (5.0 / 1024)))
    bad = cli("simulate", "sine", "--out", tmp_path / "x", "--adc-bits", "8")
    assert bad.code == 2 and "--full-scale" in bad.err
