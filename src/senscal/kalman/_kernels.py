"""Compiled Kalman recursions (one series per call; batching loops outside).

Every matrix argument is three-dimensional with a leading "time" axis of
length 1 (time-invariant) or T (given per step); ``_at(A, t)`` picks the
right slice, so one kernel serves both cases without copies.

Internal layout is time-major (``x[t, i]``, ``P[t, i, j]``) so that a step
touches contiguous memory; the public API transposes to time-last views.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

_LOG_2PI = math.log(2.0 * math.pi)
# Relative change of the predicted covariance below which the Riccati
# recursion is taken as converged (a few ulps: the frozen gain then differs
# from the exact one by far less than the 1e-9 agreement we promise).
_SS_TOL = 1e-14
_SS_HOLD = 3


@nb.njit(cache=True)
def _at(A, t):
    return A[0] if A.shape[0] == 1 else A[t]


@nb.njit(cache=True)
def _sym(P):
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            a = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = a
            P[j, i] = a


# Whole-array assignments (``a[t] = b``, ``a[:, :] = b``) are written as the
# loops below: numba compiles its broadcasting setitem with shape-mismatch
# messages built from strings, which alone cost ~15 s of compilation on a
# user's first run; these loops compile in a fraction of a second.
@nb.njit(cache=True)
def _copy1(dst, src):
    """dst[:] = src for vectors."""
    for i in range(src.shape[0]):
        dst[i] = src[i]


@nb.njit(cache=True)
def _copy2(dst, src):
    """dst[:, :] = src for matrices."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@nb.njit(cache=True)
def _mm(A, B, out):
    """out = A @ B for small square matrices (no allocation)."""
    n = out.shape[0]
    k = A.shape[1]
    p = out.shape[1]
    for i in range(n):
        for j in range(p):
            acc = 0.0
            for l in range(k):
                acc += A[i, l] * B[l, j]
            out[i, j] = acc


@nb.njit(cache=True)
def _abt_sym(A, B, k, out, accumulate):
    """out = [out +] A[:, :k] B[:, :k]^T from its lower triangle, mirrored (exactly symmetric)."""
    n = out.shape[0]
    for i in range(n):
        for j in range(i + 1):
            acc = out[i, j] if accumulate else 0.0
            for l in range(k):
                acc += A[i, l] * B[j, l]
            out[i, j] = acc
            out[j, i] = acc


@nb.njit(cache=True)
def _chol(A, idx, k, L):
    """Cholesky factor of A[idx[:k]][:, idx[:k]] into L[:k, :k]; False if not PD."""
    for a in range(k):
        for b in range(a + 1):
            acc = A[idx[a], idx[b]]
            for c in range(b):
                acc -= L[a, c] * L[b, c]
            if a == b:
                if not acc > 0.0:
                    return False
                L[a, a] = math.sqrt(acc)
            else:
                L[a, b] = acc / L[b, b]
    return True


@nb.njit(cache=True)
def _chol_solve(L, k, rhs, out):
    """Solve L L^T out = rhs (vectors of length k) by two substitutions."""
    for a in range(k):
        acc = rhs[a]
        for b in range(a):
            acc -= L[a, b] * out[b]
        out[a] = acc / L[a, a]
    for a in range(k - 1, -1, -1):
        acc = out[a]
        for b in range(a + 1, k):
            acc -= L[b, a] * out[b]
        out[a] = acc / L[a, a]


