"""Kernels for the uniform-time, unweighted fast path of the sine fit.

The projections ``A^T y`` and ``sum(y^2)`` of every channel are taken in one
streaming pass over the data.  For the fundamental the sin/cos basis is never
stored: each block of ``_TEMPLATE`` samples is the template
``sin(k w dt), cos(k w dt)`` rotated by the block's exact start angle (one
sin/cos per block), so the only memory traffic is the data itself and the
basis is exact to rounding (no accumulated recurrence error).  Harmonics and
drift use a stored basis from a re-anchored rotation recurrence.

Compilation is a first-use cost (about 10 s of numba on a quiet machine for
these kernels, several times that on a busy one), so the compiled loops are
built only for records of at least :data:`COMPILED_MIN_SAMPLES` values
(channels x samples); below that, plain NumPy computes the same sums (to
rounding) in a few milliseconds, and numba is not even imported.  The public functions
(``gram_rotated``, ``project_rotated_serial``, ``project_serial``,
``harmonic_basis``, ``residual_ss`` ...) choose the path; :func:`compiled`
returns the numba dispatchers.
"""

from __future__ import annotations

import math
import types

import numpy as np

_ANCHOR = 512   # samples between exact re-anchoring of the recurrence
_BLOCK = 2048   # samples per cache block in the projection
_TEMPLATE = 1024  # samples per rotated template block (two 8 KiB tables stay in L1)


def _harmonic_basis_into(out: np.ndarray, w_dt: float, tau0_w: float, harmonics: int) -> np.ndarray:
    """Rows ``sin(k*(tau0_w + i*w_dt))``, ``cos(...)`` for k = 1..harmonics, written into the first
    ``2*harmonics`` rows of ``out`` (shape (>= 2K, n)); returns ``out``.

    The sine fit builds its design rows (basis, constant, drift) in one array, so that the basis is not
    allocated and copied a second time (64 MB at a million samples and three harmonics, issue 28).
    """
    n = out.shape[1]
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
    """One pass: ``A^T (y - pilot)``, ``sum((y - pilot)^2)`` and the lag-one sum per channel.

    The lag-one sum ``sum_i v_i v_{i-1}`` (``v = y - pilot``) costs one
    multiply-add on data already in cache; from it the residual's lag-one
    autocorrelation (the whiteness test) follows without a second pass.

    The design matrix ``A`` has the rows of ``basis``, then a constant row,
    then (if ``use_tau``) the centred time ``tau``.  Block partial sums keep
    the accumulation error at the level of pairwise summation.
    """
    nch, n = y.shape
    nb_ = basis.shape[0]
    p = nb_ + 1 + (1 if use_tau else 0)
    aty = np.zeros((nch, p))
    yy = np.zeros(nch)
    l1 = np.zeros(nch)
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
                lag = 0.0
                prev = y[c, s - 1] - pv if s > 0 else 0.0
                for i in range(s, e):
                    v = y[c, i] - pv
                    sq += v * v
                    lag += v * prev
                    prev = v
                    for j in range(nb_):
                        part[j] += v * basis[j, i]
                    part[nb_] += v
                    if use_tau:
                        part[nb_ + 1] += v * tau[i]
                for j in range(p):
                    aty[c, j] += part[j]
                yy[c] += sq
                l1[c] += lag
    return aty, yy, l1


def _residual_ss(y: np.ndarray, basis: np.ndarray, tau: np.ndarray, use_tau: bool, coef: np.ndarray, rows: np.ndarray):
    """Second pass: exact residual sum of squares and lag-one sum for the channels in ``rows``."""
    nb_ = basis.shape[0]
    n = y.shape[1]
    out = np.zeros(rows.size)
    lag = np.zeros(rows.size)
    for r in nb.prange(rows.size):
        c = rows[r]
        acc = 0.0
        acc1 = 0.0
        prev = 0.0
        for s in range(0, n, _BLOCK):
            e = min(s + _BLOCK, n)
            part = 0.0
            part1 = 0.0
            for i in range(s, e):
                m = coef[c, nb_]
                for j in range(nb_):
                    m += coef[c, j] * basis[j, i]
                if use_tau:
                    m += coef[c, nb_ + 1] * tau[i]
                d = y[c, i] - m
                part += d * d
                part1 += d * prev
                prev = d
            acc += part
            acc1 += part1
        out[r] = acc
        lag[r] = acc1
    return out, lag


