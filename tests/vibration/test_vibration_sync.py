"""Double-centrifuge angle synchronisation: cutting records to whole revolutions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from senscal.errors import DataError, TooFewSamplesError
from senscal.vibration import cut_whole_revolutions, fit_against_angle


@given(theta0=st.floats(0.5, 359.5), step=st.floats(1.0, 90.0), n=st.integers(30, 400),
       direction=st.sampled_from([1, -1]), wrapped=st.booleans())
def test_cut_starts_after_a_crossing_and_holds_whole_revolutions(theta0, step, n, direction, wrapped):
    cum = theta0 + direction * step * np.arange(n)
    t = np.arange(n) * 0.01
    total = (abs(cum[-1] - cum[0])) / 360.0
    angle = np.mod(cum, 360.0) if wrapped else cum
    k = np.floor(direction * cum / 360.0)
    crossings = np.flatnonzero(np.diff(k) != 0) + 1
    if crossings.size < 2:
        with pytest.raises(TooFewSamplesError):
            cut_whole_revolutions(angle, t)
        return
    s = cut_whole_revolutions(angle, t)
    assert s.direction == direction
    # first sample after a crossing, last sample before a later crossing
    assert k[s.start] == k[s.start - 1] + 1
    assert k[s.stop] == k[s.stop - 1] + 1
    assert s.revolutions == int(k[s.stop] - k[s.start]) >= 1
    assert s.revolutions <= total
    # the kept samples span just under the whole revolutions
    span = abs(cum[s.stop - 1] - cum[s.start]) / 360.0
    assert s.revolutions - step / 360.0 * 2 <= span < s.revolutions
    assert s.frequency == pytest.approx(step / 360.0 / 0.01, rel=1e-9)


def test_angle_that_turns_back_is_refused():
    a = np.concatenate([np.linspace(0, 700, 50), np.linspace(690, 1500, 50)])
    with pytest.raises(DataError, match="steadily"):
        cut_whole_revolutions(a, np.arange(a.size) * 0.01)


@given(phi=st.floats(-3.0, 3.0), amp=st.floats(0.1, 10.0))
def test_fit_against_angle_returns_phase_at_angle_zero(phi, amp):
    ang = 37.0 + 7.3 * np.arange(300)  # non-uniform start, about 6 revolutions
    y = amp * np.sin(np.radians(ang) + phi) + 0.3
    f = fit_against_angle(y, np.mod(ang, 360.0))
    assert f.amplitude == pytest.approx(amp, rel=1e-9)
    assert math.remainder(f.phase - phi, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
