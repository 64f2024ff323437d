"""QA: numerically hostile inputs give one-line errors, not tracebacks or warnings."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from senscal.errors import DataError
from senscal.io import Recording, write_recording
from senscal.sinefit import fit_sine


def _write(path, x, fs=1000.0):
    t = np.arange(x.size) / fs
    write_recording(Recording({"x": x}, t=t), path)
    return path


def _one_line_error(r):
    assert r.code == 2, (r.code, r.err)
    assert "Traceback" not in r.err
    assert len(r.err.strip().splitlines()) == 1, r.err


@pytest.mark.parametrize("freq", [None, 10.0])
def test_fit_sine_refuses_values_whose_squares_overflow(freq):
    t = np.arange(500) / 1000.0
    with pytest.raises(DataError, match="too large"):
        fit_sine(1e300 * np.sin(2 * np.pi * 10 * t), t, freq=freq)


def test_fit_sine_keeps_large_but_safe_values():
    t = np.arange(500) / 1000.0
    fit = fit_sine(1e100 * np.sin(2 * np.pi * 10 * t + 0.3), t, freq=10.0)
    assert abs(fit.amplitude / 1e100 - 1.0) < 1e-9


def test_cli_fit_huge_values(cli, tmp_path):
    f = _write(tmp_path / "huge.csv", 1e300 * np.sin(2 * np.pi * 10 * np.arange(1000) / 1000.0))
    _one_line_error(cli("fit", f))


def test_cli_fit_constant_channel_known_frequency_has_no_warning(cli, tmp_path):
    # A constant channel is not fitted (channel-not-fitted); alone in its file that is a one-line error,
    # reached without any numpy RuntimeWarning on the way.
    f = _write(tmp_path / "c.csv", np.ones(1000))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning from numpy now raises
        r = cli("fit", f, "--freq", "10", "--json")
    assert r.code == 2, r.err
    assert r.err.count("\n") == 1 and "constant" in r.err


def test_cli_response_dead_output_is_a_one_line_error(cli, tmp_path):
    f = _write(tmp_path / "c.csv", np.ones(1000))
    _one_line_error(cli("response", f, "--output", "x", "--input-amplitude", "100", "--freq", "10"))


def test_duplicate_time_message_shows_plain_numbers(cli, tmp_path):
    t = np.arange(100) / 100.0
    t[10] = t[9]
    f = tmp_path / "dup.csv"
    f.write_text("t,x\n" + "".join(f"{float(a)!r},{float(np.sin(a))!r}\n" for a in t))
    r = cli("fit", f)
    _one_line_error(r)
    assert "np.float64" not in r.err and "t=0.09 then 0.09" in r.err


@pytest.mark.parametrize("opts", [["--input-amplitude", "inf"],
                                  ["--input-amplitude", "100", "--static-sensitivity", "inf"]])
def test_cli_response_infinite_numbers(cli, tmp_path, opts):
    x = np.sin(2 * np.pi * 10 * np.arange(1000) / 1000.0)
    f = _write(tmp_path / "s.csv", x)
    _one_line_error(cli("response", f, "--output", "x", "--freq", "10", *opts))
