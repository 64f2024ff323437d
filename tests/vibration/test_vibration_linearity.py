"""Amplitude linearity against the simulated nonlinearity."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import linregress

from senscal.errors import TooFewSamplesError
from senscal.simulate.vibration import simulate_centrifuge
from senscal.vibration import amplitude_linearity, response_point

LEVELS = (20.0, 40.0, 60.0, 80.0, 100.0)


def _fit_levels(cubic, seed, harmonics=3):
    recs, truth = simulate_centrifuge(frequencies=(1.0,), accelerations=LEVELS, cubic=cubic, seed=seed, min_duration=10.0)
    pts = [response_point(r["output"], r.time, input_amplitude=a, angle_deg=r["angle"], harmonics=harmonics)
           for r, a in zip(recs, LEVELS)]
    return pts, truth


def test_cubic_nonlinearity_is_measured():
    pts, truth = _fit_levels(cubic=2e-6, seed=8)
    lin = amplitude_linearity(LEVELS, [p.output_amplitude for p in pts], [p.u_output_amplitude for p in pts])
    # The truth: exact fundamental amplitudes of the model through the same line definition.
    y_true = np.array([p["sensitivity"] * p["acceleration"] for p in truth["points"]])
    lr = linregress(LEVELS, y_true)
    dev_true = y_true - (lr.slope * np.array(LEVELS) + lr.intercept)
    lin_true = 100 * np.max(np.abs(dev_true)) / y_true.max()
    u_out = max(p.u_output_amplitude for p in pts)
    # Each deviation is a linear combination of the outputs with coefficients of
    # magnitude <= 1 + 1/n + ..., bounded by 2 u per level; 4 sigma of that.
    assert abs(lin.linearity_percent - lin_true) < 100 * 4 * 2 * u_out / y_true.max()
    assert lin.linearity_percent > 0.1  # the model's 0.2 % is clearly seen
    assert lin.slope == pytest.approx(lr.slope, abs=4 * lin.u_slope)


def test_linear_sensor_has_linearity_at_noise_level():
    pts, truth = _fit_levels(cubic=0.0, seed=9, harmonics=1)
    lin = amplitude_linearity(LEVELS, [p.output_amplitude for p in pts], [p.u_output_amplitude for p in pts])
    u_out = max(p.u_output_amplitude for p in pts)
    assert lin.linearity_percent < 100 * 4 * 2 * u_out / lin.full_scale_output
    assert abs(lin.slope - truth["points"][0]["sensitivity"]) < 4 * lin.u_slope


@given(scale=st.floats(1e-3, 1e3), gain=st.floats(0.01, 10.0))
def test_linearity_is_invariant_to_units(scale, gain):
    x = np.array([1.0, 2.0, 3.0, 5.0])
    y = gain * (x + 0.01 * x**2)
    a = amplitude_linearity(x, y)
    b = amplitude_linearity(scale * x, scale * y)
    assert b.linearity_percent == pytest.approx(a.linearity_percent, rel=1e-7)
    assert b.slope == pytest.approx(a.slope, rel=1e-9)


def test_too_few_levels():
    with pytest.raises(TooFewSamplesError, match="at least 3"):
        amplitude_linearity([1.0, 2.0], [1.0, 2.0])
