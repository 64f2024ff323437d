"""Known-rate segments (a rate table) in the gyroscope's estimate, with the multi-pose one (issue 27).

On a rate table the gyro reads, averaged over a segment of constant stated rate ``w_k = rate_k a_k``,

    m_k = D_k M_g w_k + b(t_k, T) + e_k,   D_k = I + diag(sum_j c_j <dT^(j+1)>_k)

with the same temperature model as the multi-pose part: the bias ``b`` against time and temperature (the static
poses' bias model evaluated over the segment) and each gyro row's relative scale change ``S_g(dT) = sum_j c_j
dT^(j+1)`` (``dT = T - T_ref``, averaged over the segment's samples: the rate is constant there, so the mean
reading holds the mean factor exactly).  Without temperature terms ``D_k = I`` and the model is linear in
``M_g``.  The multi-pose fit (:mod:`senscal.imu.calibrate`) gives ``theta = (M_g, c)`` as ``theta_p`` with
covariance ``C_p``; the table's segments are combined with it as one Gaussian likelihood (the pose fit
linearised at its optimum; the segments' model, bilinear in ``M_g`` and ``c``, by Gauss-Newton)::

    theta = argmin (theta - theta_p)^T C_p^-1 (theta - theta_p) + (y - f(theta))^T S^-1 (y - f(theta))

``y_k = m_k - b(t_k, T)``; ``A`` below is the Jacobian of ``f`` at the solution.  Segments at temperatures the
poses did not see sharpen ``c`` as well as ``M_g``.  ``S`` holds every source of the segments' error: the noise of the segment means
(type A), the gyro bias model from the static poses evaluated at the segments (type A, correlated between
segments), the stated rate's u (type B: one relative error of the table common to all segments, its encoder
or timebase scale) and the axis direction's u (type B: the mount's, common to the segments about the same
stated axis), both through ``M_g``.  Because ``S`` and
``C_p`` add up linearly, the combined covariance ``(C_p^-1 + A^T S^-1 A)^-1`` splits exactly into one term
per source: the certificate's budget.

Consistency: the segments predicted by the multi-pose estimate, ``e = y - A theta_p`` with covariance
``S + A C_p A^T``, must scatter as chi-square with ``3 K`` degrees of freedom; beyond its 99.9 % point the
table's rates disagree with the data beyond u (``rate-table-inconsistent``, the u then scaled by the excess).

The pose fit and the segments share only the static poses' bias estimate, whose effect on the
rotations between poses is small (each rotation lasts a second or two); that correlation is neglected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import InputError

__all__ = ["RateTableFit", "SegmentData", "segment_data", "pose_cut", "combine_rate_table", "derived_components",
           "temperature_powers", "SOURCES"]

#: Budget sources of the combined gyro matrix, in order, with their GUM type.
SOURCES = (("multi-pose rotations (type A)", "A"), ("rate-table segment means, gyro noise (type A)", "A"),
           ("gyro bias from the static poses (type A)", "A"), ("table rate, stated u (type B)", "B"),
           ("table axis alignment, stated u (type B)", "B"))
#: A gyro sample farther than this many still-noise deviations from the still level is moving.
MOVING_SIGMA = 6.0
#: Margin kept between the multi-pose part and the table's first motion, s.
CUT_MARGIN_S = 1.0


@dataclass(frozen=True)
class SegmentData(ResultMixin):
    """Gyro readings averaged over each rate-table segment.

    Attributes
    ----------
    index : tuple of ndarray
        Sample indices of each segment.
    means, var_means : ndarray, shape (K, 3)
        Mean reading per axis and the variance of that mean (gyro units).
    """

    index: tuple = field(repr=False)
    means: np.ndarray
    var_means: np.ndarray


def temperature_powers(temp: np.ndarray | None, seg: SegmentData, temp_ref: float | None, degree: int) -> np.ndarray:
    """``<dT^(j+1)>_k``: the mean power of the temperature offset over each segment's samples, shape (K, degree).

    Parameters
    ----------
    temp : ndarray (N,) or None
        The temperature channel on the segments' sample axis (None: no temperature terms, shape (K, 0)).
    temp_ref : float or None
        The reference temperature of the calibration.
    degree : int
        Degree of the gyro's scale against temperature.
    """
    k_n = len(seg.index)
    if temp is None or temp_ref is None or degree <= 0:
        return np.zeros((k_n, 0))
    tp = np.asarray(temp, float)
    return np.array([[float(np.mean((tp[ix] - temp_ref) ** (j + 1))) for j in range(degree)] for ix in seg.index])


@dataclass(frozen=True)
class RateTableFit(ResultMixin):
    """The gyro matrix from the multi-pose fit and the rate table together.

    Attributes
    ----------
    matrix, covariance : ndarray, shape (3, 3) and (9, 9)
        Combined ``M_g`` (reading per rad/s) and its covariance (scaled by ``inflation``).
    components : tuple of (str, str, ndarray (9, 9))
        ``(source, type, covariance)`` per :data:`SOURCES`; they add up to ``covariance``.
    pose_matrix, pose_covariance :
        The multi-pose estimate alone.
    table_matrix, table_covariance : ndarray or None
        The table alone (None when its axes do not span three dimensions).
    chi2, dof : float, int
        Consistency of the segments with the multi-pose estimate (``3 K`` degrees of freedom).
    inflation : float
        ``sqrt(chi2 / dof)`` when that exceeds the 99.9 % point, else 1.
    residual, u_residual : ndarray, shape (K, 3)
        Segment mean minus the combined prediction (gyro units), and the u of the predicted mean.
    predicted_from_poses : ndarray, shape (K, 3)
        Segment mean minus the multi-pose prediction (gyro units).
    warnings : tuple of str
    scale_tc, scale_tc_covariance : ndarray, shape (d, 3) and (3d, 3d)
        The gyro's relative scale change against temperature (coefficient ``j`` per ``dT^(j+1)``, per gyro
        axis), combined, and its covariance (row-major, scaled by ``inflation``); ``d = 0`` without temperature
        terms.
    full_covariance : ndarray, shape (9 + 3d, 9 + 3d)
        Covariance of ``M_g`` and ``scale_tc`` together (scaled by ``inflation``).
    temperature_span : ndarray, shape (K,) or None
        Mean temperature offset ``<dT>`` of each segment from the reference (None without temperature terms).
    """

    matrix: np.ndarray
    covariance: np.ndarray
    components: tuple = field(repr=False)
    pose_matrix: np.ndarray
    pose_covariance: np.ndarray
    table_matrix: np.ndarray | None
    table_covariance: np.ndarray | None
    chi2: float
    dof: int
    inflation: float
    residual: np.ndarray
    u_residual: np.ndarray
    predicted_from_poses: np.ndarray
    warnings: tuple = ()
    scale_tc: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    scale_tc_covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    full_covariance: np.ndarray | None = None
    temperature_span: np.ndarray | None = None


def _runs_at(x: np.ndarray, ext: float) -> int:
    at = np.concatenate([[0], (x == ext).astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(at))
    return int(np.max(edges[1::2] - edges[0::2])) if edges.size else 0


def segment_data(t: np.ndarray, gyro: np.ndarray, table, *, gyro_noise: np.ndarray | None = None,
                 source: str = "the recording") -> SegmentData:
    """Average the gyro over each segment; refuse segments outside the record or beyond the gyro's range.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times, s: the table's times are on this axis (the recording's time column; a record without
        one starts at 0), so ``--start``/``--stop`` leave them valid.
    gyro : ndarray, shape (3, N)
    table : senscal.io.ratetable.RateTable
    gyro_noise : ndarray (3,), optional
        Per-sample noise at rest; the mean's variance uses the larger of it and the segment's own scatter.

    Raises
    ------
    InputError
        A segment outside the record or with fewer than 10 samples; a gyro axis clipped at its extreme
        reading during a segment (the stated rate is beyond the gyro's range).
    """
    rel = np.asarray(t, float)
    idx, means, var = [], [], []
    for k in range(table.n_segments):
        lab = table.label(k)
        if table.start[k] < rel[0] or table.stop[k] > rel[-1]:
            raise InputError(f"rate table {table.source}: {lab} lies outside {source} ({rel[0]:.6g} .. {rel[-1]:.6g} "
                             "s); give the segments' times on the recording's time axis")
        ix = np.flatnonzero((rel >= table.start[k]) & (rel <= table.stop[k]))
        if ix.size < 10:
            raise InputError(f"rate table {table.source}: {lab} holds {ix.size} samples of {source}; a segment "
                             "needs at least 10 (give its constant-rate part)")
        for i in range(3):
            for ext in (gyro[i].max(), gyro[i].min()):
                if _runs_at(gyro[i, ix], ext) >= 3:
                    raise InputError(f"rate table {table.source}: during {lab} gyro axis {'xyz'[i]} sits at its "
                                     f"extreme reading {ext:.6g}: the rate is beyond the gyro's range (saturated); "
                                     "drop the segment or run the table slower")
        g = gyro[:, ix]
        # The scatter about a straight line in time: a temperature drift during the segment moves the bias and
        # the scale (both modelled through the segment's mean temperature), it is no noise of the mean.
        tt = rel[ix] - rel[ix].mean()
        slope = (g - g.mean(axis=1, keepdims=True)) @ tt / max(float(tt @ tt), 1e-300)
        s2 = np.sum((g - g.mean(axis=1, keepdims=True) - slope[:, None] * tt[None, :]) ** 2, axis=1) / (ix.size - 2)
        if gyro_noise is not None:
            s2 = np.maximum(s2, np.asarray(gyro_noise, float) ** 2)
        idx.append(ix)
        means.append(g.mean(axis=1))
        var.append(s2 / ix.size)
    return SegmentData(index=tuple(idx), means=np.array(means), var_means=np.array(var))


def pose_cut(t: np.ndarray, gyro: np.ndarray, table) -> int:
    """Samples before this index hold the multi-pose session (the table's motion comes after it).

    The accelerometer cannot see a turn about the vertical, so a pose on the table would run into the spin-up:
    the cut lies :data:`CUT_MARGIN_S` before the last still gyro sample preceding the first segment (still:
    within :data:`MOVING_SIGMA` still-noise deviations of the pre-table median; the noise from the record's
    first second, the IMU-TK protocol's still start).
    """
    rel = np.asarray(t, float)
    i_seg = int(np.searchsorted(rel, float(np.min(table.start))))
    fs = (rel.size - 1) / max(float(rel[-1] - rel[0]), 1e-300)
    n0 = max(int(round(fs)), 20)
    if i_seg <= n0:
        return i_seg
    b0 = np.median(gyro[:, :i_seg], axis=1)
    s0 = np.maximum(gyro[:, :n0].std(axis=1, ddof=1), 1e-12 * (np.abs(b0) + 1.0))
    dev = np.max(np.abs(gyro[:, :i_seg] - b0[:, None]) / s0[:, None], axis=0)
    quiet = np.flatnonzero(dev < MOVING_SIGMA)
    j = int(quiet[-1]) if quiet.size else i_seg
    return max(j - int(round(CUT_MARGIN_S * fs)), 0)


def derived_components(matrix: np.ndarray, covs) -> tuple[np.ndarray, list[np.ndarray]]:
    """Scale (3) and misalignment angles (6) of ``matrix`` and each covariance carried to them."""
    from senscal.imu.calibrate import _derived

    x = np.asarray(matrix, float).ravel()
    f0 = _derived(x)
    step = 1e-7 * max(float(np.max(np.abs(x))), 1e-300)
    jac = np.empty((f0.size, 9))
    for i in range(9):
        h = np.zeros(9)
        h[i] = step
        jac[:, i] = (_derived(x + h) - _derived(x - h)) / (2 * step)
    return f0, [jac @ c @ jac.T for c in covs]


def _inv(c: np.ndarray) -> np.ndarray:
    c = 0.5 * (c + c.T)
    try:
        return np.linalg.inv(c)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(c)


def combine_rate_table(table, seg: SegmentData, bias: np.ndarray, cov_bias: np.ndarray, pose_matrix: np.ndarray,
                       pose_covariance: np.ndarray, *, scale_tc: np.ndarray | None = None,
                       temp_powers: np.ndarray | None = None) -> RateTableFit:
    """Combine the rate table's segments with the multi-pose gyro estimate (one likelihood).

    Parameters
    ----------
    table : senscal.io.ratetable.RateTable
    seg : SegmentData
        The segments' gyro means (:func:`segment_data`).
    bias : ndarray, shape (K, 3)
        The gyro bias model at each segment (mean over its samples, temperature terms included), gyro units.
    cov_bias : ndarray, shape (3, K, K)
        Its covariance between segments, per axis.
    pose_matrix : ndarray, shape (3, 3)
        The multi-pose estimate of ``M_g``.
    pose_covariance : ndarray, shape (9 + 3d, 9 + 3d)
        Its covariance (row-major), with ``scale_tc`` the joint covariance of ``M_g`` and ``scale_tc``.
    scale_tc : ndarray, shape (d, 3), optional
        The multi-pose estimate of the gyro's relative scale change against temperature
        (:class:`senscal.imu.calibrate.TemperatureTerms` ``gyro_scale``).
    temp_powers : ndarray, shape (K, d), optional
        ``<dT^(j+1)>`` over each segment (:func:`temperature_powers`).

    Returns
    -------
    RateTableFit
    """
    k_n = table.n_segments
    w = table.rate_vectors
    c_p = np.zeros((0, 3)) if scale_tc is None else np.asarray(scale_tc, float).reshape(-1, 3)
    d_n = c_p.shape[0]
    pw = np.zeros((k_n, 0)) if d_n == 0 else np.asarray(temp_powers, float).reshape(k_n, d_n)
    n_p = 9 + 3 * d_n
    y = (seg.means - bias).ravel()
    s_noise = np.diag(seg.var_means.ravel())
    s_bias = np.zeros((3 * k_n, 3 * k_n))
    for i in range(3):
        s_bias[i::3, i::3] = cov_bias[i]
    theta_p = np.concatenate([np.asarray(pose_matrix, float).ravel(), c_p.ravel()])
    cp = np.asarray(pose_covariance, float)
    if cp.shape != (n_p, n_p):
        raise ValueError(f"pose_covariance must be {n_p} x {n_p} for {d_n} scale-temperature degrees, got {cp.shape}")
    cp = 0.5 * (cp + cp.T)
    cpi = _inv(cp)

    def factors(th):
        """``(1 + S_g)`` per segment and gyro axis, shape (K, 3)."""
        return 1.0 + pw @ th[9:].reshape(d_n, 3) if d_n else np.ones((k_n, 3))

    def model(th):
        """Predicted segment means less bias (3K,) and their Jacobian (3K, 9 + 3d)."""
        m = th[:9].reshape(3, 3)
        fac = factors(th)
        mw = w @ m.T  # (K, 3): M_g w_k
        jac = np.zeros((3 * k_n, n_p))
        for k in range(k_n):
            for i in range(3):
                jac[3 * k + i, 3 * i:3 * i + 3] = fac[k, i] * w[k]
                for j in range(d_n):
                    jac[3 * k + i, 9 + 3 * j + i] = pw[k, j] * mw[k, i]
        return (fac * mw).ravel(), jac

    # The stated rate's error is one relative error of the table (its encoder or timebase scale), common to
    # all segments; the axis error is the mount's, common to the segments about the same stated axis.  Both act
    # through the gyro as it reads on the table: D_k M_g.
    same = np.abs(table.axis @ table.axis.T - 1.0) < 1e-9
    sgn = np.sign(table.rate)

    def type_b(th):
        m = th[:9].reshape(3, 3)
        fac = factors(th)
        v = (fac * (table.axis @ m.T) * (table.u_rate * sgn)[:, None]).ravel()  # (3K,): one common error
        s_rate = np.outer(v, v)
        s_axis = np.zeros_like(s_noise)
        for k in range(k_n):
            for j in np.flatnonzero(same[k]):
                ax = table.axis[k]
                c = table.rate[k] * table.rate[j] * table.u_axis[k] * table.u_axis[j]
                s_axis[3 * k:3 * k + 3, 3 * j:3 * j + 3] = c * (np.diag(fac[k]) @ m @ (np.eye(3) - np.outer(ax, ax))
                                                               @ m.T @ np.diag(fac[j]))
        return s_rate, s_axis

    theta = theta_p.copy()
    # Gauss-Newton on the prior plus the segments; the type B terms scale with M_g (a fixed point): a few passes.
    for _ in range(6):
        s_rate, s_axis = type_b(theta)
        parts = [s_noise, s_bias, s_rate, s_axis]
        s = sum(parts)
        si = _inv(s)
        f, a = model(theta)
        h = cpi + a.T @ si @ a
        cc = _inv(h)
        step = cc @ (cpi @ (theta_p - theta) + a.T @ si @ (y - f))
        theta = theta + step
        if np.all(np.abs(step) <= 1e-12 * (np.abs(theta) + 1e-300)):
            break
    s_rate, s_axis = type_b(theta)
    parts = [s_noise, s_bias, s_rate, s_axis]
    s = sum(parts)
    si = _inv(s)
    f, a = model(theta)
    cc = _inv(cpi + a.T @ si @ a)
    m = theta[:9].reshape(3, 3)
    gain = cc @ a.T @ si
    comps = [cc @ cpi @ cc] + [gain @ p @ gain.T for p in parts]
    # Consistency of the segments with the multi-pose estimate: predictive chi-square, 3 K dof.
    f_p, a_p = model(theta_p)
    e = y - f_p
    sp = s + a_p @ cp @ a_p.T
    chi2 = float(e @ _inv(sp) @ e)
    dof = 3 * k_n
    warnings = []
    infl = 1.0
    if chi2 > stats.chi2.ppf(0.999, dof):
        infl = math.sqrt(chi2 / dof)
        per = [float(e[3 * k:3 * k + 3] @ _inv(sp[3 * k:3 * k + 3, 3 * k:3 * k + 3]) @ e[3 * k:3 * k + 3])
               for k in range(k_n)]
        worst = int(np.argmax(per))
        warnings.append(named("rate-table-inconsistent", (
            f"the gyro readings on the rate table disagree with the table's stated rates and the multi-pose "
            f"calibration beyond their u (chi2 {chi2:.1f} for {dof} dof, 99.9 % point "
            f"{stats.chi2.ppf(0.999, dof):.1f}; worst {table.label(worst)}, chi2 {per[worst]:.1f} of 3): a wrong "
            "stated rate or axis, a u_rate too small, the IMU moving on the table, or a gyro scale against "
            f"temperature the poses did not resolve; the u are scaled by {infl:.2g}")))
    table_m = table_c = None
    if np.linalg.matrix_rank(w, tol=1e-9 * float(np.max(np.abs(w)))) == 3:
        # The table alone, its segments read through the multi-pose temperature factors.
        am = a[:, :9] if d_n == 0 else model(np.concatenate([theta[:9], theta_p[9:]]))[1][:, :9]
        tc = _inv(am.T @ si @ am)
        table_c = tc
        table_m = (tc @ am.T @ si @ y).reshape(3, 3)
    res = (y - f).reshape(k_n, 3)
    u_pred = np.sqrt(np.clip(np.diag(a @ cc @ a.T), 0, None)).reshape(k_n, 3)
    f2 = infl ** 2
    cm = cc[:9, :9] * f2
    return RateTableFit(matrix=m, covariance=cm,
                        components=tuple((src, kind, c[:9, :9] * f2) for (src, kind), c in zip(SOURCES, comps)),
                        pose_matrix=np.asarray(pose_matrix, float), pose_covariance=cp[:9, :9], table_matrix=table_m,
                        table_covariance=table_c, chi2=chi2, dof=dof, inflation=infl, residual=res,
                        u_residual=u_pred, predicted_from_poses=e.reshape(k_n, 3), warnings=tuple(warnings),
                        scale_tc=theta[9:].reshape(d_n, 3), scale_tc_covariance=cc[9:, 9:] * f2,
                        full_covariance=cc * f2, temperature_span=pw[:, 0] if d_n else None)
