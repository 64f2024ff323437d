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


@nb.njit(cache=True, inline="always")
def _inv3(A, out):
    a, b, c = A[0, 0], A[0, 1], A[0, 2]
    d, e, f = A[1, 0], A[1, 1], A[1, 2]
    g, h, i = A[2, 0], A[2, 1], A[2, 2]
    c00 = e * i - f * h
    c01 = f * g - d * i
    c02 = d * h - e * g
    det = a * c00 + b * c01 + c * c02
    out[0, 0] = c00 / det
    out[1, 0] = c01 / det
    out[2, 0] = c02 / det
    out[0, 1] = (c * h - b * i) / det
    out[1, 1] = (a * i - c * g) / det
    out[2, 1] = (b * g - a * h) / det
    out[0, 2] = (b * f - c * e) / det
    out[1, 2] = (c * d - a * f) / det
    out[2, 2] = (a * e - b * d) / det


@nb.njit(cache=True)
def quadratic_ekf(wq, u, Q, Rinv, x0, P0, gate):
    """Extended Kalman filter on the six quadratic terms of the array.

    State ``w`` (3), process ``w_k = w_{k-1} + u_{k-1} + noise(Q)``;
    measurement ``W = w w^T - |w|^2 I`` as ``(W_xx, W_yy, W_zz, W_xy,
    W_xz, W_yz)`` with constant covariance ``R`` (given as ``Rinv``, 6x6).
    The update is done in information form, ``P+ = (P^-1 + H' R^-1 H)^-1``,
    which needs only 3x3 inverses; the normalised innovation squared comes
    from the Woodbury identity.  Steps whose NIS exceeds ``gate`` (if > 0)
    are rejected.
    """
    n = wq.shape[1]
    x = np.empty((3, n))
    P = np.empty((3, 3, n))
    nis = np.empty(n)
    rejected = np.zeros(n, dtype=np.bool_)
    xk = x0.copy()
    Pk = P0.copy()
    H = np.zeros((6, 3))
    nu = np.empty(6)
    RiH = np.empty((6, 3))
    Pi = np.empty((3, 3))
    M = np.empty((3, 3))
    Pn = np.empty((3, 3))
    g = np.empty(3)
    dx = np.empty(3)
    for k in range(n):
        if k > 0:
            for i in range(3):
                xk[i] += u[i, k - 1]
                for j in range(3):
                    Pk[i, j] += Q[i, j]
        a, b, c = xk[0], xk[1], xk[2]
        nu[0] = wq[0, k] + (b * b + c * c)
        nu[1] = wq[1, k] + (a * a + c * c)
        nu[2] = wq[2, k] + (a * a + b * b)
        nu[3] = wq[3, k] - a * b
        nu[4] = wq[4, k] - a * c
        nu[5] = wq[5, k] - b * c
        H[0, 1] = -2 * b
        H[0, 2] = -2 * c
        H[1, 0] = -2 * a
        H[1, 2] = -2 * c
        H[2, 0] = -2 * a
        H[2, 1] = -2 * b
        H[3, 0] = b
        H[3, 1] = a
        H[4, 0] = c
        H[4, 2] = a
        H[5, 1] = c
        H[5, 2] = b
        # R^-1 H, g = H' R^-1 nu, M = H' R^-1 H, q = nu' R^-1 nu
        q = 0.0
        for r in range(6):
            s = 0.0
            for m in range(6):
                s += Rinv[r, m] * nu[m]
            q += nu[r] * s
            for j in range(3):
                t = 0.0
                for m in range(6):
                    t += Rinv[r, m] * H[m, j]
                RiH[r, j] = t
        for i in range(3):
            s = 0.0
            for r in range(6):
                s += RiH[r, i] * nu[r]
            g[i] = s
            for j in range(3):
                t = 0.0
                for r in range(6):
                    t += H[r, i] * RiH[r, j]
                M[i, j] = t
        _inv3(Pk, Pi)
        for i in range(3):
            for j in range(3):
                M[i, j] += Pi[i, j]
        _inv3(M, Pn)
        d2 = q
        for i in range(3):
            s = 0.0
            for j in range(3):
                s += Pn[i, j] * g[j]
            dx[i] = s
            d2 -= g[i] * s
        nis[k] = d2
        if gate > 0 and d2 > gate:
            rejected[k] = True
        else:
            for i in range(3):
                xk[i] += dx[i]
                for j in range(3):
                    Pk[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
        x[:, k] = xk
        P[:, :, k] = Pk
    return x, P, nis, rejected