@nb.njit(cache=True)
def filter_series(F, B, H, Q, R, x0, P0, y, u, gate, allow_ss, store,
                  xf, Pf, xp_out, Pp_out, v_out, S_out, e_out, rej):
    """Kalman filter of one series; fills the output arrays in place.

    Shapes: F (1|T, n, n), B (1|T, n, k), H (1|T, m, n), Q (1|T, n, n),
    R (1|T, m, m), x0 (n,), P0 (n, n), y (T, m) with NaN = missing,
    u (T, k) (time-major, contiguous rows).  Outputs time-major: xf, xp_out
    (T, n); Pf, Pp_out (T, n, n); v_out, e_out (T, m); S_out (T, m, m);
    rej (T,) bool.  With ``store`` False nothing but ``rej`` is written (the
    likelihood-only pass of parameter estimation).

    Small fixed-size loops on preallocated buffers: at n, m <= 10 they beat
    BLAS calls, whose per-call overhead and allocations would dominate.

    Returns (loglik, index at which the steady-state gain was frozen, -1 if
    never, or -2 if an innovation covariance was not positive definite).
    """
    n = F.shape[1]
    m = H.shape[1]
    k = B.shape[2]
    T = y.shape[0]
    x = x0.copy()
    P = P0.copy()
    xp = np.empty(n)
    Pp = np.empty((n, n))
    Pp_prev = np.zeros((n, n))
    tmp = np.empty((n, n))
    IKH = np.empty((n, n))
    PHt = np.empty((n, m))
    Kg = np.empty((n, m))
    KR = np.empty((n, m))
    S = np.empty((m, m))
    L = np.zeros((m, m))
    v = np.empty(m)
    es = np.empty(m)
    obs = np.empty(m, dtype=np.int64)
    rhs = np.empty(m)
    loglik = 0.0
    hold = 0
    for t in range(T):
        # ---- predict
        if t == 0:
            _copy1(xp, x0)
            _copy2(Pp, P0)
        else:
            Ft = _at(F, t)
            Bt = _at(B, t)
            Qt = _at(Q, t)
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += Ft[i, j] * x[j]
                for j in range(k):
                    acc += Bt[i, j] * u[t - 1, j]
                xp[i] = acc
            _mm(Ft, P, tmp)
            _copy2(Pp, Qt)
            _abt_sym(tmp, Ft, n, Pp, True)
        # ---- innovation
        Ht = _at(H, t)
        Rt = _at(R, t)
        for i in range(n):
            for a in range(m):
                acc = 0.0
                for j in range(n):
                    acc += Pp[i, j] * Ht[a, j]
                PHt[i, a] = acc
        for a in range(m):
            for b in range(a + 1):
                acc = Rt[a, b]
                for i in range(n):
                    acc += Ht[a, i] * PHt[i, b]
                S[a, b] = acc
                S[b, a] = acc
        mo = 0
        for a in range(m):
            acc = y[t, a]
            for j in range(n):
                acc -= Ht[a, j] * xp[j]
            v[a] = acc
            if not math.isnan(acc):
                obs[mo] = a
                mo += 1
        if store:
            _copy1(xp_out[t], xp)
            _copy2(Pp_out[t], Pp)
            _copy1(v_out[t], v)
            _copy2(S_out[t], S)
            for a in range(m):
                e_out[t, a] = np.nan
        if mo == 0:
            _copy1(x, xp)
            _copy2(P, Pp)
            if store:
                _copy1(xf[t], x)
                _copy2(Pf[t], P)
            continue
        # ---- Cholesky of the observed block, whitened innovation
        if not _chol(S, obs, mo, L):
            return np.nan, -2
        nis = 0.0
        logdet = 0.0
        for a in range(mo):
            acc = v[obs[a]]
            for b in range(a):
                acc -= L[a, b] * es[b]
            es[a] = acc / L[a, a]
            nis += es[a] * es[a]
            logdet += 2.0 * math.log(L[a, a])
            if store:
                e_out[t, obs[a]] = es[a]
        if gate > 0.0 and nis > gate:
            rej[t] = True
            _copy1(x, xp)
            _copy2(P, Pp)
            if store:
                _copy1(xf[t], x)
                _copy2(Pf[t], P)
            continue
        loglik += -0.5 * (mo * _LOG_2PI + logdet + nis)
        # ---- gain K = Pp Hs^T Ss^-1, row by row through the Cholesky factor
        for i in range(n):
            for a in range(mo):
                rhs[a] = PHt[i, obs[a]]
            _chol_solve(L, mo, rhs, Kg[i])
        for i in range(n):
            acc = xp[i]
            for a in range(mo):
                acc += Kg[i, a] * v[obs[a]]
            x[i] = acc
        # ---- Joseph form: P = (I - K H) Pp (I - K H)^T + K R K^T
        for i in range(n):
            for j in range(n):
                acc = 1.0 if i == j else 0.0
                for a in range(mo):
                    acc -= Kg[i, a] * Ht[obs[a], j]
                IKH[i, j] = acc
            for a in range(mo):
                acc = 0.0
                for b in range(mo):
                    acc += Kg[i, b] * Rt[obs[b], obs[a]]
                KR[i, a] = acc
        _mm(IKH, Pp, tmp)
        _abt_sym(tmp, IKH, n, P, False)
        _abt_sym(KR, Kg, mo, P, True)
        if store:
            _copy1(xf[t], x)
            _copy2(Pf[t], P)
        if allow_ss and t > 0:
            # Converged when the predicted covariance stops changing.
            scale = 0.0
            diff = 0.0
            for i in range(n):
                for j in range(n):
                    scale = max(scale, abs(Pp[i, j]))
                    diff = max(diff, abs(Pp[i, j] - Pp_prev[i, j]))
            hold = hold + 1 if diff <= _SS_TOL * scale else 0
            if hold >= _SS_HOLD and t + 1 < T:
                loglik += _steady(F[0], B[0], H[0], Kg, L, P, x, y, u, t + 1, store, xf, Pf, xp_out,
                                  Pp_out, v_out, S_out, e_out, logdet, Pp, S)
                return loglik, t + 1
        _copy2(Pp_prev, Pp)
    return loglik, -1