def _template(w_dt: float):
    k = np.arange(_TEMPLATE) * w_dt
    return np.sin(k), np.cos(k)


def _row_rotated(yr, ts, tc, sa, ca, pv):
    # b0 = sin(a + k w dt), b1 = cos(a + k w dt) by the angle-sum identities:
    # independent per sample, so the loop vectorises.
    v = yr[0] - pv
    a0 = v * (sa * tc[0] + ca * ts[0])
    a1 = v * (ca * tc[0] - sa * ts[0])
    a2 = v
    sq = v * v
    lag = 0.0
    # The lag-one product reads yr[k - 1] afresh (no value carried between
    # iterations), so the loop still vectorises.
    for k in range(1, yr.size):
        v = yr[k] - pv
        b0 = sa * tc[k] + ca * ts[k]
        b1 = ca * tc[k] - sa * ts[k]
        a0 += v * b0
        a1 += v * b1
        a2 += v
        sq += v * v
        lag += v * (yr[k - 1] - pv)
    return a0, a1, a2, sq, lag


def _project_rotated(y: np.ndarray, w_dt: float, tau0_w: float, pilot: np.ndarray):
    """``A^T (y - pilot)``, ``sum((y - pilot)^2)`` and the lag-one sum for the fundamental + offset.

    The basis is generated on the fly.
    """
    nch, n = y.shape
    ts, tc = _template(w_dt)
    aty = np.zeros((nch, 3))
    yy = np.zeros(nch)
    l1 = np.zeros(nch)
    for c in nb.prange(nch):
        pv = pilot[c]
        for s in range(0, n, _TEMPLATE):
            e = min(s + _TEMPLATE, n)
            a = tau0_w + s * w_dt
            r0, r1, r2, r3, r4 = _row_rotated(y[c, s:e], ts, tc, math.sin(a), math.cos(a), pv)
            aty[c, 0] += r0
            aty[c, 1] += r1
            aty[c, 2] += r2
            yy[c] += r3
            l1[c] += r4
            if s > 0:
                l1[c] += (y[c, s] - pv) * (y[c, s - 1] - pv)
    return aty, yy, l1


def _gram_rotated(n: int, w_dt: float, tau0_w: float):
    """Normal matrix of [sin, cos, 1] on the same on-the-fly basis, shape (3, 3)."""
    ts, tc = _template(w_dt)
    ss = 0.0
    sc = 0.0
    cc = 0.0
    s1 = 0.0
    c1 = 0.0
    for s in range(0, n, _TEMPLATE):
        e = min(s + _TEMPLATE, n)
        a = tau0_w + s * w_dt
        sa = math.sin(a)
        ca = math.cos(a)
        for k in range(e - s):
            b0 = sa * tc[k] + ca * ts[k]
            b1 = ca * tc[k] - sa * ts[k]
            ss += b0 * b0
            sc += b0 * b1
            cc += b1 * b1
            s1 += b0
            c1 += b1
    g = np.empty((3, 3))
    g[0, 0] = ss
    g[0, 1] = g[1, 0] = sc
    g[1, 1] = cc
    g[0, 2] = g[2, 0] = s1
    g[1, 2] = g[2, 1] = c1
    g[2, 2] = n
    return g


# Threads pay only on large arrays; on small ones (and on a busy machine)
# the serial build is much faster than waking the thread pool.
PARALLEL_MIN_SAMPLES = 1 << 20
# Below this many values (channels x samples) NumPy's vectorised sums cost at
# most ~20 ms a call (the compiled pass: a tenth of that), far less than the
# ~10 s the compilation costs once; every record of `senscal demo` (the
# largest: one 100,000-sample channel in the gfimu section) and most single
# calibration records stay below it, while fit-array chunks and large batches
# (256 channels x 1024 samples and up) get the compiled pass.  Measured with
# benchmarks/bench_cli.py --cold-demo.
COMPILED_MIN_SAMPLES = 1 << 18


