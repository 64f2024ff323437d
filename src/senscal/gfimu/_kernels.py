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
    nrm = np.sqrt(np.sum(q0 * q0))
    # Element loops, not q[:, 0] = ...: numba's broadcasting setitem compiles ~15 s of error-message code.
    for i in range(4):
        q[i, 0] = q0[i] / nrm
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


@nb.njit(cache=True, inline="always")
def _below_cap(Pk, xk, wq, k):
    """Is the rate variance still below the squared rate magnitude (the widest a re-acquisition needs)?

    ``|w|^2`` is taken as the larger of the state's and the measurement's
    (``trace W = -2 |w|^2``), floored at 1e-6 (rad/s)^2: a rate covariance
    as wide as the rate itself already lets the filter accept any
    measurement of that magnitude, and widening further only invites
    overflow.
    """
    m = max(xk[0] * xk[0] + xk[1] * xk[1] + xk[2] * xk[2], -0.5 * (wq[0, k] + wq[1, k] + wq[2, k]), 1e-6)
    return Pk[0, 0] + Pk[1, 1] + Pk[2, 2] < 3.0 * m


@nb.njit(cache=True, inline="always")
def _quadratic_innovation(wq, k, xk, nu, H):
    """Innovation of the six quadratic terms at sample k and its Jacobian in ``w`` (H: 6x3, zeros kept)."""
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