@nb.njit(cache=True)
def _tril_inv(L, m):
    """Inverse of the lower-triangular L[:m, :m] by forward substitution.

    np.linalg.inv (a general LU through LAPACK) costs ~8 s of compilation on
    a first run, and the triangle is all the whitening uses.
    """
    Li = np.zeros((m, m))
    for j in range(m):
        Li[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, m):
            acc = 0.0
            for c in range(j, i):
                acc -= L[i, c] * Li[c, j]
            Li[i, j] = acc / L[i, i]
    return Li


@nb.njit(cache=True)
def _steady(F, B, H, K, L, P, x, y, u, t0, store, xf, Pf, xp_out, Pp_out, v_out, S_out, e_out,
            logdet, Pp, S):
    """Mean-only recursion with the frozen gain from step ``t0`` on.

    Only for time-invariant models without missing data or gating: the
    covariances are the converged ones, copied into the outputs.
    """
    n = F.shape[0]
    m = H.shape[0]
    k = B.shape[1]
    T = y.shape[0]
    Linv = _tril_inv(L, m)
    const = -0.5 * (m * _LOG_2PI + logdet)
    ll = 0.0
    xp = np.empty(n)
    v = np.empty(m)
    e = np.empty(m)
    for t in range(t0, T):
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += F[i, j] * x[j]
            for j in range(k):
                acc += B[i, j] * u[t - 1, j]
            xp[i] = acc
        for a in range(m):
            acc = y[t, a]
            for j in range(n):
                acc -= H[a, j] * xp[j]
            v[a] = acc
        nis = 0.0
        for a in range(m):
            acc = 0.0
            for b in range(a + 1):
                acc += Linv[a, b] * v[b]
            e[a] = acc
            nis += acc * acc
        for i in range(n):
            acc = xp[i]
            for a in range(m):
                acc += K[i, a] * v[a]
            x[i] = acc
        ll += const - 0.5 * nis
        if not store:
            continue
        _copy1(xp_out[t], xp)
        _copy1(xf[t], x)
        _copy1(v_out[t], v)
        _copy1(e_out[t], e)
        _copy2(Pf[t], P)
        _copy2(Pp_out[t], Pp)
        _copy2(S_out[t], S)
    return ll


def smoother_gains(F, Pf, Pp):
    """RTS gains C_t = P_t F_{t+1}^T Pp_{t+1}^{-1}, t = 0..T-2 (time-major).

    Pp is symmetric positive definite: C^T = Pp^{-1} (F P) by a Cholesky
    solve on preallocated buffers.  Otherwise (rounding broke definiteness,
    or a state is known exactly, e.g. held at a given value with zero prior
    and process variance) the pseudo-inverse: such a state's gain is zero.
    That rare step runs in NumPy here: inside the compiled loop,
    np.linalg.pinv would compile numba's SVD wrappers (seconds) on every
    first run whether it is needed or not.
    """
    C, bad = _smoother_gains(F, Pf, Pp)
    for t in np.flatnonzero(bad):
        Ft1 = F[0] if F.shape[0] == 1 else F[t + 1]
        C[t] = (np.linalg.pinv(Pp[t + 1]) @ (Ft1 @ Pf[t])).T
    return C