def _build(nb, fn, parallel: bool):
    """Compile ``fn`` serial or parallel under its own name.

    Numba's on-disk cache is keyed by the function's qualified name and line:
    two builds of one Python function would share (and overwrite) one cache
    entry, and a process could load the threaded build where it asked for the
    serial one, oversubscribing the cores of every Dask worker.
    """
    suffix = "_parallel" if parallel else "_serial"
    copy = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__ + suffix, fn.__defaults__, fn.__closure__)
    copy.__qualname__ = fn.__qualname__ + suffix
    copy.__doc__ = fn.__doc__
    copy.__module__ = fn.__module__
    return nb.njit(cache=True, parallel=parallel)(copy)


_COMPILED: types.SimpleNamespace | None = None


def compiled() -> types.SimpleNamespace:
    """The numba dispatchers (numba imported and the kernels declared on first call; each compiles on first use).

    Attributes ``project_rotated`` / ``project_rotated_serial``,
    ``project_parallel`` / ``project_serial``, ``harmonic_basis_parallel`` /
    ``harmonic_basis_serial``, ``harmonic_basis_into_parallel`` / ``harmonic_basis_into_serial``,
    ``gram_rotated``, ``residual_ss``.
    """
    global _COMPILED
    if _COMPILED is None:
        import numba as nb

        g = globals()
        # The kernels' bodies call nb.prange and the helpers below as globals, resolved when they compile.
        g["nb"] = nb
        g["_template"] = nb.njit(cache=True)(_template)
        g["_row_rotated"] = nb.njit(cache=True, fastmath=True)(_row_rotated)
        _COMPILED = types.SimpleNamespace(
            project_rotated=_build(nb, _project_rotated, True),
            project_rotated_serial=_build(nb, _project_rotated, False),
            project_parallel=_build(nb, _project, True),
            project_serial=_build(nb, _project, False),
            harmonic_basis_into_parallel=_build(nb, _harmonic_basis_into, True),
            harmonic_basis_into_serial=_build(nb, _harmonic_basis_into, False),
            gram_rotated=nb.njit(cache=True, fastmath=True)(_gram_rotated),
            residual_ss=nb.njit(cache=True, parallel=True, fastmath=False)(_residual_ss),
        )
        ns = _COMPILED
        # The basis alone is the written-into kernel on a fresh array: one kernel to compile and keep.
        ns.harmonic_basis_parallel = lambda n, w_dt, tau0_w, harmonics: ns.harmonic_basis_into_parallel(
            np.empty((2 * harmonics, n)), w_dt, tau0_w, harmonics)
        ns.harmonic_basis_serial = lambda n, w_dt, tau0_w, harmonics: ns.harmonic_basis_into_serial(
            np.empty((2 * harmonics, n)), w_dt, tau0_w, harmonics)
    return _COMPILED


def num_threads() -> int:
    """Threads the parallel kernels use (numba's setting)."""
    import numba as nb

    return int(nb.get_num_threads())


# --- NumPy: the same sums for records below COMPILED_MIN_SAMPLES -------------------------------------------


def _angles(n: int, w_dt: float, tau0_w: float) -> np.ndarray:
    return tau0_w + np.arange(n) * w_dt


def _sums(v: np.ndarray, design: np.ndarray):
    """``design @ v`` per channel, ``sum(v^2)`` and the lag-one sum ``sum v_i v_(i-1)``."""
    aty = v @ design.T
    yy = np.einsum("ij,ij->i", v, v)
    l1 = np.einsum("ij,ij->i", v[:, 1:], v[:, :-1])
    return aty, yy, l1


def _np_rotated_design(n: int, w_dt: float, tau0_w: float) -> np.ndarray:
    a = _angles(n, w_dt, tau0_w)
    return np.stack([np.sin(a), np.cos(a), np.ones(n)])


def _np_full_design(basis: np.ndarray, tau: np.ndarray, use_tau: bool) -> np.ndarray:
    rows = [basis, np.ones((1, basis.shape[1]))] + ([tau[None, :]] if use_tau else [])
    return np.concatenate(rows, axis=0)


