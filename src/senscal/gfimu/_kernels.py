"""Compiled recursions for the array's angular-velocity filters."""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def quaternion_integrate(omega, t, q0):
    """Body-to-navigation quaternion from body rates (trapezoid-mean rotation per step).

    Each step applies the exact rotation of the mean rate over the step,
    ``q_k = q_{k-1} (x) exp(0.5 * dt * (w_{k-1} + w_k) / 2)``; second-order
    accurate, and the quaternion stays unit by construction.
    """
    n = omega.shape[1]
    q = np.empty((4, n))
    q[:, 0] = q0 / np.sqrt(np.sum(q0 * q0))
    for k in range(1, n):
        dt = t[k] - t[k - 1]
        rx = 0.5 * dt * (omega[0, k - 1] + omega[0, k])
        ry = 0.5 * dt * (omega[1, k - 1] + omega[1, k])
        rz = 0.5 * dt * (omega[2, k - 1] + omega[2, k])
        ang = np.sqrt(rx * rx + ry * ry + rz * rz)
        c = np.cos(0.5 * ang)
        s = 0.5 - ang * ang / 48.0 if ang < 1e-4 else np.sin(0.5 * ang) / ang
        bw, bx, by, bz = c, s * rx, s * ry, s * rz
        aw, ax, ay, az = q[0, k - 1], q[1, k - 1], q[2, k - 1], q[3, k - 1]
        qw = aw * bw - ax * bx - ay * by - az * bz
        qx = aw * bx + ax * bw + ay * bz - az * by
        qy = aw * by - ax * bz + ay * bw + az * bx
        qz = aw * bz + ax * by - ay * bx + az * bw
        nrm = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        q[0, k] = qw / nrm
        q[1, k] = qx / nrm
        q[2, k] = qy / nrm
        q[3, k] = qz / nrm
    return q


@nb.njit(cache=True)
def rate_filter(y, u, Q, R, x0, P0, gate):
    """Three-state random-walk-plus-control Kalman filter (fallback kernel).

    ``x_k = x_{k-1} + u_{k-1} + w_k``, ``z_k = x_k + v_k`` with ``R`` per step
    (3, 3, T); NaN components of ``z`` are skipped; a step whose normalised
    innovation squared exceeds ``gate`` (if > 0) is rejected.  Joseph form.
    """
    n = y.shape[1]
    x = np.empty((3, n))
    P = np.empty((3, 3, n))
    nis = np.full(n, np.nan)
    rejected = np.zeros(n, dtype=np.bool_)
    xk = x0.copy()
    Pk = P0.copy()
    eye = np.eye(3)
    for k in range(n):
        if k > 0:
            xk = xk + u[:, k - 1]
            Pk = Pk + Q
        idx = np.empty(3, dtype=np.int64)
        m = 0
        for i in range(3):
            if not np.isnan(y[i, k]):
                idx[m] = i
                m += 1
        if m > 0:
            H = np.zeros((m, 3))
            Rm = np.empty((m, m))
            nu = np.empty(m)
            for a in range(m):
                H[a, idx[a]] = 1.0
                nu[a] = y[idx[a], k] - xk[idx[a]]
                for b in range(m):
                    Rm[a, b] = R[idx[a], idx[b], k]
            S = H @ Pk @ H.T + Rm
            Si = np.linalg.inv(S)
            d2 = nu @ Si @ nu
            nis[k] = d2
            if gate > 0 and d2 > gate:
                rejected[k] = True
            else:
                K = Pk @ H.T @ Si
                xk = xk + K @ nu
                A = eye - K @ H
                Pk = A @ Pk @ A.T + K @ Rm @ K.T
                Pk = 0.5 * (Pk + Pk.T)
        x[:, k] = xk
        P[:, :, k] = Pk
    return x, P, nis, rejected
