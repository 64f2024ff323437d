"""CUSUM detector: run lengths against the requested false-alarm rate."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.drift.detect import cusum, cusum_arl, cusum_threshold
from senscal.errors import InputError


def test_brook_evans_matches_published_arl():
    # Montgomery, Introduction to Statistical Quality Control, table 9.3
    # (two-sided, k = 0.5): h = 4 -> ARL0 168, ARL(1 sd) 8.38; h = 5 -> 465.
    assert cusum_arl(4.0, 0.5) / 2 == pytest.approx(168, rel=0.01)
    assert cusum_arl(5.0, 0.5) / 2 == pytest.approx(465, rel=0.01)
    assert cusum_arl(4.0, 0.5, shift=1.0) == pytest.approx(8.38, rel=0.01)


def test_in_control_run_length_matches_requested_rate():
    rng = np.random.default_rng(31)
    arl0, S = 150.0, 1500
    z = rng.standard_normal((S, 4000))
    res = cusum(z, arl0)
    assert np.all(res.alarm >= 0)
    rl = res.alarm + 1.0
    # Run lengths are close to geometric: sd ~ mean, so the mean of S has a
    # relative standard error of 1/sqrt(S).
    assert abs(rl.mean() / arl0 - 1) < 4 / np.sqrt(S)


def test_onset_estimate_of_a_step():
    rng = np.random.default_rng(32)
    z = rng.standard_normal((200, 600))
    z[:, 300:] += 1.5
    arl0 = 1e4
    res = cusum(z, arl0)
    early = res.alarm < 300
    # False alarms before the step: at most a binomial 4-sd excess over 300/ARL0.
    p = 300 / arl0
    assert early.sum() <= 200 * p + 4 * np.sqrt(200 * p * (1 - p))
    ok = ~early
    assert np.all(res.direction[ok] == 1)
    assert abs(np.median(res.onset[ok]) - 300) <= 2
    # Detection delay near the Markov-chain ARL at that shift (sd of a run
    # length below its mean at this shift: 4/sqrt(n) relative).
    delay = np.mean(res.alarm[ok] - 300 + 1)
    assert delay == pytest.approx(cusum_arl(res.threshold, 0.5, shift=1.5), rel=4 / np.sqrt(ok.sum()))


def test_bad_rates():
    with pytest.raises(InputError):
        cusum_threshold(1.0)
    with pytest.raises(InputError):
        cusum(np.zeros(10), 100.0, k=0.0)


def test_channel_residuals_remove_common_mode_and_are_standard_normal():
    from senscal.drift.core import channel_residuals

    rng = np.random.default_rng(33)
    m, T = 3, 20000
    A = rng.normal(size=(m, m))
    S = A @ A.T + np.eye(m)
    Hs = np.ones((m, 1))
    v = np.linalg.cholesky(S) @ rng.standard_normal((m, T))
    Sc = np.repeat(S[:, :, None], T, axis=2)
    z = channel_residuals(v, Sc, Hs)
    # Unit variance within 4 sd of the sample variance of T normals.
    assert np.all(np.abs(z.var(axis=1) - 1) < 4 * np.sqrt(2 / T))
    shifted = channel_residuals(v + 5.0, Sc, Hs)  # a common shift (signal misfit) is invisible
    assert np.allclose(shifted, z, atol=1e-9)
    one = v.copy()
    one[1] += 5.0  # a single channel's shift is not
    assert channel_residuals(one, Sc, Hs)[1].mean() > 1.0
