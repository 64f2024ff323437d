"""Compiled quaternion integration of the rotation between static poses."""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@nb.njit(cache=True)
def rotations_rk4(omega, t, first, last):
    """Rotation matrices of each interval by RK4 on ``q' = q (x) [0, w] / 2``.

    Parameters
    ----------
    omega : ndarray, shape (3, N)
        Body angular rate, rad/s (bias and scale already removed).
    t : ndarray, shape (N,)
        Sample times, s.
    first, last : ndarray of int, shape (K,)
        Sample index where each interval starts and ends (inclusive).

    Returns
    -------
    ndarray, shape (K, 3, 3)
        ``R_k``: a vector in the body frame at ``last`` expressed in the body
        frame at ``first`` is ``R_k v``.

    Notes
    -----
    The rate between two samples is taken linear in time (its value at the
    half step is the mean of the two), which makes RK4 fourth-order in the
    attitude for smooth motion; the quaternion is renormalised each step.
    """
    k_n = first.shape[0]
    out = np.empty((k_n, 3, 3))
    for k in range(k_n):
        q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
        for i in range(first[k], last[k]):
            h = t[i + 1] - t[i]
            wa0, wa1, wa2 = omega[0, i], omega[1, i], omega[2, i]
            wc0, wc1, wc2 = omega[0, i + 1], omega[1, i + 1], omega[2, i + 1]
            wb0, wb1, wb2 = 0.5 * (wa0 + wc0), 0.5 * (wa1 + wc1), 0.5 * (wa2 + wc2)
            # k1
            d0, d1, d2, d3 = _qmul(q0, q1, q2, q3, 0.0, wa0, wa1, wa2)
            k10, k11, k12, k13 = 0.5 * d0, 0.5 * d1, 0.5 * d2, 0.5 * d3
            # k2
            d0, d1, d2, d3 = _qmul(q0 + 0.5 * h * k10, q1 + 0.5 * h * k11, q2 + 0.5 * h * k12, q3 + 0.5 * h * k13,
                                   0.0, wb0, wb1, wb2)
            k20, k21, k22, k23 = 0.5 * d0, 0.5 * d1, 0.5 * d2, 0.5 * d3
            # k3
            d0, d1, d2, d3 = _qmul(q0 + 0.5 * h * k20, q1 + 0.5 * h * k21, q2 + 0.5 * h * k22, q3 + 0.5 * h * k23,
                                   0.0, wb0, wb1, wb2)
            k30, k31, k32, k33 = 0.5 * d0, 0.5 * d1, 0.5 * d2, 0.5 * d3
            # k4
            d0, d1, d2, d3 = _qmul(q0 + h * k30, q1 + h * k31, q2 + h * k32, q3 + h * k33, 0.0, wc0, wc1, wc2)
            k40, k41, k42, k43 = 0.5 * d0, 0.5 * d1, 0.5 * d2, 0.5 * d3
            q0 += h / 6.0 * (k10 + 2.0 * k20 + 2.0 * k30 + k40)
            q1 += h / 6.0 * (k11 + 2.0 * k21 + 2.0 * k31 + k41)
            q2 += h / 6.0 * (k12 + 2.0 * k22 + 2.0 * k32 + k42)
            q3 += h / 6.0 * (k13 + 2.0 * k23 + 2.0 * k33 + k43)
            n = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
            q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
        out[k, 0, 0] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
        out[k, 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
        out[k, 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
        out[k, 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
        out[k, 1, 1] = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
        out[k, 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
        out[k, 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
        out[k, 2, 1] = 2.0 * (q2 * q3 + q0 * q1)
        out[k, 2, 2] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)
    return out
