"""Regression on a real oscilloscope capture with correlated noise.

``tests/data/sine_adalm2000_scope_1khz.csv`` (MIT, R. Fredericks, see the
``.LICENSE.txt`` beside it): 8000 samples at 1 MS/s of a 1 kHz sine, eight
periods.  Its residual has lag-1 autocorrelation 0.25, so the white-noise
uncertainty is too small: the period-to-period scatter of the fitted
parameters was 1.4-2x the stated u.  Now the fit detects the colour and the
scatter of eight one-period fits must be consistent with their stated u.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from senscal import fit_sine
from senscal.diagnostics import has_warning

DATA = Path(__file__).resolve().parents[1] / "data" / "sine_adalm2000_scope_1khz.csv"
PERIOD = 1000  # samples per period (1 kHz at 1 MS/s)


@pytest.fixture(scope="module")
def scope():
    # Seven ';' metadata lines precede the header.
    df = pd.read_csv(DATA, skiprows=7)
    return df["Time(S)"].to_numpy(), df


def _scatter_statistic(t, y, freq, noise_model):
    """Pooled ``sum_q 7 s_q^2 / mean(u_q^2)`` of amplitude, phase, offset over eight periods.

    With honest u each term is about chi2_7 (u estimated with dof_effective
    each): the sum follows 21 F(21, 8 nu) approximately.
    """
    rows = []
    for k in range(t.size // PERIOD):
        sl = slice(k * PERIOD, (k + 1) * PERIOD)
        g = fit_sine(y[sl], t[sl], freq=freq, noise_model=noise_model)
        rows.append((g.amplitude, g.phase, g.offset, g.u_amplitude, g.u_phase, g.u_offset, g.dof_effective))
    r = np.array(rows)
    m = r.shape[0]
    stat = sum((m - 1) * np.var(r[:, j], ddof=1) / np.mean(r[:, j + 3] ** 2) for j in range(3))
    return stat, 3 * (m - 1), m * float(np.min(r[:, 6]))


@pytest.mark.parametrize("channel", ["CH1(V)", "CH2(V)"])
def test_scope_capture_uncertainty_matches_period_scatter(scope, channel):
    t, df = scope
    y = df[channel].to_numpy()
    whole = fit_sine(y, t)
    assert whole.residual_lag1 > 0.2
    assert whole.noise_model == "coloured" and has_warning(whole.warnings, "coloured-noise")
    white = fit_sine(y, t, noise_model="white")
    assert whole.u_amplitude > 1.3 * white.u_amplitude
    stat, df1, df2 = _scatter_statistic(t, y, whole.frequency, "auto")
    lo, hi = df1 * stats.f.ppf([0.0005, 0.9995], df1, df2)
    assert lo <= stat <= hi, (stat, lo, hi)
    # The white-noise u fails the same 99.9 % test: the scatter is too large.
    stat_w, df1, df2 = _scatter_statistic(t, y, whole.frequency, "white")
    hi_w = df1 * stats.f.ppf(0.9995, df1, df2)
    assert stat_w > hi_w, (stat_w, hi_w)
