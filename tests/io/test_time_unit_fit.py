"""A bare ``senscal fit`` on a time column in the wrong unit is named (issue 32): both directions.

Seconds under ``t [ms]`` make a 1 kHz record 1 MHz and 12.5 Hz 12.5 kHz; ms
(not whole numbers, so the counter-clock rule stays quiet) under a bare ``t``
or ``t [s]`` make 2 kHz 2 Hz and 12.5 Hz 0.0125 Hz. Neither is a contradiction
(nothing else states the rate), so each is a named ``time-unit-suspect``
warning (``--strict``: exit 3); the same records in their right units, and
typical recordings around the limits, stay quiet.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from senscal.io.plausibility import (MAX_SAMPLE_RATE_IN_UNIT, SLOW_SINE_HZ, SLOW_SINE_RATE_HZ, TIME_UNIT_WARNING,
                                     check_declared_unit, check_fitted_frequency)


def _sine(tmp_path: Path, name: str, *, header: str, fs: float, f: float = 12.5, scale: float = 1.0,
          n: int = 2000) -> Path:
    """``n`` samples of an ``f`` Hz sine at ``fs`` Hz; stamps (s) times ``scale`` under ``header`` (6 decimals)."""
    t = np.arange(n) / fs
    y = np.sin(2 * np.pi * f * t + 0.3) + 0.01 * np.random.default_rng(1).standard_normal(n)
    path = tmp_path / name
    pd.DataFrame({header: np.round(t * scale, 6), "y": y}).to_csv(path, index=False)
    return path


def _fit(cli, path, *args):
    r = cli("fit", path, "--json", *args)
    assert r.code == 0, r.err
    doc = json.loads(r.out)
    return doc["channels"]["y"]["frequency_hz"], [w for w in doc["warnings"] if w.startswith(TIME_UNIT_WARNING)]


def test_seconds_labelled_ms_are_named(cli, tmp_path):
    path = _sine(tmp_path, "s_as_ms.csv", header="t [ms]", fs=1000.0)
    f, sus = _fit(cli, path)
    assert f == pytest.approx(12500.0, rel=1e-3)                       # still the wrong number ...
    assert len(sus) == 1 and "seconds labelled ms" in sus[0] and "1e+06 Hz" in sus[0]  # ... but named
    assert cli("fit", path, "--strict").code == 3
    # The same record with its right unit: the right frequency, nothing named.
    f, sus = _fit(cli, _sine(tmp_path, "s.csv", header="t [s]", fs=1000.0))
    assert f == pytest.approx(12.5, rel=1e-4) and sus == []


@pytest.mark.parametrize("header", ["t", "t [s]"])
def test_milliseconds_read_as_seconds_are_named(cli, tmp_path, header):
    # 2 kHz in ms: stamps step by 0.5, not whole numbers (the counter-clock rule does not see them).
    path = _sine(tmp_path, "ms_as_s.csv", header=header, fs=2000.0, scale=1000.0)
    f, sus = _fit(cli, path)
    assert f == pytest.approx(0.0125, rel=1e-3)
    assert len(sus) == 1 and "in ms: 12.5 Hz at 2000 Hz" in sus[0], sus
    assert cli("fit", path, "--strict").code == 3
    # Stated right, it is right; stated by the user as seconds, or with a --freq the data have, it is taken.
    f, sus = _fit(cli, path, "--time-unit", "ms") if header == "t" else _fit(
        cli, _sine(tmp_path, "ms.csv", header="t [ms]", fs=2000.0, scale=1000.0))
    assert f == pytest.approx(12.5, rel=1e-4) and sus == []
    if header == "t":
        assert _fit(cli, path, "--time-unit", "s")[1] == []
    assert _fit(cli, path, "--freq", "0.0125")[1] == []


def test_typical_records_near_the_limits_stay_quiet(cli, tmp_path):
    # A hydraulic rig at 0.1 Hz on 20 Hz (the slowest vibration calibration), a 200 kHz digitiser stamping ms,
    # a seismometer-like 0.05 Hz sine on 10 Hz samples.
    for name, kw in [("rig.csv", dict(header="t", fs=20.0, f=0.1, n=4000)),
                     ("fast_ms.csv", dict(header="t [ms]", fs=2e5, f=1000.0, scale=1000.0, n=4000)),
                     ("seis.csv", dict(header="t", fs=10.0, f=0.05, n=4000))]:
        assert _fit(cli, _sine(tmp_path, name, **kw))[1] == [], name


def test_the_rules_themselves():
    assert MAX_SAMPLE_RATE_IN_UNIT["ms"] == 2e5 and SLOW_SINE_HZ == 0.1 and SLOW_SINE_RATE_HZ == 10.0
    t_ms = np.arange(1000) / 1e6                                  # 1 MHz, as read from 't [ms]'
    assert len(check_declared_unit(t_ms, "ms", "fit")) == 1
    assert check_declared_unit(np.arange(1000) / 1e5, "ms", "fit") == ()          # 100 kHz in ms: plausible
    assert len(check_declared_unit(np.arange(1000) / 1e9, "us", None)) == 1       # 1 GHz in us
    assert check_declared_unit(np.arange(1000) / 1e8, "us", None) == ()
    assert check_declared_unit(np.arange(1000) / 1e6, "min", "fit") == ()         # no bound for minutes
    slow = np.arange(1000) * 0.5
    assert len(check_fitted_frequency(slow, 0.0125)) == 1
    assert check_fitted_frequency(slow, 0.2) == ()                 # a frequency a slow rig uses
    assert check_fitted_frequency(np.arange(1000) / 20.0, 0.0125) == ()    # 20 Hz sampling: a DAQ rate
    assert check_fitted_frequency(slow[:1], 0.0125) == () and check_fitted_frequency(slow, float("nan")) == ()