@nb.njit(cache=True)
def quadratic_ekf(wq, u, Q, Rinv, x0, P0, gate, reset_after=0, inflate=4.0):
    """Extended Kalman filter on the six quadratic terms of the array.

    State ``w`` (3), process ``w_k = w_{k-1} + u_{k-1} + noise(Q)``;
    measurement ``W = w w^T - |w|^2 I`` as ``(W_xx, W_yy, W_zz, W_xy,
    W_xz, W_yz)`` with constant covariance ``R`` (given as ``Rinv``, 6x6).
    The update is done in information form, ``P+ = (P^-1 + H' R^-1 H)^-1``,
    which needs only 3x3 inverses; the normalised innovation squared comes
    from the Woodbury identity.  Steps whose NIS exceeds ``gate`` (if > 0)
    are rejected.  After ``reset_after`` (> 0) consecutive rejections every
    further rejection multiplies ``P`` by ``inflate``, so that a filter whose
    state has left the measurements (a lock-out) widens until it accepts
    them again instead of integrating on with a covariance that no longer
    describes its error.
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
    run = 0
    for k in range(n):
        if k > 0:
            for i in range(3):
                xk[i] += u[i, k - 1]
                for j in range(3):
                    Pk[i, j] += Q[i, j]
        _quadratic_innovation(wq, k, xk, nu, H)
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
            run += 1
            if reset_after > 0 and run >= reset_after and _below_cap(Pk, xk, wq, k):
                for i in range(3):
                    for j in range(3):
                        Pk[i, j] *= inflate
        else:
            run = 0
            for i in range(3):
                xk[i] += dx[i]
                for j in range(3):
                    Pk[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
        for i in range(3):
            x[i, k] = xk[i]
            for j in range(3):
                P[i, j, k] = Pk[i, j]
    return x, P, nis, rejected


@nb.njit(cache=True)
def quadratic_ekf_offsets(wq, u, dt, Q, R, x0, P0, gate, reset_after=0, inflate=4.0, skip=None):
    """EKF on the quadratic terms with the array's constant errors as states.

    State (12): ``w`` (3), the constant error of the angular acceleration
    ``c_a`` (3) and the constant errors of the six quadratic terms ``c_W``
    (6).  Process ``w_k = w_{k-1} + u_{k-1} - dt_k c_a + noise(Q)`` (the
    trapezoid increment of a constant error is exactly ``dt c_a``), the
    offsets constant; measurement ``W_meas = h(w) + c_W + noise(R)``.  The
    measurement Jacobian is ``[H_w, 0, I]``, which the update exploits.
    Returns the filtered state (12, T), the covariance of ``w`` (3, 3, T),
    the final full covariance (12, 12), the NIS (T,), the gate flags, and
    the innovations (6, T) with their inverse covariances (6, 6, T), NaN on
    skipped samples (for score tests of unmodelled errors).
    ``reset_after`` and ``inflate`` as in :func:`quadratic_ekf`; only the
    rate block is widened (its rows and columns scaled by ``sqrt(inflate)``,
    which keeps ``P`` positive definite), the constant errors keep theirs.
    Samples with ``skip[k]`` (optional bool array) are predicted only: their
    information is already in the prior (a rest segment's mean), and using
    it again would count it twice.  Their NIS is NaN.
    """
    n = wq.shape[1]
    x = np.empty((12, n))
    Pw = np.empty((3, 3, n))
    nis = np.empty(n)
    rejected = np.zeros(n, dtype=np.bool_)
    innov = np.full((6, n), np.nan)
    sinv = np.full((6, 6, n), np.nan)
    xk = x0.copy()
    Pk = P0.copy()
    Hw = np.zeros((6, 3))
    nu = np.empty(6)
    PHt = np.empty((12, 6))
    S = np.empty((6, 6))
    L = np.zeros((6, 6))
    Si = np.empty((6, 6))
    K = np.empty((12, 6))
    run = 0
    sq = np.sqrt(inflate)
    for k in range(n):
        if k > 0:
            h = dt[k]
            for i in range(3):
                xk[i] += u[i, k - 1] - h * xk[i + 3]
            # P <- F P F' with F = I except F[0:3, 3:6] = -h I.
            for i in range(3):
                for j in range(12):
                    Pk[i, j] -= h * Pk[i + 3, j]
            for i in range(12):
                for j in range(3):
                    Pk[i, j] -= h * Pk[i, j + 3]
            for i in range(3):
                for j in range(3):
                    Pk[i, j] += Q[i, j]
        if skip is not None and skip[k]:
            nis[k] = np.nan
            for i in range(xk.shape[0]):
                x[i, k] = xk[i]
            for i in range(3):
                for j in range(3):
                    Pw[i, j, k] = Pk[i, j]
            continue
        _quadratic_innovation(wq, k, xk, nu, Hw)
        for r in range(6):
            nu[r] -= xk[6 + r]
        # P H' = P[:, 0:3] Hw' + P[:, 6:12]
        for i in range(12):
            for r in range(6):
                s = Pk[i, 6 + r]
                for j in range(3):
                    s += Pk[i, j] * Hw[r, j]
                PHt[i, r] = s
        # S = H P H' + R = Hw PHt[0:3] + PHt[6:12] + R
        for r in range(6):
            for m in range(r, 6):
                s = PHt[6 + r, m] + R[r, m]
                for j in range(3):
                    s += Hw[r, j] * PHt[j, m]
                S[r, m] = s
                S[m, r] = s
        # S^-1 by Cholesky (S is SPD: R is).
        for r in range(6):
            for m in range(r + 1):
                s = S[r, m]
                for j in range(m):
                    s -= L[r, j] * L[m, j]
                if r == m:
                    L[r, r] = np.sqrt(s)
                else:
                    L[r, m] = s / L[m, m]
        for col in range(6):
            # Solve L L' y = e_col.
            for r in range(6):
                s = 1.0 if r == col else 0.0
                for j in range(r):
                    s -= L[r, j] * Si[j, col]
                Si[r, col] = s / L[r, r]
            for r in range(5, -1, -1):
                s = Si[r, col]
                for j in range(r + 1, 6):
                    s -= L[j, r] * Si[j, col]
                Si[r, col] = s / L[r, r]
        d2 = 0.0
        for r in range(6):
            s = 0.0
            for m in range(6):
                s += Si[r, m] * nu[m]
            d2 += nu[r] * s
        nis[k] = d2
        for r in range(6):
            innov[r, k] = nu[r]
            for m in range(6):
                sinv[r, m, k] = Si[r, m]
        if gate > 0 and d2 > gate:
            rejected[k] = True
            run += 1
            if reset_after > 0 and run >= reset_after and _below_cap(Pk, xk, wq, k):
                for i in range(3):
                    for j in range(12):
                        Pk[i, j] *= sq
                        Pk[j, i] *= sq
        else:
            run = 0
            for i in range(12):
                for r in range(6):
                    s = 0.0
                    for m in range(6):
                        s += PHt[i, m] * Si[m, r]
                    K[i, r] = s
            for i in range(12):
                s = 0.0
                for r in range(6):
                    s += K[i, r] * nu[r]
                xk[i] += s
            # P - K S K' = P - K (P H')'
            for i in range(12):
                for j in range(i, 12):
                    s = 0.0
                    for r in range(6):
                        s += K[i, r] * PHt[j, r]
                    v = 0.5 * ((Pk[i, j] - s) + (Pk[j, i] - s))
                    Pk[i, j] = v
                    Pk[j, i] = v
        for i in range(xk.shape[0]):
            x[i, k] = xk[i]
        for i in range(3):
            for j in range(3):
                Pw[i, j, k] = Pk[i, j]
    return x, Pw, Pk, nis, rejected, innov, sinv
