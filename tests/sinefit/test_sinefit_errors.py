"""Bad input to the sine fit raises one-line senscal errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from senscal import fit_sine
from senscal.errors import ConvergenceError, DataError, InputError, TooFewSamplesError

T = np.arange(200) / 100.0
Y = np.sin(2 * math.pi * 3 * T)


def test_nan_names_channel_and_sample():
    y = np.stack([Y, Y.copy()])
    y[1, 17] = np.nan
    with pytest.raises(DataError, match=r"channel 1 .*data row 18"):
        fit_sine(y, T, freq=3)


def test_too_few_samples():
    with pytest.raises(TooFewSamplesError, match="at least 4"):
        fit_sine(Y[:3], T[:3], freq=3)


def test_above_nyquist():
    with pytest.raises(InputError, match="Nyquist"):
        fit_sine(Y, fs=100.0, freq=60.0)


def test_non_monotonic_time():
    t = T.copy()
    t[50] = t[49]
    with pytest.raises(DataError, match="duplicate"):
        fit_sine(Y, t, freq=3)


def test_record_much_shorter_than_period_is_refused():
    t = np.linspace(0, 1e-6, 50)
    with pytest.raises(DataError, match="too short"):
        fit_sine(np.sin(t), t, freq=1e-3)


def test_flat_signal_without_frequency():
    with pytest.raises(ConvergenceError, match="no sinusoid"):
        fit_sine(np.ones(100), fs=10.0)


def test_t_and_fs_both():
    with pytest.raises(InputError, match="not both"):
        fit_sine(Y, T, fs=100.0, freq=3)


def test_bad_weights():
    with pytest.raises(InputError, match="weights"):
        fit_sine(Y, T, freq=3, weights=-np.ones(T.size))
