"""The scalar-measurement score kernel gives the general kernel's numbers bit for bit (issue 30)."""

from __future__ import annotations

import numpy as np
import pytest

from senscal.kalman._score import score_series, score_series_scalar


def _case(rng, n, p, T, *, varying, gaps, move_f, move_h):
    """A random stable one-measurement model with derivative stacks (time-major, as LevelLikelihood builds them)."""
    Tm = T if varying else 1
    F = np.zeros((Tm, n, n))
    F[:, range(n), range(n)] = rng.uniform(0.5, 1.0, (Tm, n))
    if n > 1:
        F[:, 0, 1] = rng.uniform(0.0, 0.1, Tm)
    B = rng.normal(0, 0.1, (Tm, n, n))
    Q = np.einsum("tij,tkj->tik", B, B) + 1e-3 * np.eye(n)
    H = np.zeros((T if move_h else 1, 1, n))
    H[:, 0, :] = rng.uniform(0.5, 1.5, (H.shape[0], n))
    R = np.full((1, 1, 1), 0.04)
    x0 = rng.normal(0, 0.1, n)
    P0 = np.eye(n) * 0.5
    y = rng.normal(0, 0.3, (T, 1))
    if gaps:
        y[rng.choice(T, T // 20, replace=False), 0] = np.nan
    useF = np.zeros(p, np.bool_)
    useH = np.zeros(p, np.bool_)
    dF = np.zeros((p, Tm if move_f else 1, n, n))
    dH = np.zeros((p, H.shape[0] if move_h else 1, 1, n))
    dQ = np.zeros((p, Tm, n, n))
    dR = np.zeros((p, 1, 1, 1))
    dP0 = np.zeros((p, n, n))
    dQ[0] = 2 * Q
    dR[1] = 2 * R
    if p > 2:
        dP0[2] = np.eye(n)
        dQ[2, :, n - 1, n - 1] = 0.3
    if move_f and p > 3:
        useF[3] = True
        dF[3, :, n - 1, n - 1] = F[:, n - 1, n - 1] * 0.2
    if move_h and p > 3:
        useH[3] = True
        dH[3, :, 0, 0] = rng.normal(0, 0.1, H.shape[0])
    return F, H, Q, R, x0, P0, np.ascontiguousarray(y), dF, dH, dQ, dR, dP0, useF, useH


@pytest.mark.parametrize("n,p,varying,gaps,move_f,move_h,allow_ss", [
    (1, 2, False, False, False, False, True),   # steady state reached and frozen
    (1, 2, True, True, False, False, False),    # irregular steps, missing samples
    (2, 4, True, False, True, False, False),    # a time constant moving F (coloured noise)
    (2, 4, True, True, False, True, False),     # a lag moving H (covariate)
    (2, 3, False, False, False, False, True),
])
def test_scalar_kernel_is_the_general_kernel(n, p, varying, gaps, move_f, move_h, allow_ss):
    rng = np.random.default_rng(n * 10 + p)
    a = _case(rng, n, p, 3000, varying=varying, gaps=gaps, move_f=move_f, move_h=move_h)
    for grad in (True, False):
        r1 = score_series(*a, allow_ss, grad)
        r2 = score_series_scalar(*a, allow_ss, grad)
        assert np.isfinite(r1[0])
        # The same operations in the same order: equal, not merely close.
        assert r1[0] == r2[0]
        assert np.array_equal(r1[1], r2[1])
        assert np.array_equal(r1[2], r2[2])
        assert r1[3] == r2[3]
    if allow_ss:
        assert r1[3] > 0  # the frozen-gain branch was exercised


def test_scalar_kernel_refuses_a_non_positive_innovation_variance():
    rng = np.random.default_rng(1)
    F, H, Q, R, x0, P0, y, dF, dH, dQ, dR, dP0, useF, useH = _case(rng, 1, 2, 50, varying=False, gaps=False,
                                                                   move_f=False, move_h=False)
    R = -np.ones((1, 1, 1))
    P0 = np.zeros((1, 1))
    r1 = score_series(F, H, Q, R, x0, P0, y, dF, dH, dQ, dR, dP0, useF, useH, False, True)
    r2 = score_series_scalar(F, H, Q, R, x0, P0, y, dF, dH, dQ, dR, dP0, useF, useH, False, True)
    assert np.isnan(r1[0]) and np.isnan(r2[0]) and r1[3] == r2[3] == -2
