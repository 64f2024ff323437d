"""Compiled kernels for the uniform-time, unweighted fast path of the sine fit.

The basis is generated once by a rotation recurrence (re-anchored with exact
sin/cos every block, so rounding cannot accumulate) and the projections
``A^T y`` and ``sum(y^2)`` of every channel are taken in one streaming pass
over the data, blocked so the basis block stays in cache while all channels
of a thread read it.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

_ANCHOR = 512   # samples between exact re-anchoring of the recurrence
_BLOCK = 2048   # samples per cache block in the projection


def _harmonic_basis(n: int, w_dt: float, tau0_w: float, harmonics: int) -> np.ndarray:
    """Rows ``sin(k*(tau0_w + i*w_dt))``, ``cos(...)`` for k = 1..harmonics.

    Returns an array of shape (2*harmonics, n).
    """
    out = np.empty((2 * harmonics, n))
    nblocks = (n + _ANCHOR - 1) // _ANCHOR
    for kk in range(harmonics):
        k = kk + 1
        cs = math.cos(k * w_dt)
        sn = math.sin(k * w_dt)
        for b in nb.prange(nblocks):
            i0 = b * _ANCHOR
            i1 = min(i0 + _ANCHOR, n)
            ang = k * (tau0_w + i0 * w_dt)
            s = math.sin(ang)
            c = math.cos(ang)
            for i in range(i0, i1):
                out[2 * kk, i] = s
                out[2 * kk + 1, i] = c
                s, c = s * cs + c * sn, c * cs - s * sn
    return out


def _project(y: np.ndarray, basis: np.ndarray, tau: np.ndarray, use_tau: bool, pilot: np.ndarray, nthreads: int):
    """One pass: ``A^T (y - pilot)`` and ``sum((y - pilot)^2)`` per channel.

    The design matrix ``A`` has the rows of ``basis``, then a constant row,
    then (if ``use_tau``) the centred time ``tau``.  Block partial sums keep
    the accumulation error at the level of pairwise summation.
    """
    nch, n = y.shape
    nb_ = basis.shape[0]
    p = nb_ + 1 + (1 if use_tau else 0)
    aty = np.zeros((nch, p))
    yy = np.zeros(nch)
    ngroups = min(nthreads, nch)
    for g in nb.prange(ngroups):
        c0 = (g * nch) // ngroups
        c1 = ((g + 1) * nch) // ngroups
        part = np.zeros(p)
        for s in range(0, n, _BLOCK):
            e = min(s + _BLOCK, n)
            for c in range(c0, c1):
                pv = pilot[c]
                for j in range(p):
                    part[j] = 0.0
                sq = 0.0
                for i in range(s, e):
                    v = y[c, i] - pv
                    sq += v * v
                    for j in range(nb_):
                        part[j] += v * basis[j, i]
                    part[nb_] += v
                    if use_tau:
                        part[nb_ + 1] += v * tau[i]
                for j in range(p):
                    aty[c, j] += part[j]
                yy[c] += sq
    return aty, yy


@nb.njit(cache=True, parallel=True, fastmath=False)
def residual_ss(y: np.ndarray, basis: np.ndarray, tau: np.ndarray, use_tau: bool, coef: np.ndarray, rows: np.ndarray):
    """Second pass: exact residual sum of squares for the channels in ``rows``."""
    nb_ = basis.shape[0]
    n = y.shape[1]
    out = np.zeros(rows.size)
    for r in nb.prange(rows.size):
        c = rows[r]
        acc = 0.0
        for s in range(0, n, _BLOCK):
            e = min(s + _BLOCK, n)
            part = 0.0
            for i in range(s, e):
                m = coef[c, nb_]
                for j in range(nb_):
                    m += coef[c, j] * basis[j, i]
                if use_tau:
                    m += coef[c, nb_ + 1] * tau[i]
                d = y[c, i] - m
                part += d * d
            acc += part
        out[r] = acc
    return out


@nb.njit(cache=True, fastmath=True)
def _row_fundamental(yr, b0, b1, pv):
    # Scalar accumulators over a contiguous block: LLVM vectorises this loop
    # (fastmath only lets it re-associate the sums into SIMD lanes).
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    sq = 0.0
    for i in range(yr.size):
        v = yr[i] - pv
        a0 += v * b0[i]
        a1 += v * b1[i]
        a2 += v
        sq += v * v
    return a0, a1, a2, sq


def _project_fundamental(y: np.ndarray, basis: np.ndarray, pilot: np.ndarray):
    """:func:`project` specialised to the fundamental with offset (p = 3).

    One streaming pass per channel; block partial sums (``_BLOCK * 8``
    samples) bound the rounding error of the long sums.
    """
    nch, n = y.shape
    aty = np.zeros((nch, 3))
    yy = np.zeros(nch)
    blk = _BLOCK * 8
    for c in nb.prange(nch):
        pv = pilot[c]
        for s in range(0, n, blk):
            e = min(s + blk, n)
            a0, a1, a2, sq = _row_fundamental(y[c, s:e], basis[0, s:e], basis[1, s:e], pv)
            aty[c, 0] += a0
            aty[c, 1] += a1
            aty[c, 2] += a2
            yy[c] += sq
    return aty, yy


# Threads pay only on large arrays; on small ones (and on a busy machine)
# the serial build is much faster than waking the thread pool.
project_fundamental = nb.njit(cache=True, parallel=True)(_project_fundamental)
project_parallel = nb.njit(cache=True, parallel=True)(_project)
project_serial = nb.njit(cache=True)(_project)
harmonic_basis_parallel = nb.njit(cache=True, parallel=True)(_harmonic_basis)
harmonic_basis_serial = nb.njit(cache=True)(_harmonic_basis)


def harmonic_basis(n: int, w_dt: float, tau0_w: float, harmonics: int) -> np.ndarray:
    """Rows ``sin(k*(tau0_w + i*w_dt))``, ``cos(...)`` for k = 1..harmonics, shape (2K, n)."""
    fn = harmonic_basis_parallel if n * harmonics >= PARALLEL_MIN_SAMPLES // 4 else harmonic_basis_serial
    return fn(n, float(w_dt), float(tau0_w), int(harmonics))
project_fundamental_serial = nb.njit(cache=True)(_project_fundamental)
PARALLEL_MIN_SAMPLES = 1 << 20
