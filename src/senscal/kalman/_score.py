"""Compiled log-likelihood and its gradient (the score) in one Kalman pass.

The score comes from the sensitivity equations: every quantity of the
filter (predicted mean and covariance, innovation, its covariance, gain)
is differentiated along the recursion with respect to each parameter, given
the derivatives of the model matrices.  One pass then gives ``ln L`` and all
``p`` partial derivatives at about ``1 + p`` times the cost of the plain
likelihood, instead of ``1 + p`` (forward) or ``1 + 2p`` (central) passes of
finite differences, and without their truncation error.

Layout as in :mod:`senscal.kalman._kernels`: time-major, every model matrix
``(1|T, r, c)``; derivative stacks carry a leading parameter axis
``(p, 1|T, r, c)``.  No control input, no gating (the likelihood of
parameter estimation).  The model stacks are indexed in place (``F[f, i, j]``
with ``f = _ti(F, t)``), not sliced per step.

The filter step is written out here rather than shared with
:func:`senscal.kalman._kernels.filter_series`: shared step functions
either cost 13 s more compilation on a user's first run (numba
``inline="always"``) or, as plain calls, up to twice the time per pass of
a small model (measured for issue 30).

References
----------
R. K. Mehra, "Approaches to adaptive filtering", IEEE Trans. Autom. Control
17 (1972) 693-698 (score by the sensitivity equations); A. C. Harvey,
*Forecasting, Structural Time Series Models and the Kalman Filter* (1989),
sec. 3.4.6.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from senscal.kalman._kernels import _chol

_LOG_2PI = math.log(2.0 * math.pi)
# Relative change of the predicted covariance and of its derivatives below
# which the Riccati and sensitivity recursions are taken as converged: the
# frozen gain then changes the log-likelihood by far less than 1e-6 nat.
_SS_TOL = 1e-13
_SS_HOLD = 3


@nb.njit(cache=True)
def _ti(A, t):
    """Index of step ``t`` in a (1|T, ...) stack."""
    return 0 if A.shape[0] == 1 else t


@nb.njit(cache=True)
def _tril_inv_into(L, m, Li):
    """Li[:m, :m] = inverse of the lower-triangular L[:m, :m] (no allocation: called every step)."""
    for j in range(m):
        Li[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, m):
            acc = 0.0
            for c in range(j, i):
                acc -= L[i, c] * Li[c, j]
            Li[i, j] = acc / L[i, i]
        for i in range(j):
            Li[i, j] = 0.0


@nb.njit(cache=True, nogil=True)
def score_series(F, H, Q, R, x0, P0, y, dF, dH, dQ, dR, dP0, useF, useH, allow_ss, grad):
    """Log-likelihood and (with ``grad``) its gradient for one series (releases the GIL).

    Shapes: F, Q (1|T, n, n); H (1|T, m, n); R (1|T, m, m); x0 (n,); P0 (n,
    n); y (T, m) time-major with NaN = missing; dF, dQ (p, 1|T, n, n); dH
    (p, 1|T, m, n); dR (p, 1|T, m, m); dP0 (p, n, n); useF, useH (p,) bool:
    whether parameter k moves F, H at all (their stacks are skipped
    otherwise).  ``allow_ss``: the model is time-invariant and ``y`` has no
    NaN, so the gain and its derivatives may be frozen once converged.

    Returns (loglik, gradient (p,), expected information (p, p), first
    frozen step or -1); loglik is NaN when an innovation covariance was not
    positive definite.  The information is the sum over steps of
    ``tr(S^-1 dS_k S^-1 dS_l) / 2 + dv_k' S^-1 dv_l`` (Fisher scoring for
    state-space models: the expected Hessian of ``-ln L`` given the past).
    """
    n = F.shape[1]
    m = H.shape[1]
    p = dQ.shape[0]
    T = y.shape[0]
    g = np.zeros(p)
    info = np.zeros((p, p))
    tt = np.zeros((p, p))
    SdS = np.empty((p, m, m))
    u = np.empty((p, m))
    x = x0.copy()
    P = P0.copy()
    dx = np.zeros((p, n))
    dP = np.empty((p, n, n))
    for k in range(p):
        for i in range(n):
            for j in range(n):
                dP[k, i, j] = dP0[k, i, j]
    xp = np.empty(n)
    Pp = np.empty((n, n))
    Pp_prev = np.zeros((n, n))
    dxp = np.empty((p, n))
    dPp = np.empty((p, n, n))
    dPp_prev = np.zeros((p, n, n))
    FP = np.empty((n, n))
    A = np.empty((n, n))
    obs = np.empty(m, dtype=np.int64)
    idx = np.arange(m)
    v = np.empty(m)
    dv = np.empty((p, m))
    L = np.zeros((m, m))
    Sinv = np.empty((m, m))
    Li = np.zeros((m, m))
    M = np.empty((n, m))
    Kg = np.empty((n, m))
    S = np.empty((m, m))
    w = np.empty(m)
    dM = np.empty((p, n, m))
    dS = np.empty((p, m, m))
    dK = np.empty((p, n, m))
    trc = np.zeros(p)
    IKH = np.empty((n, n))
    tmp = np.empty((n, n))
    ll = 0.0
    logdet = 0.0
    frozen = False
    hold = 0
    ss_from = -1
    for t in range(T):
        f = _ti(F, t)
        fd = _ti(dF[0], t) if p > 0 else 0
        # ---- predict
        if t == 0:
            for i in range(n):
                xp[i] = x0[i]
                for j in range(n):
                    Pp[i, j] = P0[i, j]
            for k in range(p):
                for i in range(n):
                    dxp[k, i] = 0.0
                    for j in range(n):
                        dPp[k, i, j] = dP0[k, i, j]
        else:
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += F[f, i, j] * x[j]
                xp[i] = acc
            if grad:
                for k in range(p):
                    for i in range(n):
                        acc = 0.0
                        for j in range(n):
                            acc += F[f, i, j] * dx[k, j]
                        if useF[k]:
                            for j in range(n):
                                acc += dF[k, fd, i, j] * x[j]
                        dxp[k, i] = acc
            if not frozen:
                q = _ti(Q, t)
                for i in range(n):
                    for j in range(n):
                        acc = 0.0
                        for l in range(n):
                            acc += F[f, i, l] * P[l, j]
                        FP[i, j] = acc
                for i in range(n):
                    for j in range(i + 1):
                        acc = Q[q, i, j]
                        for l in range(n):
                            acc += FP[i, l] * F[f, j, l]
                        Pp[i, j] = acc
                        Pp[j, i] = acc
                if grad:
                    qd = _ti(dQ[0], t)
                    for k in range(p):
                        for i in range(n):
                            for j in range(n):
                                acc = 0.0
                                for l in range(n):
                                    acc += F[f, i, l] * dP[k, l, j]
                                A[i, j] = acc
                        for i in range(n):
                            for j in range(i + 1):
                                acc = dQ[k, qd, i, j]
                                for l in range(n):
                                    acc += A[i, l] * F[f, j, l]
                                dPp[k, i, j] = acc
                                dPp[k, j, i] = acc
                        if useF[k]:
                            for i in range(n):
                                for j in range(n):
                                    acc = 0.0
                                    for l in range(n):
                                        acc += dF[k, fd, i, l] * FP[j, l]
                                    A[i, j] = acc
                            for i in range(n):
                                for j in range(n):
                                    dPp[k, i, j] += A[i, j] + A[j, i]
        # ---- innovation
        h = _ti(H, t)
        hd = _ti(dH[0], t) if p > 0 else 0
        mo = 0
        for a in range(m):
            acc = y[t, a]
            for j in range(n):
                acc -= H[h, a, j] * xp[j]
            v[a] = acc
            if not math.isnan(acc):
                obs[mo] = a
                mo += 1
        if grad:
            for k in range(p):
                for a in range(mo):
                    r = obs[a]
                    acc = 0.0
                    for j in range(n):
                        acc -= H[h, r, j] * dxp[k, j]
                    if useH[k]:
                        for j in range(n):
                            acc -= dH[k, hd, r, j] * xp[j]
                    dv[k, a] = acc
        if mo == 0:
            for i in range(n):
                x[i] = xp[i]
                for j in range(n):
                    P[i, j] = Pp[i, j]
            for k in range(p):
                for i in range(n):
                    dx[k, i] = dxp[k, i]
                    for j in range(n):
                        dP[k, i, j] = dPp[k, i, j]
            continue
        if not frozen:
            rr = _ti(R, t)
            for i in range(n):
                for a in range(mo):
                    acc = 0.0
                    for j in range(n):
                        acc += Pp[i, j] * H[h, obs[a], j]
                    M[i, a] = acc
            for a in range(mo):
                for b in range(a + 1):
                    acc = R[rr, obs[a], obs[b]]
                    for j in range(n):
                        acc += H[h, obs[a], j] * M[j, b]
                    S[a, b] = acc
                    S[b, a] = acc
            if not _chol(S, idx, mo, L):
                return np.nan, g, info, -2
            logdet = 0.0
            for a in range(mo):
                logdet += 2.0 * math.log(L[a, a])
            _tril_inv_into(L, mo, Li)
            for a in range(mo):
                for b in range(mo):
                    acc = 0.0
                    for c in range(max(a, b), mo):
                        acc += Li[c, a] * Li[c, b]
                    Sinv[a, b] = acc
            for i in range(n):
                for a in range(mo):
                    acc = 0.0
                    for b in range(mo):
                        acc += M[i, b] * Sinv[b, a]
                    Kg[i, a] = acc
            if grad:
                rd = _ti(dR[0], t)
                for k in range(p):
                    for i in range(n):
                        for a in range(mo):
                            acc = 0.0
                            for j in range(n):
                                acc += dPp[k, i, j] * H[h, obs[a], j]
                            if useH[k]:
                                for j in range(n):
                                    acc += Pp[i, j] * dH[k, hd, obs[a], j]
                            dM[k, i, a] = acc
                    for a in range(mo):
                        for b in range(mo):
                            acc = dR[k, rd, obs[a], obs[b]]
                            for j in range(n):
                                acc += H[h, obs[a], j] * dM[k, j, b]
                            if useH[k]:
                                for j in range(n):
                                    acc += dH[k, hd, obs[a], j] * M[j, b]
                            dS[k, a, b] = acc
                    tr = 0.0
                    for a in range(mo):
                        for b in range(mo):
                            tr += Sinv[a, b] * dS[k, b, a]
                    trc[k] = tr
                    for i in range(n):
                        for a in range(mo):
                            acc = dM[k, i, a]
                            for b in range(mo):
                                acc -= Kg[i, b] * dS[k, b, a]
                            w[a] = acc
                        for a in range(mo):
                            acc = 0.0
                            for b in range(mo):
                                acc += w[b] * Sinv[b, a]
                            dK[k, i, a] = acc
        # ---- likelihood and its gradient
        nis = 0.0
        for a in range(mo):
            acc = 0.0
            for b in range(mo):
                acc += Sinv[a, b] * v[obs[b]]
            w[a] = acc
            nis += v[obs[a]] * acc
        ll += -0.5 * (mo * _LOG_2PI + logdet + nis)
        if grad:
            for k in range(p):
                q1 = 0.0
                q2 = 0.0
                for a in range(mo):
                    q1 += w[a] * dv[k, a]
                    acc = 0.0
                    for b in range(mo):
                        acc += dS[k, a, b] * w[b]
                    q2 += w[a] * acc
                g[k] += -0.5 * (trc[k] + 2.0 * q1 - q2)
            if not frozen:
                for k in range(p):
                    for a in range(mo):
                        for b in range(mo):
                            acc = 0.0
                            for c in range(mo):
                                acc += Sinv[a, c] * dS[k, c, b]
                            SdS[k, a, b] = acc
                for k in range(p):
                    for l in range(k + 1):
                        acc = 0.0
                        for a in range(mo):
                            for b in range(mo):
                                acc += SdS[k, a, b] * SdS[l, b, a]
                        tt[k, l] = 0.5 * acc
                        tt[l, k] = 0.5 * acc
            for k in range(p):
                for a in range(mo):
                    acc = 0.0
                    for b in range(mo):
                        acc += Sinv[a, b] * dv[k, b]
                    u[k, a] = acc
            for k in range(p):
                for l in range(k + 1):
                    acc = tt[k, l]
                    for a in range(mo):
                        acc += dv[l, a] * u[k, a]
                    info[k, l] += acc
                    if l != k:
                        info[l, k] += acc
        # ---- update: means
        for i in range(n):
            acc = xp[i]
            for a in range(mo):
                acc += Kg[i, a] * v[obs[a]]
            x[i] = acc
        if grad:
            for k in range(p):
                for i in range(n):
                    acc = dxp[k, i]
                    for a in range(mo):
                        acc += dK[k, i, a] * v[obs[a]] + Kg[i, a] * dv[k, a]
                    dx[k, i] = acc
        if frozen:
            continue
        rr = _ti(R, t)
        for i in range(n):
            for j in range(n):
                acc = 1.0 if i == j else 0.0
                for a in range(mo):
                    acc -= Kg[i, a] * H[h, obs[a], j]
                IKH[i, j] = acc
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for l in range(n):
                    acc += IKH[i, l] * Pp[l, j]
                tmp[i, j] = acc
        for i in range(n):
            for j in range(i + 1):
                acc = 0.0
                for l in range(n):
                    acc += tmp[i, l] * IKH[j, l]
                for a in range(mo):
                    for b in range(mo):
                        acc += Kg[i, a] * R[rr, obs[a], obs[b]] * Kg[j, b]
                P[i, j] = acc
                P[j, i] = acc
        if grad:
            for k in range(p):
                for i in range(n):
                    for j in range(i + 1):
                        acc = dPp[k, i, j]
                        for a in range(mo):
                            acc -= dK[k, i, a] * M[j, a] + Kg[i, a] * dM[k, j, a]
                        acc2 = dPp[k, j, i]
                        for a in range(mo):
                            acc2 -= dK[k, j, a] * M[i, a] + Kg[j, a] * dM[k, i, a]
                        val = 0.5 * (acc + acc2)
                        dP[k, i, j] = val
                        dP[k, j, i] = val
        if allow_ss and t > 0 and mo == m:
            scale = 0.0
            diff = 0.0
            for i in range(n):
                for j in range(n):
                    scale = max(scale, abs(Pp[i, j]))
                    diff = max(diff, abs(Pp[i, j] - Pp_prev[i, j]))
                    Pp_prev[i, j] = Pp[i, j]
            ok = diff <= _SS_TOL * scale
            if grad and ok:
                for k in range(p):
                    sk = 0.0
                    dk = 0.0
                    for i in range(n):
                        for j in range(n):
                            sk = max(sk, abs(dPp[k, i, j]))
                            dk = max(dk, abs(dPp[k, i, j] - dPp_prev[k, i, j]))
                            dPp_prev[k, i, j] = dPp[k, i, j]
                    if dk > _SS_TOL * max(sk, 1e-300) and sk > 0.0:
                        ok = False
            elif grad:
                for k in range(p):
                    for i in range(n):
                        for j in range(n):
                            dPp_prev[k, i, j] = dPp[k, i, j]
            hold = hold + 1 if ok else 0
            if hold >= _SS_HOLD:
                frozen = True
                ss_from = t + 1
    return ll, g, info, ss_from


@nb.njit(cache=True, nogil=True)
def score_series_scalar(F, H, Q, R, x0, P0, y, dF, dH, dQ, dR, dP0, useF, useH, allow_ss, grad):
    """:func:`score_series` for one measurement per step (m = 1), the same numbers.

    A channel fitted on its own (a known quantity's channels, one sensor
    with a covariate) has a scalar innovation: its covariance needs no
    factorisation, and the loops over measurement components and the
    bookkeeping of missing components go.  Every floating-point operation of
    the general kernel is kept, in its order (including its additions to a
    zero accumulator), so the likelihood, score and information are
    bit-for-bit those of :func:`score_series`; only the work around them is
    saved (measured: about half the time per pass of a two-state model).
    Same arguments and returns.
    """
    n = F.shape[1]
    p = dQ.shape[0]
    T = y.shape[0]
    g = np.zeros(p)
    info = np.zeros((p, p))
    tt = np.zeros((p, p))
    SdS = np.empty(p)
    u = np.empty(p)
    x = x0.copy()
    P = P0.copy()
    dx = np.zeros((p, n))
    dP = np.empty((p, n, n))
    for k in range(p):
        for i in range(n):
            for j in range(n):
                dP[k, i, j] = dP0[k, i, j]
    xp = np.empty(n)
    Pp = np.empty((n, n))
    Pp_prev = np.zeros((n, n))
    dxp = np.empty((p, n))
    dPp = np.empty((p, n, n))
    dPp_prev = np.zeros((p, n, n))
    FP = np.empty((n, n))
    A = np.empty((n, n))
    dv = np.empty(p)
    M = np.empty(n)
    Kg = np.empty(n)
    dM = np.empty((p, n))
    dS = np.empty(p)
    dK = np.empty((p, n))
    trc = np.zeros(p)
    IKH = np.empty((n, n))
    tmp = np.empty((n, n))
    Sinv = 0.0
    ll = 0.0
    logdet = 0.0
    frozen = False
    hold = 0
    ss_from = -1
    for t in range(T):
        f = 0 if F.shape[0] == 1 else t
        fd = (0 if dF.shape[1] == 1 else t) if p > 0 else 0
        # ---- predict (as score_series)
        if t == 0:
            for i in range(n):
                xp[i] = x0[i]
                for j in range(n):
                    Pp[i, j] = P0[i, j]
            for k in range(p):
                for i in range(n):
                    dxp[k, i] = 0.0
                    for j in range(n):
                        dPp[k, i, j] = dP0[k, i, j]
        else:
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += F[f, i, j] * x[j]
                xp[i] = acc
            if grad:
                for k in range(p):
                    for i in range(n):
                        acc = 0.0
                        for j in range(n):
                            acc += F[f, i, j] * dx[k, j]
                        if useF[k]:
                            for j in range(n):
                                acc += dF[k, fd, i, j] * x[j]
                        dxp[k, i] = acc
            if not frozen:
                q = 0 if Q.shape[0] == 1 else t
                for i in range(n):
                    for j in range(n):
                        acc = 0.0
                        for l in range(n):
                            acc += F[f, i, l] * P[l, j]
                        FP[i, j] = acc
                for i in range(n):
                    for j in range(i + 1):
                        acc = Q[q, i, j]
                        for l in range(n):
                            acc += FP[i, l] * F[f, j, l]
                        Pp[i, j] = acc
                        Pp[j, i] = acc
                if grad:
                    qd = 0 if dQ.shape[1] == 1 else t
                    for k in range(p):
                        for i in range(n):
                            for j in range(n):
                                acc = 0.0
                                for l in range(n):
                                    acc += F[f, i, l] * dP[k, l, j]
                                A[i, j] = acc
                        for i in range(n):
                            for j in range(i + 1):
                                acc = dQ[k, qd, i, j]
                                for l in range(n):
                                    acc += A[i, l] * F[f, j, l]
                                dPp[k, i, j] = acc
                                dPp[k, j, i] = acc
                        if useF[k]:
                            for i in range(n):
                                for j in range(n):
                                    acc = 0.0
                                    for l in range(n):
                                        acc += dF[k, fd, i, l] * FP[j, l]
                                    A[i, j] = acc
                            for i in range(n):
                                for j in range(n):
                                    dPp[k, i, j] += A[i, j] + A[j, i]
        # ---- innovation
        h = 0 if H.shape[0] == 1 else t
        hd = (0 if dH.shape[1] == 1 else t) if p > 0 else 0
        v = y[t, 0]
        for j in range(n):
            v -= H[h, 0, j] * xp[j]
        if math.isnan(v):
            for i in range(n):
                x[i] = xp[i]
                for j in range(n):
                    P[i, j] = Pp[i, j]
            for k in range(p):
                for i in range(n):
                    dx[k, i] = dxp[k, i]
                    for j in range(n):
                        dP[k, i, j] = dPp[k, i, j]
            continue
        if grad:
            for k in range(p):
                acc = 0.0
                for j in range(n):
                    acc -= H[h, 0, j] * dxp[k, j]
                if useH[k]:
                    for j in range(n):
                        acc -= dH[k, hd, 0, j] * xp[j]
                dv[k] = acc
        if not frozen:
            rr = 0 if R.shape[0] == 1 else t
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += Pp[i, j] * H[h, 0, j]
                M[i] = acc
            S = R[rr, 0, 0]
            for j in range(n):
                S += H[h, 0, j] * M[j]
            if not S > 0.0:
                return np.nan, g, info, -2
            L = math.sqrt(S)
            logdet = 0.0
            logdet += 2.0 * math.log(L)
            Li = 1.0 / L
            Sinv = 0.0
            Sinv += Li * Li
            for i in range(n):
                acc = 0.0
                acc += M[i] * Sinv
                Kg[i] = acc
            if grad:
                rd = 0 if dR.shape[1] == 1 else t
                for k in range(p):
                    for i in range(n):
                        acc = 0.0
                        for j in range(n):
                            acc += dPp[k, i, j] * H[h, 0, j]
                        if useH[k]:
                            for j in range(n):
                                acc += Pp[i, j] * dH[k, hd, 0, j]
                        dM[k, i] = acc
                    acc = dR[k, rd, 0, 0]
                    for j in range(n):
                        acc += H[h, 0, j] * dM[k, j]
                    if useH[k]:
                        for j in range(n):
                            acc += dH[k, hd, 0, j] * M[j]
                    dS[k] = acc
                    tr = 0.0
                    tr += Sinv * dS[k]
                    trc[k] = tr
                    for i in range(n):
                        w0 = dM[k, i]
                        w0 -= Kg[i] * dS[k]
                        acc = 0.0
                        acc += w0 * Sinv
                        dK[k, i] = acc
        # ---- likelihood and its gradient
        w = 0.0
        w += Sinv * v
        nis = 0.0
        nis += v * w
        ll += -0.5 * (1 * _LOG_2PI + logdet + nis)
        if grad:
            for k in range(p):
                q1 = 0.0
                q2 = 0.0
                q1 += w * dv[k]
                acc = 0.0
                acc += dS[k] * w
                q2 += w * acc
                g[k] += -0.5 * (trc[k] + 2.0 * q1 - q2)
            if not frozen:
                for k in range(p):
                    acc = 0.0
                    acc += Sinv * dS[k]
                    SdS[k] = acc
                for k in range(p):
                    for l in range(k + 1):
                        acc = 0.0
                        acc += SdS[k] * SdS[l]
                        tt[k, l] = 0.5 * acc
                        tt[l, k] = 0.5 * acc
            for k in range(p):
                acc = 0.0
                acc += Sinv * dv[k]
                u[k] = acc
            for k in range(p):
                for l in range(k + 1):
                    acc = tt[k, l]
                    acc += dv[l] * u[k]
                    info[k, l] += acc
                    if l != k:
                        info[l, k] += acc
        # ---- update: means
        for i in range(n):
            x[i] = xp[i] + Kg[i] * v
        if grad:
            for k in range(p):
                for i in range(n):
                    dx[k, i] = dxp[k, i] + (dK[k, i] * v + Kg[i] * dv[k])
        if frozen:
            continue
        rr = 0 if R.shape[0] == 1 else t
        for i in range(n):
            for j in range(n):
                acc = 1.0 if i == j else 0.0
                acc -= Kg[i] * H[h, 0, j]
                IKH[i, j] = acc
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for l in range(n):
                    acc += IKH[i, l] * Pp[l, j]
                tmp[i, j] = acc
        for i in range(n):
            for j in range(i + 1):
                acc = 0.0
                for l in range(n):
                    acc += tmp[i, l] * IKH[j, l]
                acc += Kg[i] * R[rr, 0, 0] * Kg[j]
                P[i, j] = acc
                P[j, i] = acc
        if grad:
            for k in range(p):
                for i in range(n):
                    for j in range(i + 1):
                        acc = dPp[k, i, j] - (dK[k, i] * M[j] + Kg[i] * dM[k, j])
                        acc2 = dPp[k, j, i] - (dK[k, j] * M[i] + Kg[j] * dM[k, i])
                        val = 0.5 * (acc + acc2)
                        dP[k, i, j] = val
                        dP[k, j, i] = val
        if allow_ss and t > 0:
            scale = 0.0
            diff = 0.0
            for i in range(n):
                for j in range(n):
                    scale = max(scale, abs(Pp[i, j]))
                    diff = max(diff, abs(Pp[i, j] - Pp_prev[i, j]))
                    Pp_prev[i, j] = Pp[i, j]
            ok = diff <= _SS_TOL * scale
            if grad and ok:
                for k in range(p):
                    sk = 0.0
                    dk = 0.0
                    for i in range(n):
                        for j in range(n):
                            sk = max(sk, abs(dPp[k, i, j]))
                            dk = max(dk, abs(dPp[k, i, j] - dPp_prev[k, i, j]))
                            dPp_prev[k, i, j] = dPp[k, i, j]
                    if dk > _SS_TOL * max(sk, 1e-300) and sk > 0.0:
                        ok = False
            elif grad:
                for k in range(p):
                    for i in range(n):
                        for j in range(n):
                            dPp_prev[k, i, j] = dPp[k, i, j]
            hold = hold + 1 if ok else 0
            if hold >= _SS_HOLD:
                frozen = True
                ss_from = t + 1
    return ll, g, info, ss_from