def _small(values: int) -> bool:
    return values < COMPILED_MIN_SAMPLES


# --- what the sine fit calls --------------------------------------------------------------------------------


def gram_rotated(n: int, w_dt: float, tau0_w: float) -> np.ndarray:
    """Normal matrix of [sin, cos, 1] on the fundamental's basis, shape (3, 3)."""
    if _small(n):
        a = _np_rotated_design(n, w_dt, tau0_w)
        return a @ a.T
    return compiled().gram_rotated(n, float(w_dt), float(tau0_w))


def project_rotated(y: np.ndarray, w_dt: float, tau0_w: float, pilot: np.ndarray):
    """``A^T (y - pilot)``, ``sum((y - pilot)^2)``, lag-one sum for fundamental + offset (threaded when compiled)."""
    if _small(y.size):
        return _sums(y - pilot[:, None], _np_rotated_design(y.shape[1], w_dt, tau0_w))
    return compiled().project_rotated(y, float(w_dt), float(tau0_w), pilot)


def project_rotated_serial(y: np.ndarray, w_dt: float, tau0_w: float, pilot: np.ndarray):
    """As :func:`project_rotated`, one thread."""
    if _small(y.size):
        return _sums(y - pilot[:, None], _np_rotated_design(y.shape[1], w_dt, tau0_w))
    return compiled().project_rotated_serial(y, float(w_dt), float(tau0_w), pilot)


def project_parallel(y, basis, tau, use_tau: bool, pilot, nthreads: int):
    """``A^T (y - pilot)``, ``sum((y - pilot)^2)``, lag-one sum with a stored basis (threaded when compiled)."""
    if _small(y.size):
        return _sums(y - pilot[:, None], _np_full_design(basis, tau, use_tau))
    return compiled().project_parallel(y, basis, tau, use_tau, pilot, nthreads)


def project_serial(y, basis, tau, use_tau: bool, pilot, nthreads: int):
    """As :func:`project_parallel`, one thread."""
    if _small(y.size):
        return _sums(y - pilot[:, None], _np_full_design(basis, tau, use_tau))
    return compiled().project_serial(y, basis, tau, use_tau, pilot, nthreads)


def harmonic_basis(n: int, w_dt: float, tau0_w: float, harmonics: int, out: np.ndarray | None = None) -> np.ndarray:
    """Rows ``sin(k*(tau0_w + i*w_dt))``, ``cos(...)`` for k = 1..harmonics, shape (2K, n).

    With ``out`` (C-contiguous, shape (>= 2K, n)) the rows are written into its first 2K rows and ``out``
    is returned.
    """
    if _small(n * harmonics):
        a = _angles(n, w_dt, tau0_w)
        rows = [f(k * a) for k in range(1, harmonics + 1) for f in (np.sin, np.cos)]
        if out is None:
            return np.stack(rows)
        for j, r in enumerate(rows):
            out[j] = r
        return out
    c = compiled()
    par = n * harmonics >= PARALLEL_MIN_SAMPLES // 4
    if out is not None:
        fn = c.harmonic_basis_into_parallel if par else c.harmonic_basis_into_serial
        return fn(out, float(w_dt), float(tau0_w), int(harmonics))
    fn = c.harmonic_basis_parallel if par else c.harmonic_basis_serial
    return fn(n, float(w_dt), float(tau0_w), int(harmonics))


def residual_ss(y, basis, tau, use_tau: bool, coef, rows):
    """Second pass: exact residual sum of squares and lag-one sum for the channels in ``rows``."""
    if _small(y.shape[1] * rows.size):
        c = coef[rows]
        nb_ = basis.shape[0]
        m = c[:, :nb_] @ basis + c[:, nb_, None]
        if use_tau:
            m = m + c[:, nb_ + 1, None] * tau[None, :]
        d = y[rows] - m
        return np.einsum("ij,ij->i", d, d), np.einsum("ij,ij->i", d[:, 1:], d[:, :-1])
    return compiled().residual_ss(y, basis, tau, use_tau, coef, rows)