@nb.njit(cache=True)
def _smoother_gains(F, Pf, Pp):
    """The Cholesky gains; ``bad[t]`` where Pp_{t+1} was not positive definite (C[t] left zero)."""
    T, n, _ = Pf.shape
    C = np.zeros((T, n, n))
    bad = np.zeros(T, dtype=np.bool_)
    L = np.zeros((n, n))
    FP = np.empty((n, n))
    idx = np.arange(n)
    rhs = np.empty(n)
    col = np.empty(n)
    for t in range(T - 1):
        Ft1 = _at(F, t + 1)
        A = Pp[t + 1]
        Pt = Pf[t]
        _mm(Ft1, Pt, FP)
        if not _chol(A, idx, n, L):
            bad[t] = True
            continue
        for c in range(n):
            for i in range(n):
                rhs[i] = FP[i, c]
            _chol_solve(L, n, rhs, col)
            for i in range(n):
                C[t, c, i] = col[i]
    return C, bad


@nb.njit(cache=True)
def _rts_step(Ct, xf_t, Pf_t, xp_n, Pp_n, x, P, D, CD):
    """One backward step in place: x <- xf + C (x - xp), P <- Pf + C (P - Pp) C^T."""
    n = x.shape[0]
    for i in range(n):
        D[i, 0] = x[i] - xp_n[i]
    for i in range(n):
        acc = xf_t[i]
        for j in range(n):
            acc += Ct[i, j] * D[j, 0]
        x[i] = acc
    for i in range(n):
        for j in range(n):
            D[i, j] = P[i, j] - Pp_n[i, j]
    _mm(Ct, D, CD)
    _copy2(P, Pf_t)
    _abt_sym(CD, Ct, n, P, True)


@nb.njit(cache=True)
def rts_series(C, xf, Pf, xp, Pp, xs, Ps):
    """Rauch-Tung-Striebel backward pass (time-major, in place)."""
    T, n = xf.shape
    x = xf[T - 1].copy()
    P = Pf[T - 1].copy()
    D = np.empty((n, n))
    CD = np.empty((n, n))
    _copy1(xs[T - 1], x)
    _copy2(Ps[T - 1], P)
    for t in range(T - 2, -1, -1):
        _rts_step(C[t], xf[t], Pf[t], xp[t + 1], Pp[t + 1], x, P, D, CD)
        _copy1(xs[t], x)
        _copy2(Ps[t], P)


@nb.njit(cache=True)
def fixed_lag_series(C, xf, Pf, xp, Pp, lag, xs, Ps):
    """Fixed-lag smoother: the estimate at t uses data up to min(t+lag, T-1).

    A backward RTS pass of ``lag`` steps from each ``t + lag``; the gains do
    not depend on the end point, so each window reuses them.
    """
    T, n = xf.shape
    x = np.empty(n)
    P = np.empty((n, n))
    D = np.empty((n, n))
    CD = np.empty((n, n))
    for t in range(T):
        end = min(t + lag, T - 1)
        _copy1(x, xf[end])
        _copy2(P, Pf[end])
        for s in range(end - 1, t - 1, -1):
            _rts_step(C[s], xf[s], Pf[s], xp[s + 1], Pp[s + 1], x, P, D, CD)
        _copy1(xs[t], x)
        _copy2(Ps[t], P)


@nb.njit(cache=True)
def observability_gramian(F, H, pick):
    """W = sum over ``pick`` of (H_t Phi_t)^T (H_t Phi_t), Phi_t = F_t ... F_1 (transition from the first sample).

    F (1|T, n, n), H (1|T, m, n), pick increasing sample indices.  Stops
    before the first Phi_t whose largest entry is not finite or above
    1e150 (an unstable transition: the later samples would only add
    overflow).  The per-step products of a time-varying F in compiled code:
    a ramp over 65,000 irregular steps took a second in a Python loop.
    """
    n = F.shape[1]
    m = H.shape[1]
    W = np.zeros((n, n))
    Phi = np.eye(n)
    tmp = np.empty((n, n))
    Hp = np.empty((m, n))
    prev = 0
    for t in pick:
        for s in range(prev + 1, t + 1):
            _mm(_at(F, s), Phi, tmp)
            _copy2(Phi, tmp)
        prev = t
        for i in range(n):
            for j in range(n):
                if not abs(Phi[i, j]) <= 1e150:  # NaN too
                    return W
        _mm(_at(H, t), Phi, Hp)
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for a in range(m):
                    acc += Hp[a, i] * Hp[a, j]
                W[i, j] += acc
    return W
