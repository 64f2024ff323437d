"""The fit job: typed result, the registry's quantities, a table, and --save through the job."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from senscal.errors import DataError
from senscal.io import Recording, write_recording
from senscal.jobs import run
from senscal.jobs.fit import FitOptions, FitResult, fit


@pytest.fixture
def sine_csv(tmp_path):
    rng = np.random.default_rng(7)
    t = np.arange(4000) / 1000.0
    rec = Recording(channels={"a": 2.0 * np.sin(2 * math.pi * 12.5 * t + 0.4) + 0.1 + rng.normal(0, 0.05, t.size),
                              "b": 0.5 * np.sin(2 * math.pi * 12.5 * t - 1.0) + rng.normal(0, 0.05, t.size),
                              "n": np.arange(t.size, dtype=float)}, t=t, units={"a": "V", "b": "V"})
    return write_recording(rec, tmp_path / "s.csv"), rec


def test_result_is_typed_and_the_document_is_built_from_it(sine_csv):
    path, rec = sine_csv
    res = fit(path, FitOptions(freq=12.5))
    assert isinstance(res, FitResult) and list(res.channels) == ["a", "b"]
    assert "n" in res.not_fitted and res.warning_names == ("channel-not-fitted",)
    doc = res.to_dict()
    assert list(doc) == ["file", "channels", "not_fitted", "warnings"]
    a = res.channels["a"]
    assert doc["channels"]["a"]["amplitude"] == a.amplitude
    assert doc["channels"]["a"]["phase_deg"] == math.degrees(a.phase)
    # A Recording in memory gives the same numbers as its file.
    mem = fit(rec, FitOptions(freq=12.5))
    assert mem.channels["a"].amplitude == pytest.approx(a.amplitude, rel=1e-9)


def test_quantities_are_the_registry_names_and_leave_out_a_known_frequency(sine_csv):
    path, _ = sine_csv
    est = run("fit", path, FitOptions(channels=("a", "b")))
    names = [q.name for q in est.quantities()]
    assert names == [f"{c}.{q}" for c in ("a", "b") for q in ("amplitude", "phase", "offset", "frequency")]
    doc = est.to_dict()["channels"]
    by = {q.name: q for q in est.quantities()}
    assert by["a.phase"].unit == "deg" and by["a.phase"].value == doc["a"]["phase_deg"]
    assert by["b.frequency"].uncertainty == doc["b"]["u_frequency_hz"] and by["b.frequency"].unit == "Hz"
    known = fit(path, FitOptions(channels=("a",), freq=12.5))
    assert [q.name for q in known.quantities()] == ["a.amplitude", "a.phase", "a.offset"]


def test_dataframe_one_row_per_channel(sine_csv):
    path, _ = sine_csv
    df = fit(path, FitOptions(freq=12.5)).to_dataframe()
    assert list(df["channel"]) == ["a", "b"] and {"amplitude", "u_amplitude", "phase_deg"} <= set(df.columns)


def test_options_are_checked():
    from senscal.errors import InputError

    with pytest.raises(InputError, match="--noise-model must be one of"):
        FitOptions(noise_model="pink")
    assert FitOptions(channels=["a"]).channels == ("a",)


def test_no_channel_fits_is_one_error(tmp_path):
    t = np.arange(100) / 100.0
    p = write_recording(Recording(channels={"c": np.ones(100)}, t=t), tmp_path / "c.csv")
    with pytest.raises(DataError, match="constant"):
        fit(p)


def test_save_with_known_frequency_stores_the_quantities(cli, sine_csv, tmp_path):
    # A known frequency has u = 0, which the registry refuses: it is left out, the rest is stored.
    from senscal.registry import open_registry

    path, _ = sine_csv
    db = tmp_path / "reg.sqlite"
    with open_registry(f"sqlite:///{db}") as reg:
        reg.add_sensor("SN-9", "accelerometer")
    r = cli("fit", path, "--freq", "12.5", "--json", "--save", "--sensor", "SN-9", "--db", f"sqlite:///{db}",
            "--date", "2026-01-02")
    assert r.code == 0, r.err
    with open_registry(f"sqlite:///{db}") as reg:
        (cal,) = reg.calibrations("SN-9")
    assert {q.name for q in cal.quantities} == {f"{c}.{q}" for c in "ab" for q in ("amplitude", "phase", "offset")}
    assert cal.result == json.loads(r.out) and cal.job == "fit"
