"""Accelerometer and gyroscope of an IMU from one multi-pose session.

The protocol is IMU-TK's [1]_: a still start, then static poses joined by
hand rotations.  The accelerometer is calibrated on the static pose means by
maximum likelihood on ``|f| = g`` (the triaxial engine,
:func:`senscal.triaxial.calibrate` / :func:`senscal.triaxial.fit_ml`); its
corrected pose directions are the reference for the gyroscope, whose model

    w_meas = M_g w + b_g(t)

(``M_g`` a full 3x3 matrix: scale on the diagonal, misalignment to the
accelerometer's frame off it; ``b_g`` linear in time) is fitted so that the
rotation integrated between consecutive poses (quaternion RK4) carries the
gravity direction seen at one pose onto the one seen at the next.

Uncertainty: generalised least squares with the residual covariance built
from the noise (integrated gyro noise per rotation, pose-mean noise of the
accelerometer, which correlates consecutive residuals), scaled by the
residuals' own chi-square per degree of freedom; the uncertainty of the
accelerometer calibration and of the gyro bias (nuisance parameters fixed
during the fit) is propagated through the fit's sensitivity to them.

References
----------
.. [1] Tedaldi D., Pretto A., Menegatti E., "A robust and easy to implement
   method for IMU calibration without external equipments", ICRA 2014.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy import linalg, optimize, stats

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import ConvergenceError, DataError, InputError
from senscal.imu.static import MULTIPLES, PoseSweep, sweep_static
from senscal.imu.terms import (MIN_SWING_K, BiasDesign, accel_temperature_correct, accel_temperature_degree, fit_bias,
                               press_degree)

__all__ = ["GyroCalibration", "ImuResult", "TemperatureTerms", "calibrate_imu", "GYRO_ANGLES", "ACCEL_NAMES"]

ACCEL_NAMES = ("Kx", "Ky", "Kz", "alpha", "beta", "gamma", "Bx", "By", "Bz")
#: Gyro misalignment angles: ``"xy"`` is the tilt of the gyro's X axis towards the accelerometer frame's Y.
GYRO_ANGLES = ("xy", "xz", "yx", "yz", "zx", "zy")
_PAIRS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
#: Rotation per sample above which the rate is sampled too coarsely for the integration (rad); RK4 on a
#: linearly interpolated rate has a per-step attitude error ~ (w dt)^3 |dw/dt| dt / w ..., which stays below
#: 1e-5 rad per step at this rotation for hand motion.
MAX_STEP_ANGLE = 0.15
#: An axis whose accumulated rotation is below this fraction of the most-rotated axis's is called unexcited.
MIN_EXCITATION = 0.1


@dataclass(frozen=True)
class GyroCalibration(ResultMixin):
    """The gyroscope's model with u (k=1).

    Attributes
    ----------
    matrix : ndarray, shape (3, 3)
        ``M_g``: reading per rad/s of true rate along each accelerometer-frame axis.
    covariance : ndarray, shape (9, 9)
        Covariance of ``matrix`` (row-major elements), noise and nuisance (accelerometer, bias) together.
    scale, u_scale : ndarray, shape (3,)
        Reading per rad/s along each gyro axis (signed row norm of ``M_g``).
    angles, u_angles : ndarray, shape (6,)
        Misalignment angles in rad (:data:`GYRO_ANGLES`).
    bias, u_bias : ndarray, shape (3,)
        Reading at zero rate at ``t_ref`` (gyro units); with a temperature channel at the reference
        temperature, with ``g_sensitivity`` at zero specific force.
    bias_rate, u_bias_rate : ndarray, shape (3,) or None
        Bias change per second during the session (None when temperature terms model the change instead).
    t_ref : float
        Time of ``bias`` (s from the recording's first sample): the weighted centre of the static poses.
    g_sensitivity, u_g_sensitivity : ndarray, shape (3, 3) or None
        ``G``: gyro reading per m/s^2 of specific force (row: gyro axis, column: accelerometer-frame axis);
        None unless asked for.
    """

    matrix: np.ndarray
    covariance: np.ndarray
    scale: np.ndarray
    u_scale: np.ndarray
    angles: np.ndarray
    u_angles: np.ndarray
    bias: np.ndarray
    u_bias: np.ndarray
    bias_rate: np.ndarray | None
    u_bias_rate: np.ndarray | None
    t_ref: float
    g_sensitivity: np.ndarray | None = None
    u_g_sensitivity: np.ndarray | None = None

    def apply(self, gyro: np.ndarray) -> np.ndarray:
        """True rate in rad/s (accelerometer frame) from readings, shape (3, N), at the reference conditions."""
        return np.linalg.solve(self.matrix, np.asarray(gyro, float) - self.bias[:, None])


@dataclass(frozen=True)
class TemperatureTerms(ResultMixin):
    """Bias and scale against temperature (``dT = T - reference``; coefficient ``j`` multiplies ``dT^(j+1)``).

    Attributes
    ----------
    reference : float
        Temperature at which the calibration's biases and scales hold (sample-weighted mean over the poses).
    unit : str
        The temperature channel's unit.
    swing, low, high : float
        Range of the pose temperatures.
    degree_accel, degree_gyro : int
        Polynomial degrees chosen on held-out poses (0: no temperature dependence detected).
    accel_bias, u_accel_bias : ndarray, shape (degree_accel, 3)
        Accelerometer bias change, reading per unit^j.
    accel_scale, u_accel_scale : ndarray, shape (degree_accel, 3)
        Relative accelerometer scale change per unit^j.
    gyro_bias, u_gyro_bias : ndarray, shape (degree_gyro, 3)
        Gyro bias change, reading per unit^j.
    scores_accel, scores_gyro : tuple of float
        Held-out chi-square per degree tried (the smallest wins).
    degree_gyro_scale : int
        Degree of the gyro's relative scale change, chosen on held-out rotations (0: none detected).
    gyro_scale, u_gyro_scale : ndarray, shape (degree_gyro_scale, 3)
        Relative gyro scale change per unit^j, per gyro axis: ``g = (1 + S_g(dT)) M_g w + ...`` (each row of
        ``M_g`` scaled: the misalignment angles do not change with temperature).
    scores_gyro_scale : tuple of float
        Held-out chi-square of the rotations per degree tried.
    """

    reference: float
    unit: str
    swing: float
    low: float
    high: float
    degree_accel: int
    degree_gyro: int
    accel_bias: np.ndarray
    u_accel_bias: np.ndarray
    accel_scale: np.ndarray
    u_accel_scale: np.ndarray
    gyro_bias: np.ndarray
    u_gyro_bias: np.ndarray
    scores_accel: tuple = ()
    scores_gyro: tuple = ()
    degree_gyro_scale: int = 0
    gyro_scale: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    u_gyro_scale: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    scores_gyro_scale: tuple = ()


@dataclass(frozen=True)
class ImuResult(ResultMixin):
    """Everything the IMU calibration found out.

    Attributes
    ----------
    accelerometer : senscal.triaxial.TriaxialResult
        The triaxial engine's answer on the static pose means (model ``full``, field = gravity).
    accel_values : ndarray, shape (9,)
        :data:`ACCEL_NAMES` (gains, angles in rad, offsets in the accelerometer's unit).
    accel_covariance : ndarray, shape (9, 9)
        Their covariance from the pose means' own noise (see :func:`_accel_covariance`); the triaxial
        engine's ``parameters`` quote ``s^2 (J^T J)^-1`` with one pooled noise instead.
    accel_chi2, accel_dof :
        Chi-square of the pose means about ``|f| = g`` against their noise, and its degrees of freedom.
    gyroscope : GyroCalibration
    poses : PoseSweep
        Static poses and the threshold sweep.
    residual_before_deg, residual_after_deg : ndarray, shape (K-1,)
        Per rotation: angle between the gravity direction predicted at the next pose and the one measured,
        with the nominal gyro (bias removed, unit matrix times the nominal scale) and calibrated.
    nominal_scale : float
        The nominal gyro scale of the 'before' figures (reading per rad/s; 1 for readings in rad/s).
    chi2, dof : float, int
        Generalised residual chi-square of the gyro fit and its degrees of freedom.
    noise_scale : float
        ``sqrt(chi2 / dof)``: how much larger the residuals are than the noise model says (u are scaled by it).
    excitation_rad : ndarray, shape (3,)
        Rotation accumulated about each accelerometer-frame axis over the rotations, rad.
    gyro_noise : ndarray, shape (3,)
        Per-sample standard deviation of the gyro at rest (gyro units).
    gravity : float
    temperature : TemperatureTerms or None
        With a temperature channel.
    warnings : tuple of str
    rate_table : senscal.imu.ratetable.RateTableFit or None
        With known-rate segments: the pose-only and combined gyro estimates, the consistency check and the
        budget (``gyroscope`` then holds the combined matrix).
    """

    accelerometer: Any
    accel_values: np.ndarray
    accel_covariance: np.ndarray
    accel_chi2: float
    accel_dof: int
    gyroscope: GyroCalibration
    poses: PoseSweep
    residual_before_deg: np.ndarray
    residual_after_deg: np.ndarray
    nominal_scale: float
    chi2: float
    dof: int
    noise_scale: float
    excitation_rad: np.ndarray
    gyro_noise: np.ndarray
    gravity: float
    temperature: TemperatureTerms | None = None
    warnings: tuple[str, ...] = field(default=())
    rate_table: Any = None


def _unit_rows(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=0, keepdims=True)


def _tangent_bases(a: np.ndarray) -> np.ndarray:
    """Two unit vectors orthogonal to each column of ``a`` (K, 2, 3); the helper axis is the least aligned one."""
    out = np.empty((a.shape[1], 2, 3))
    for k in range(a.shape[1]):
        helper = np.zeros(3)
        helper[int(np.argmin(np.abs(a[:, k])))] = 1.0
        e1 = np.cross(a[:, k], helper)
        e1 /= np.linalg.norm(e1)
        out[k, 0], out[k, 1] = e1, np.cross(a[:, k], e1)
    return out


class _GyroProblem:
    """The rotations between consecutive poses as a function of the gyro model and the nuisance parameters.

    ``nu`` = the accelerometer's 9 parameters, then the gyro bias coefficients (``design`` columns x 3 axes,
    row-major); ``design_rot`` is the bias design at every sample of the rotations.  ``stc`` (optional, in
    every method) = the gyro's relative scale change against temperature, ``(d, 3)`` flattened: coefficient
    ``j`` multiplies ``dtemp^(j+1)`` (``dtemp`` set by the caller: temperature minus the reference at every
    sample of the rotations).
    """

    def __init__(self, t, gyro, starts, stops, means, gravity, design_of):
        from senscal.imu._kernels import rotations_rk4

        self._rk4 = rotations_rk4
        self.gravity = gravity
        self.means = means
        k_n = starts.size
        idx, first, last = [], [], []
        pos = 0
        for k in range(k_n - 1):
            i0, i1 = int(stops[k]) - 1, int(starts[k + 1])
            idx.append(np.arange(i0, i1 + 1))
            first.append(pos)
            last.append(pos + i1 - i0)
            pos += i1 - i0 + 1
        self.idx = np.concatenate(idx)
        self.first = np.asarray(first, np.int64)
        self.last = np.asarray(last, np.int64)
        self.t = np.ascontiguousarray(t[self.idx])
        self.w = np.ascontiguousarray(gyro[:, self.idx])
        self.design = design_of(self.idx)
        self.n_steps = self.last - self.first
        self.duration = self.t[self.last] - self.t[self.first]
        self.bases = None
        self.white = None
        self.dtemp = None

    def directions(self, accel_theta, means=None):
        from senscal.triaxial.estimators import unpack

        m, b, _ = unpack("full", accel_theta, self.gravity)
        return _unit_rows(np.linalg.solve(m, (self.means if means is None else means) - b[:, None]))

    def rates(self, mg, coef, stc=None):
        b = (self.design @ np.asarray(coef, float).reshape(-1, 3)).T
        y = self.w - b
        if stc is not None and len(stc):
            c = np.asarray(stc, float).reshape(-1, 3)
            pw = self.dtemp[:, None] ** np.arange(1, c.shape[0] + 1)[None, :]
            y = y / (1.0 + (pw @ c).T)
        return np.ascontiguousarray(np.linalg.inv(mg) @ y)

    def rotations(self, mg, coef, stc=None):
        return self._rk4(self.rates(mg, coef, stc), self.t, self.first, self.last)

    def raw(self, mg, nu, means=None, stc=None):
        """Residuals (2 per rotation, rad) before whitening."""
        a = self.directions(nu[:9], means)
        rot = self.rotations(mg, nu[9:], stc)
        pred = np.einsum("kji,jk->ki", rot, a[:, :-1])  # R_k^T a_k
        if self.bases is None:
            self.bases = _tangent_bases(a)
        # The difference, not the prediction alone: the bases are fixed at the first call, and the measured
        # direction moves with the accelerometer's parameters.
        return np.einsum("kcj,kj->kc", self.bases[1:], pred - a[:, 1:].T).ravel()

    def angles_deg(self, mg, nu, means=None, stc=None):
        a = self.directions(nu[:9], means)
        rot = self.rotations(mg, nu[9:], stc)
        pred = np.einsum("kji,jk->ki", rot, a[:, :-1])
        c = np.clip(np.einsum("ki,ik->k", pred, a[:, 1:]), -1.0, 1.0)
        return np.degrees(np.arccos(c))

    def whitened(self, mg, nu, means=None, stc=None):
        r = self.raw(mg, nu, means, stc)
        return r if self.white is None else linalg.solve_triangular(self.white, r, lower=True)


def _pose_stats(t, gyro, temp, starts, stops):
    """Per pose: mean time, mean temperature (or None), gyro means (K, 3), counts; pooled gyro noise per axis."""
    k_n = starts.size
    tm = np.array([t[a:b].mean() for a, b in zip(starts, stops)])
    tk = None if temp is None else np.array([temp[a:b].mean() for a, b in zip(starts, stops)])
    mk = np.array([gyro[:, a:b].mean(axis=1) for a, b in zip(starts, stops)])
    nk = (stops - starts).astype(float)
    var = np.array([gyro[:, a:b].var(axis=1, ddof=1) * (b - a - 1) for a, b in zip(starts, stops)]).sum(axis=0)
    noise = np.sqrt(var / max(float(nk.sum() - k_n), 1.0))
    return tm, tk, mk, nk, noise


def _lag_one(gyro, starts, stops) -> np.ndarray:
    """Pooled lag-one correlation per axis of the still samples about a straight line per pose, shape (3,).

    About the line, not the mean: a gyro bias that follows a warm-up (or drifts) moves within a pose (10 K over
    a 20 s still start at 2e-4 rad/s per K is a per-sample noise's worth), and that trend is no colour: about
    the pose mean it raised the lag-one correlation past the 99.9 % point in ~10 % of white warm-up sessions.
    For white noise the line's two parameters bias the estimate by ``-E[x' M L x] / E[x' M x] =
    sum_k tr(P_k L) / sum_k (n_k - 2)`` (``P_k`` the pose's projection on ``1, t``, ``L`` the lag): added back.
    """
    num = np.zeros(3)
    den = np.zeros(3)
    tr_pl = 0.0
    dof = 0.0
    for a, b in zip(starts, stops):
        n = int(b - a)
        if n < 4:
            continue
        tc = np.arange(n, dtype=float) - 0.5 * (n - 1)
        stt = float(tc @ tc)
        seg = gyro[:, a:b]
        x = seg - seg.mean(axis=1, keepdims=True)
        x = x - np.outer(x @ tc / stt, tc)
        num += np.einsum("ij,ij->i", x[:, 1:], x[:, :-1])
        den += np.einsum("ij,ij->i", x, x)
        # tr(P L) = sum of P's first subdiagonal, P = 1 1'/n + t t'/t't.
        tr_pl += (n - 1) / n + float(tc[1:] @ tc[:-1]) / stt
        dof += n - 2
    return num / np.maximum(den, 1e-300) + tr_pl / max(dof, 1.0)


def _saturated_axes(gyro: np.ndarray, idx: np.ndarray) -> list[str]:
    """Axes whose readings sit at the record's extreme for >= 3 samples in a row during the rotations."""
    out = []
    for i in range(3):
        x = gyro[i, idx]
        for ext in (gyro[i].max(), gyro[i].min()):
            at = np.concatenate([[0], (x == ext).astype(np.int8), [0]])
            edges = np.flatnonzero(np.diff(at))
            if edges.size and np.max(edges[1::2] - edges[0::2]) >= 3:
                out.append("xyz"[i])
                break
    return out


def _accel_covariance(st, theta, gravity):
    """Covariance of the accelerometer's maximum-likelihood fit from the pose means' own noise.

    The fit weighs every pose mean alike, but a long still start averages far more samples than a short pose:
    ``s^2 (J^T J)^-1`` with one pooled ``s`` misstates that.  The sandwich with each mean's variance (its
    within-pose scatter over its sample count, along the gravity direction) does not; when the residuals exceed
    that noise (chi-square above its 99.9 % point: poses not still, coloured noise) the covariance is scaled by
    their excess.

    Returns
    -------
    (cov, chi2, dof, var)
        ``var``: each pose mean's variance along its gravity direction.
    """
    from senscal.triaxial.estimators import _jacobian, residuals, unpack

    def fun(th):
        return residuals("full", th, st.means, gravity)

    jac = _jacobian(fun, np.asarray(theta, float))
    r = fun(theta)
    m, b, _ = unpack("full", theta, gravity)
    mi = np.linalg.inv(m)
    a = _unit_rows(mi @ (st.means - b[:, None]))
    # The engine's residual is (|u| - g) / |M^-T n| (sensor units): its variance is w^T C w / |w|^2, w = M^-T n.
    w = mi.T @ a
    var = np.einsum("ik,ik->k", w, (st.stds ** 2 / st.counts[None, :]) * w) / np.einsum("ik,ik->k", w, w)
    var = np.maximum(var, 1e-300)
    bread = np.linalg.pinv(jac.T @ jac)
    cov = bread @ (jac.T * var[None, :]) @ jac @ bread
    chi2 = float(np.sum(r * r / var))
    dof = r.size - theta.size
    return cov, chi2, dof, var


def _derived(mvec: np.ndarray) -> np.ndarray:
    m = mvec.reshape(3, 3)
    rn = np.linalg.norm(m, axis=1)
    sc = np.sign(np.diag(m)) * rn
    ang = [math.asin(max(-1.0, min(1.0, m[i, j] / rn[i]))) for i, j in _PAIRS]
    return np.concatenate([sc, ang])


#: Highest degree of the gyro's scale against temperature tried.
MAX_SCALE_DEGREE = 2
#: Largest rate at which the gyro scale-against-temperature term is chosen in sessions without one (issue 27).
SCALE_LEVEL = 0.05


def _gyro_scale_degree(prob: _GyroProblem, nu: np.ndarray, s0: float, x0: np.ndarray,
                       max_degree: int = MAX_SCALE_DEGREE, folds: int = 5) -> tuple[int, list[float], list]:
    """Degree of the gyro's scale against temperature by ``folds``-fold cross-validation over the rotations.

    For each degree the gyro-only problem (accelerometer and bias fixed, ``prob.white`` the residuals' noise)
    is fitted on all rotations; each fold then leaves out every ``folds``-th rotation (interleaved in time, so
    each fold spans the temperature range), refits the rest in the linearisation about that solution (the
    problem is nearly linear there: one generalised least-squares step) and scores the left-out rotations'
    predicted residuals by their chi-square under their own noise covariance.  The degree it prefers is kept
    only while its chi-square drop against the degree below passes a likelihood-ratio test (``SCALE_LEVEL``
    split over the ``max_degree`` nested tests), so sessions without the term choose it at most that often.

    Returns
    -------
    (degree, scores, solutions)
        ``scores[d]``: held-out chi-square (NaN where the model has too many parameters for the rotations);
        ``solutions[d]``: the full-data fit's parameters (``M_g / s0`` row-major, then the coefficients).
    """
    n_r = prob.first.size
    sig = prob.white @ prob.white.T
    rot_of = np.repeat(np.arange(n_r), 2)
    scores, sols, chi2s = [], [], []
    for d in range(max_degree + 1):
        p = 9 + 3 * d
        if 2 * (n_r - -(-n_r // folds)) - p < 3:
            scores.append(math.nan)
            sols.append(None)
            chi2s.append(math.nan)
            continue

        def fun(th, d=d):
            return prob.whitened(th[:9].reshape(3, 3) * s0, nu, stc=th[9:])

        sol = optimize.least_squares(fun, np.concatenate([x0, np.zeros(3 * d)]), method="lm", x_scale="jac",
                                     xtol=1e-12, ftol=1e-12)
        sols.append(sol.x)
        chi2s.append(float(sol.fun @ sol.fun))
        r = prob.raw(sol.x[:9].reshape(3, 3) * s0, nu, stc=sol.x[9:])
        jr = prob.white @ sol.jac  # the raw residuals' Jacobian
        tot = 0.0
        for f in range(folds):
            hold = rot_of % folds == f
            keep = ~hold
            lk = linalg.cholesky(sig[np.ix_(keep, keep)], lower=True)
            a_ = linalg.solve_triangular(lk, jr[keep], lower=True)
            b_ = linalg.solve_triangular(lk, r[keep], lower=True)
            step = np.linalg.lstsq(a_, -b_, rcond=None)[0]
            e = r[hold] + jr[hold] @ step
            tot += float(e @ np.linalg.solve(sig[np.ix_(hold, hold)], e))
        scores.append(tot)
    finite = [s if math.isfinite(s) else math.inf for s in scores]
    best = int(np.argmin(finite))
    # Five-fold cross-validation over ~30 rotations prefers 3 extra parameters in ~20 % of sessions without
    # them even when its noise is exact (linearised Gaussian residuals under this covariance, simulated per
    # session): a degree it prefers is kept only while it lowers the chi-square significantly against the
    # degree below (likelihood ratio, chi-square with 3 dof at SCALE_LEVEL / max_degree each: over the
    # max_degree nested tests the false selection is then at most SCALE_LEVEL, Bonferroni).
    q_lr = stats.chi2.ppf(1.0 - SCALE_LEVEL / max_degree, 3)
    while best > 0 and not chi2s[best - 1] - chi2s[best] > q_lr:
        best -= 1
    # As for the accelerometer (senscal.imu.terms.accel_temperature_degree): a degree the noise rejects
    # (chi-square above its 99.9 % point) steps up while the next lowers the chi-square significantly.
    while (best < max_degree and math.isfinite(chi2s[best + 1])
           and chi2s[best] > stats.chi2.ppf(0.999, 2 * n_r - 9 - 3 * best)
           and chi2s[best] - chi2s[best + 1] > stats.chi2.ppf(0.999, 3)):
        best += 1
    return best, scores, sols


def _delta(fun, x, cov, step):
    f0 = fun(x)
    jac = np.empty((f0.size, x.size))
    for i in range(x.size):
        h = np.zeros_like(x)
        h[i] = step[i]
        jac[:, i] = (fun(x + h) - fun(x - h)) / (2 * step[i])
    return f0, jac @ cov @ jac.T


def calibrate_imu(t: np.ndarray, accel: np.ndarray, gyro: np.ndarray, *, gravity: float = 9.80665,
                  window_s: float = 1.0, min_pose_s: float = 1.0, init_s: float | None = None,
                  multiples: Sequence[float] = MULTIPLES, accel_unit: str = "", gyro_unit: str = "",
                  accel_channels: Sequence[str] = ("ax", "ay", "az"), source: str = "the recording",
                  temperature: np.ndarray | None = None, temp_unit: str = "", g_sensitivity: bool = False,
                  rate_table: Any = None) -> ImuResult:
    """Calibrate accelerometer and gyroscope from one multi-pose session.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times, s.
    accel : ndarray, shape (3, N)
        Accelerometer readings (any unit: counts or m/s^2).
    gyro : ndarray, shape (3, N)
        Gyroscope readings (counts, or rad/s).  The fitted matrix is reading per rad/s.
    gravity : float
        Local g in the accelerometer's calibrated unit (m/s^2).
    window_s, min_pose_s, init_s, multiples :
        Static detection (:func:`senscal.imu.static.sweep_static`).
    accel_unit, gyro_unit : str
        Units of the readings (for the reports).
    temperature : ndarray, shape (N,), optional
        The IMU's temperature: accelerometer bias and scale and gyro bias are then fitted against it
        (polynomials, degree chosen on held-out poses) at the poses' mean temperature, which replaces the gyro
        bias's time slope.
    temp_unit : str
        Its unit (K or degC: the swing check counts in it).
    g_sensitivity : bool
        Fit the gyro's sensitivity to specific force (3x3, from the static poses' bias against orientation).
    rate_table : senscal.io.ratetable.RateTable, optional
        Segments of known rate after the multi-pose session (:mod:`senscal.imu.ratetable`): the poses are taken
        from the samples before the table's first motion, and the segments join the gyro estimate.

    Returns
    -------
    ImuResult

    Raises
    ------
    InputError
        No static poses, a single pose, non-finite readings (one line, with the fix).
    """
    from senscal.triaxial import calibrate, fit_ml
    from senscal.triaxial.estimators import _jacobian, residuals, unpack

    t = np.asarray(t, float)
    accel = np.asarray(accel, float)
    gyro = np.asarray(gyro, float)
    temp = None if temperature is None else np.asarray(temperature, float)
    if temp is not None and (temp.shape != t.shape or not np.isfinite(temp).all()):
        raise InputError(f"{source}: the temperature channel must hold one finite value per sample")
    if accel.shape != gyro.shape or accel.ndim != 2 or accel.shape[0] != 3 or t.shape != accel.shape[1:]:
        raise InputError(f"IMU calibration needs three accelerometer and three gyroscope channels sample for "
                         f"sample, got shapes {accel.shape} and {gyro.shape}")
    if not (np.isfinite(accel).all() and np.isfinite(gyro).all() and np.isfinite(t).all()):
        raise DataError(f"{source}: the accelerometer or gyroscope channels hold non-finite values; remove the "
                        "damaged rows (or cut them away with --start/--stop)")
    if not (math.isfinite(gravity) and gravity > 0):
        raise InputError(f"--gravity must be the local g in m/s^2 (e.g. 9.80665), got {gravity!r}")
    dts = np.diff(t)
    if dts.size < 10 or not np.all(dts > 0):
        raise InputError(f"{source}: time must increase sample by sample and hold more than 10 samples")
    fs = 1.0 / float(np.median(dts))
    warnings: list[str] = []
    full = None
    if rate_table is not None:
        from senscal.imu.ratetable import pose_cut, segment_data

        segment_data(t, gyro, rate_table, source=source)  # bad segments refused before any fit
        full = (t, accel, gyro, temp)
        cut = pose_cut(t, gyro, rate_table)
        t, accel, gyro = t[:cut], accel[:, :cut], gyro[:, :cut]
        temp = None if temp is None else temp[:cut]

    def quick_rms(means):
        try:
            f = fit_ml(means, "full", field=gravity, with_covariance=False, tol=1e-8)
        except Exception:  # noqa: BLE001 - a degenerate pose set only loses the sweep's vote
            return math.nan
        r = residuals("full", f.values, means, gravity)
        return float(np.sqrt(np.mean(r * r)))

    sweep = sweep_static(accel, fs, quick_rms, window_s=window_s, min_pose_s=min_pose_s, init_s=init_s,
                         multiples=multiples, source=source, gyro=gyro)
    st = sweep.static
    warnings.extend(sweep.warnings)
    # The triaxial engine on the pose means: its diagnostics and warnings; the full model, field = g.
    ra = calibrate(st.means, field=gravity, method="ml", model="full", outlier_sigma=None, unit=accel_unit,
                   channels=tuple(accel_channels), time_terms=False)
    fa = fit_ml(st.means, "full", field=gravity, start=np.array([ra.value(n) for n in ACCEL_NAMES]))
    warnings.extend(ra.warnings)
    _, _, _, var_a = _accel_covariance(st, fa.values, gravity)
    sd_a = np.sqrt(var_a)
    tm, tk, mk, nk, gnoise = _pose_stats(t, gyro, temp, st.starts, st.stops)
    t_ref = float(np.sum(nk * tm) / nk.sum())

    # Temperature: the reference is the poses' sample-weighted mean temperature; the accelerometer's degree by
    # cross-validation over the poses, the gyro bias's by leave-one-pose-out prediction error.
    temp_ref = None
    deg_a, scores_a = 0, []
    dtk = np.zeros(st.n_poses)
    if temp is not None:
        temp_ref = float(np.sum(nk * tk) / nk.sum())
        dtk = tk - temp_ref
        swing = float(tk.max() - tk.min())
        # The channel's per-sample noise from successive differences within the poses: a warm-up's trend
        # within a long still start must not pass for noise (the scatter about the pose mean would count it).
        tvar = sum(float(np.sum(np.diff(temp[a:b]) ** 2)) for a, b in zip(st.starts, st.stops))
        tnoise = math.sqrt(tvar / (2.0 * max(float(nk.sum() - st.n_poses), 1.0)))
        # A swing within ten times the channel's own per-sample noise is no temperature change at all.
        if not swing > 10.0 * tnoise or swing == 0.0:
            raise InputError(f"{source}: the temperature channel spans {swing:.3g} {temp_unit or 'units'} over the "
                             f"static poses (its noise {tnoise:.3g}): no temperature terms can be fitted; drop "
                             "--temperature-channel, or record the session over a temperature ramp")
        if swing < MIN_SWING_K:
            warnings.append(named("temperature-swing-small", f"the static poses span only {swing:.3g} "
                                  f"{temp_unit or 'units'} of temperature (reference {temp_ref:.4g}); temperature "
                                  f"terms from less than {MIN_SWING_K:g} K extrapolate poorly: use the calibration "
                                  f"within {tk.min():.4g} .. {tk.max():.4g}"))
        deg_a, scores_a = accel_temperature_degree(st.means, sd_a, dtk, fa.values, gravity)
    n_tc = 6 * deg_a

    def means_c(tc):
        return accel_temperature_correct(st.means, dtk, tc, deg_a) if deg_a else st.means

    tc0 = np.zeros(n_tc)
    theta0 = np.asarray(fa.values, float)
    if deg_a:
        def accel_t(ph):
            return residuals("full", ph[:9], means_c(ph[9:]), gravity) / sd_a

        sol_a = optimize.least_squares(accel_t, np.concatenate([theta0, tc0]), method="lm", x_scale="jac")
        theta0, tc0 = sol_a.x[:9], sol_a.x[9:]
        ra = calibrate(means_c(tc0), field=gravity, method="ml", model="full", outlier_sigma=None, unit=accel_unit,
                       channels=tuple(accel_channels), time_terms=False)

    # Gyro bias over the static poses: constant, time slope (or temperature polynomial), optional g-sensitivity.
    ma0, ba0, _ = unpack("full", theta0, gravity)
    f_pose = np.linalg.solve(ma0, means_c(tc0) - ba0[:, None])

    # Coloured gyro noise: the pose means and the integrated rotations then scatter by the long-run variance,
    # (1 + r) / (1 - r) times the per-sample one for AR(1) noise of lag-one correlation r.  The pooled lag-one
    # correlation of the still samples about their pose means is N(0, 1/N) for white noise: beyond its 99.9 %
    # point the u carry the long-run variance and the departure is named.
    r1 = _lag_one(gyro, st.starts, st.stops)
    n_still = float(nk.sum())
    colour = np.abs(r1) > stats.norm.ppf(0.9995) / math.sqrt(n_still)
    lr = np.where(colour, (1 + np.clip(r1, -0.99, 0.99)) / (1 - np.clip(r1, -0.99, 0.99)), 1.0)
    gnoise_lr = gnoise * np.sqrt(lr)
    if np.any(colour):
        ax = ", ".join(f"{'xyz'[i]} {r1[i]:.2f}" for i in np.flatnonzero(colour))
        warnings.append(named("gyro-noise-coloured", f"the gyro's still samples are correlated sample to sample "
                              f"(lag-one correlation {ax}; white noise stays within "
                              f"{stats.norm.ppf(0.9995) / math.sqrt(n_still):.3f}): the u use the long-run "
                              "variance (AR(1)) instead of the per-sample one; check the gyro's filter settings"))

    def design(d, gs, slope=False):
        return BiasDesign(t_ref=t_ref, temp_ref=temp_ref, degree=d, g_sensitivity=gs, time_slope=slope)

    deg_g, scores_g, slope_g = 0, [], False
    if temp is not None:
        # The degree, and whether the bias also drifts in time besides following the temperature, both on
        # held-out poses (PRESS).
        best = None
        for sl in (False, True):
            d_, sc_ = press_degree(lambda d, sl=sl: design(d, g_sensitivity, sl).matrix(tm, tk, f_pose), mk, nk,
                                   gnoise_lr)
            v_ = sc_[d_] if math.isfinite(sc_[d_]) else math.inf
            if best is None or v_ < best[0]:
                best = (v_, d_, sc_, sl)
        _, deg_g, scores_g, slope_g = best
    bd = design(deg_g, g_sensitivity, slope_g)
    xk = bd.matrix(tm, tk, f_pose)
    coef, cov_ax, chi2_b, dof_b = fit_bias(xk, mk, nk, gnoise_lr)
    p_b = bd.n_cols
    u_coef = np.sqrt(np.clip(np.array([np.diag(c_) for c_ in cov_ax]).T, 0, None))  # (p, 3)
    if temp is None:
        s, u_s = coef[1], u_coef[1]
        if np.any(np.abs(s) > stats.norm.ppf(1 - 0.0005) * u_s):
            ax = ", ".join("xyz"[i] for i in np.flatnonzero(np.abs(s) > 3.29 * u_s))
            warnings.append(named("gyro-bias-drift", f"the gyro bias of axis {ax} changes during the session "
                                  f"({', '.join(f'{v:.3g}' for v in s)} per s); it is modelled linear in time over "
                                  "the static poses: keep poses short and the session steady"))
    if not g_sensitivity:
        # Does the bias depend on the orientation? F-test of three specific-force columns (robust to a noise
        # level the within-pose scatter misstates).
        x1 = design(deg_g, True, slope_g).matrix(tm, tk, f_pose)
        _, _, chi2_1, dof_1 = fit_bias(x1, mk, nk, gnoise_lr)
        if dof_1 > 0:
            fstat = (chi2_b - chi2_1) / 3.0 / (chi2_1 / dof_1)
            hit = np.flatnonzero(fstat > stats.f.ppf(0.999, 3, dof_1))
            if hit.size:
                warnings.append(named("gyro-g-sensitivity", f"the gyro bias of axis {', '.join('xyz'[i] for i in hit)} "
                                      "changes with the orientation (F-test at 99.9 %): the gyro is sensitive to "
                                      "acceleration; add --g-sensitivity to fit and remove it"))

    def design_rot(idx):
        f_rot = np.linalg.solve(ma0, accel[:, idx] - ba0[:, None])
        return bd.matrix(t[idx], None if temp is None else temp[idx], f_rot)

    prob = _GyroProblem(t, gyro, st.starts, st.stops, means_c(tc0), gravity, design_rot)
    nu = np.concatenate([theta0, coef.ravel()])
    cov_b = np.zeros((3 * p_b, 3 * p_b))
    for i in range(3):
        ix = np.arange(p_b) * 3 + i
        cov_b[np.ix_(ix, ix)] = cov_ax[i]

    # Nominal scale: a one-parameter search (readings may be counts of unknown scale).
    def cost(lg):
        return float(np.mean(prob.raw(10.0 ** lg * np.eye(3), nu) ** 2))

    grid = np.arange(-3.0, 6.0001, 0.1)
    lg0 = float(grid[int(np.argmin([cost(g) for g in grid]))])
    fine = lg0 + np.arange(-0.1, 0.1001, 0.01)
    s0 = float(10.0 ** fine[int(np.argmin([cost(g) for g in fine]))])
    nominal = 1.0 if gyro_unit.strip().lower() in ("rad/s", "rad s^-1", "rad/sec") else s0
    n_r = st.n_poses - 1
    # An axis the rotations barely turn about leaves a column of M_g undetermined: the fit then wanders along a
    # flat valley (minutes of CPU for nothing; the result is named gyro-axis-unexcited below).  Seen from the
    # nominal gyro before any fit, it caps the iterations and skips the temperature-scale search.
    exc0 = np.abs(prob.rates(s0 * np.eye(3), coef) * np.gradient(prob.t)[None, :]).sum(axis=1)
    weak = bool(np.any(exc0 < MIN_EXCITATION * exc0.max()))
    # (least_squares' "lm" counts evaluations outside its finite-difference Jacobians: about one per step.)
    nfev = (lambda n: 40) if weak else (lambda n: None)

    def gyro_only(th):
        return prob.whitened(th.reshape(3, 3) * s0, nu)

    sol = optimize.least_squares(gyro_only, np.eye(3).ravel(), method="lm", x_scale="jac", xtol=1e-12,
                                 ftol=1e-12, max_nfev=nfev(9))
    mg1 = sol.x.reshape(3, 3) * s0
    # The noise model at the first estimate: integrated gyro noise per rotation, pose-mean direction noise.
    a = prob.directions(nu[:9])
    rot = prob.rotations(mg1, coef)
    minv = np.linalg.inv(mg1)
    var_w = float(np.mean(np.diag(minv @ np.diag(gnoise_lr ** 2) @ minv.T)))
    dtm = prob.duration / np.maximum(prob.n_steps, 1)
    var_th = var_w * dtm ** 2 * (prob.n_steps + 1)
    ma, ba = ma0, ba0
    mai = np.linalg.inv(ma)
    cf = np.array([mai @ np.diag(st.stds[:, k] ** 2 / st.counts[k]) @ mai.T for k in range(st.n_poses)])
    fn = np.linalg.norm(mai @ (prob.means - ba[:, None]), axis=0)
    proj = np.array([np.eye(3) - np.outer(a[:, k], a[:, k]) for k in range(st.n_poses)])
    ca = np.array([proj[k] @ cf[k] @ proj[k] / fn[k] ** 2 for k in range(st.n_poses)])
    bases = prob.bases
    sig = np.zeros((2 * n_r, 2 * n_r))
    for k in range(n_r):
        p = bases[k + 1]
        blk = var_th[k] * np.eye(2) + p @ (rot[k].T @ ca[k] @ rot[k] + ca[k + 1]) @ p.T
        sig[2 * k:2 * k + 2, 2 * k:2 * k + 2] = blk
        if k + 1 < n_r:
            cross = -p @ ca[k + 1] @ rot[k + 1] @ bases[k + 2].T
            sig[2 * k:2 * k + 2, 2 * k + 2:2 * k + 4] = cross
            sig[2 * k + 2:2 * k + 4, 2 * k:2 * k + 2] = cross.T
    # The gyro bias (fixed in the fit) errs alike for all rotations: correlated residual noise J_b C_b J_b^T.
    u_b = np.sqrt(np.clip(np.diag(cov_b), 0, None))
    jb = np.empty((sig.shape[0], u_b.size))
    for i in range(u_b.size):
        h = np.zeros_like(nu)
        hi = u_b[i] if u_b[i] > 0 else 1e-12
        h[9 + i] = hi
        jb[:, i] = (prob.raw(mg1, nu + h) - prob.raw(mg1, nu - h)) / (2 * hi)
    prob.white = linalg.cholesky(sig + jb @ cov_b @ jb.T, lower=True)
    # The gyro's scale against temperature: its degree on held-out rotations (the rotations at different
    # temperatures are what determine it), then fitted jointly with the rest.
    deg_s, scores_s = 0, []
    x_g = sol.x
    if temp is not None and not weak:
        prob.dtemp = np.ascontiguousarray(temp[prob.idx] - temp_ref)
        # The cross-validation holds the accelerometer (and its temperature terms) at the magnitude fit, so that
        # fit's error moves every predicted gravity direction alike: a residual pattern a gyro scale against
        # temperature can partly mimic over a warm-up.  Its covariance, carried through the predicted
        # directions (J_a C_a J_a^T, as the bias's above), joins the noise the degrees are fitted, scored and
        # tested under (the likelihood-ratio guard's level holds only under it); the joint fit below frees those
        # parameters instead.  Alone it left the ~20 % false selection (issue 27: 11 of 52 sessions either way).
        def accel_w(ph):
            return residuals("full", ph[:9], means_c(ph[9:]), gravity) / sd_a

        th_a = np.concatenate([theta0, tc0])
        j_w = _jacobian(accel_w, th_a)
        r_w = accel_w(th_a)
        dof_w = r_w.size - th_a.size
        chi2_w = float(r_w @ r_w)
        cov_acc = np.linalg.pinv(j_w.T @ j_w)
        if dof_w > 0 and chi2_w > stats.chi2.ppf(0.999, dof_w):
            cov_acc = cov_acc * (chi2_w / dof_w)  # as the joint fit's inflation: poses scattering beyond noise
        u_acc = np.sqrt(np.clip(np.diag(cov_acc), 0, None))
        ja = np.empty((sig.shape[0], th_a.size))
        for i in range(th_a.size):
            h = np.zeros_like(th_a)
            h[i] = u_acc[i] if u_acc[i] > 0 else 1e-12
            nu_p, nu_m = nu.copy(), nu.copy()
            nu_p[:9] += h[:9]
            nu_m[:9] -= h[:9]
            ja[:, i] = (prob.raw(mg1, nu_p, means_c((th_a + h)[9:]))
                        - prob.raw(mg1, nu_m, means_c((th_a - h)[9:]))) / (2 * h[i])
        white_fit = prob.white
        prob.white = linalg.cholesky(white_fit @ white_fit.T + ja @ cov_acc @ ja.T, lower=True)
        try:
            deg_s, scores_s, sols_s = _gyro_scale_degree(prob, nu, s0, sol.x)
        finally:
            prob.white = white_fit
        x_g = sols_s[deg_s]
    n_sc = 3 * deg_s
    # Joint maximum likelihood: the pose means' magnitude (radial noise) and the rotations' predicted
    # directions (tangential noise) share the accelerometer's parameters (and its temperature terms); fitting
    # them together carries the accelerometer's error into the gyro's u with its correlations (a two-step fit
    # understated it).
    inflate = np.ones(2)

    def joint(phi):
        th, tc, mgv, stc = phi[:9], phi[9:9 + n_tc], phi[9 + n_tc:18 + n_tc], phi[18 + n_tc:]
        m = means_c(tc)
        ra_ = residuals("full", th, m, gravity) / sd_a
        rg_ = prob.whitened(mgv.reshape(3, 3) * s0, np.concatenate([th, nu[9:]]), m, stc)
        return np.concatenate([ra_ / inflate[0], rg_ / inflate[1]])

    phi = np.concatenate([theta0, tc0, x_g])
    n_a = st.n_poses
    dof_a, dof = n_a - 9 - n_tc, 2 * n_r - 9 - n_sc
    q_a, q_g = stats.chi2.ppf(0.999, max(dof_a, 1)), stats.chi2.ppf(0.999, dof)
    # A block whose residuals exceed its noise model (chi-square above the 99.9 % point) gets its noise scaled
    # by its excess and the fit is repeated: a misfitting gyro must not drag the accelerometer's parameters.
    for _ in range(4):
        sol = optimize.least_squares(joint, phi, method="lm", x_scale="jac", xtol=1e-12, ftol=1e-12,
                                     max_nfev=nfev(phi.size))
        if not np.all(np.isfinite(sol.x)):
            raise ConvergenceError("the gyroscope fit did not converge; check --gyro-channels and that the IMU "
                                   "rotates between still poses")
        phi = sol.x
        r = joint(phi)
        chi2_a = float(r[:n_a] @ r[:n_a]) * inflate[0] ** 2
        chi2 = float(r[n_a:] @ r[n_a:]) * inflate[1] ** 2
        new_inf = np.array([math.sqrt(chi2_a / dof_a) if dof_a > 0 and chi2_a > q_a else 1.0,
                            math.sqrt(chi2 / dof) if chi2 > q_g else 1.0])
        if np.allclose(new_inf, inflate, rtol=0.05):
            break
        inflate[:] = new_inf
    if inflate[0] > 1.0:
        warnings.append(named("accel-residuals-inconsistent", f"the static pose means scatter about |f| = g "
                              f"{inflate[0]:.2g} times more than their noise explains (chi2 {chi2_a:.1f} for "
                              f"{dof_a} dof): poses not still, coloured noise, or a drift; the u are scaled by it"))
    if inflate[1] > 1.0:
        # The noise model is too small (coloured gyro noise, poses not still, motion the integration cannot
        # follow): the residuals' own scatter sets the u, and the departure is named.
        warnings.append(named("gyro-residuals-inconsistent", f"the rotations between poses predict the next "
                              f"gravity direction {inflate[1]:.2g} times worse than the noise explains (chi2 "
                              f"{chi2:.1f} for {dof} dof): coloured gyro noise, fast or jerky rotations for the "
                              "sample rate, poses not still, or g-sensitivity; the u are scaled by it"))
    jac = sol.jac
    cov_phi = np.linalg.pinv(jac.T @ jac)
    ns = math.sqrt(chi2 / dof)
    cov_a = cov_phi[:9, :9]
    fa_values = phi[:9]
    tc_f = phi[9:9 + n_tc]
    cov_tc = cov_phi[9:9 + n_tc, 9:9 + n_tc]
    means_f = means_c(tc_f)
    nu = np.concatenate([fa_values, coef.ravel()])
    mg = phi[9 + n_tc:18 + n_tc].reshape(3, 3) * s0
    cov_m = cov_phi[9 + n_tc:18 + n_tc, 9 + n_tc:18 + n_tc] * s0 * s0
    stc_f = phi[18 + n_tc:]
    u_stc = np.sqrt(np.clip(np.diag(cov_phi)[18 + n_tc:], 0, None))
    u_m = np.sqrt(np.clip(np.diag(cov_m), 0, None))
    rt_fit = None
    if full is not None:
        from senscal.imu.ratetable import combine_rate_table, segment_data, temperature_powers

        tf, af, gf, tpf = full
        seg = segment_data(tf, gf, rate_table, gyro_noise=gnoise, source=source)
        d = np.array([bd.matrix(tf[ix], None if tpf is None else tpf[ix],
                                np.linalg.solve(ma0, af[:, ix] - ba0[:, None])).mean(axis=0) for ix in seg.index])
        cov_seg = np.array([d @ cov_ax[i] @ d.T for i in range(3)])
        # The segments read through the same temperature model as the poses (issue 27): M_g and the gyro's
        # scale against temperature enter with their joint covariance.
        jx = np.arange(9 + n_tc, phi.size)
        sc_ = np.concatenate([np.full(9, s0), np.ones(n_sc)])
        rt_fit = combine_rate_table(rate_table, seg, d @ coef, cov_seg, mg, cov_phi[np.ix_(jx, jx)] * np.outer(sc_, sc_),
                                    scale_tc=stc_f.reshape(deg_s, 3),
                                    temp_powers=temperature_powers(tpf, seg, temp_ref, deg_s))
        warnings.extend(rt_fit.warnings)
        mg, cov_m = rt_fit.matrix, rt_fit.covariance
        stc_f = rt_fit.scale_tc.ravel()
        u_stc = np.sqrt(np.clip(np.diag(rt_fit.scale_tc_covariance), 0, None))
        u_m = np.sqrt(np.clip(np.diag(cov_m), 0, None))
    der, cov_d = _delta(_derived, mg.ravel(), cov_m, np.maximum(u_m, 1e-12 * abs(s0)))
    u_d = np.sqrt(np.clip(np.diag(cov_d), 0, None))
    # Identifiability: how much each axis was turned about.
    rates = prob.rates(mg, coef, stc_f)
    dtv = np.gradient(prob.t)
    exc = np.abs(rates * dtv[None, :]).sum(axis=1)
    low = [i for i in range(3) if exc[i] < MIN_EXCITATION * exc.max()]
    if low:
        ax = ", ".join("xyz"[i] for i in low)
        warnings.append(named("gyro-axis-unexcited", f"the rotations turn little about axis {ax} "
                              f"({', '.join(f'{math.degrees(e):.0f}' for e in exc)} deg about x, y, z): its gyro "
                              f"scale and misalignment are poorly determined; add rotations about {ax}"))
    step = np.abs(rates[:, 1:] + rates[:, :-1]) * 0.5 * np.diff(prob.t)[None, :]
    if step.size and float(np.linalg.norm(step, axis=0).max()) > MAX_STEP_ANGLE:
        warnings.append(named("rotation-too-fast", f"the IMU turns up to {math.degrees(float(np.linalg.norm(step, axis=0).max())):.1f} deg "
                              f"per sample at {fs:.4g} Hz; the integration cannot follow: rotate slower or sample "
                              "faster"))
    sat = _saturated_axes(gyro, prob.idx)
    if sat:
        warnings.append(named("gyro-saturated", f"gyro axis {', '.join(sat)} sits at its extreme reading for 3 or "
                              "more samples in a row during the rotations: the rate was clipped and the rotation "
                              "under-counted; rotate slower or use a wider gyro range"))
    before = prob.angles_deg(nominal * np.eye(3), nu, means_f)
    after = prob.angles_deg(mg, nu, means_f, stc_f)
    gs = coef[-3:].T.copy() if g_sensitivity else None
    u_gs = u_coef[-3:].T.copy() if g_sensitivity else None
    tsl = slice(1, 1 + deg_g)
    gyro_cal = GyroCalibration(matrix=mg, covariance=cov_m, scale=der[:3], u_scale=u_d[:3], angles=der[3:],
                               u_angles=u_d[3:], bias=coef[0].copy(), u_bias=u_coef[0].copy(),
                               bias_rate=None if bd.slope_col is None else coef[bd.slope_col].copy(),
                               u_bias_rate=None if bd.slope_col is None else u_coef[bd.slope_col].copy(), t_ref=t_ref,
                               g_sensitivity=gs, u_g_sensitivity=u_gs)
    temperature = None
    if temp is not None:
        u_tc = np.sqrt(np.clip(np.diag(cov_tc), 0, None))
        temperature = TemperatureTerms(
            reference=temp_ref, unit=temp_unit, swing=float(tk.max() - tk.min()), low=float(tk.min()),
            high=float(tk.max()), degree_accel=deg_a, degree_gyro=deg_g,
            accel_bias=tc_f[:3 * deg_a].reshape(deg_a, 3), u_accel_bias=u_tc[:3 * deg_a].reshape(deg_a, 3),
            accel_scale=tc_f[3 * deg_a:].reshape(deg_a, 3), u_accel_scale=u_tc[3 * deg_a:].reshape(deg_a, 3),
            gyro_bias=coef[tsl].copy(), u_gyro_bias=u_coef[tsl].copy(),
            scores_accel=tuple(scores_a), scores_gyro=tuple(scores_g), degree_gyro_scale=deg_s,
            gyro_scale=stc_f.reshape(deg_s, 3), u_gyro_scale=u_stc.reshape(deg_s, 3),
            scores_gyro_scale=tuple(scores_s))
    return ImuResult(accelerometer=ra, accel_values=np.asarray(fa_values, float), accel_covariance=cov_a,
                     accel_chi2=chi2_a, accel_dof=dof_a, gyroscope=gyro_cal, poses=sweep,
                     residual_before_deg=before, residual_after_deg=after, nominal_scale=nominal, chi2=chi2, dof=dof,
                     noise_scale=ns, excitation_rad=exc, gyro_noise=gnoise, gravity=float(gravity),
                     temperature=temperature, warnings=tuple(dict.fromkeys(warnings)), rate_table=rt_fit)
