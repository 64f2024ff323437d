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

__all__ = ["GyroCalibration", "ImuResult", "calibrate_imu", "GYRO_ANGLES", "ACCEL_NAMES"]

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
        Reading at zero rate at ``t_ref`` (gyro units).
    bias_rate, u_bias_rate : ndarray, shape (3,)
        Bias change per second during the session.
    t_ref : float
        Time of ``bias`` (s from the recording's first sample): the weighted centre of the static poses.
    """

    matrix: np.ndarray
    covariance: np.ndarray
    scale: np.ndarray
    u_scale: np.ndarray
    angles: np.ndarray
    u_angles: np.ndarray
    bias: np.ndarray
    u_bias: np.ndarray
    bias_rate: np.ndarray
    u_bias_rate: np.ndarray
    t_ref: float

    def apply(self, gyro: np.ndarray) -> np.ndarray:
        """True rate in rad/s (accelerometer frame) from readings, shape (3, N)."""
        return np.linalg.solve(self.matrix, np.asarray(gyro, float) - self.bias[:, None])


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
    warnings : tuple of str
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
    warnings: tuple[str, ...] = field(default=())


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
    """The rotations between consecutive poses as a function of the gyro model and the nuisance parameters."""

    def __init__(self, t, gyro, starts, stops, means, gravity):
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
        self.n_steps = self.last - self.first
        self.duration = self.t[self.last] - self.t[self.first]
        self.bases = None
        self.white = None

    def directions(self, accel_theta):
        from senscal.triaxial.estimators import unpack

        m, b, _ = unpack("full", accel_theta, self.gravity)
        return _unit_rows(np.linalg.solve(m, self.means - b[:, None]))

    def rates(self, mg, bias_c, bias_s, t_ref):
        b = bias_c[:, None] + bias_s[:, None] * (self.t - t_ref)[None, :]
        return np.ascontiguousarray(np.linalg.inv(mg) @ (self.w - b))

    def rotations(self, mg, bias_c, bias_s, t_ref):
        return self._rk4(self.rates(mg, bias_c, bias_s, t_ref), self.t, self.first, self.last)

    def raw(self, mg, nu, t_ref):
        """Residuals (2 per rotation, rad) before whitening."""
        a = self.directions(nu[:9])
        rot = self.rotations(mg, nu[9:12], nu[12:15], t_ref)
        pred = np.einsum("kji,jk->ki", rot, a[:, :-1])  # R_k^T a_k
        if self.bases is None:
            self.bases = _tangent_bases(a)
        # The difference, not the prediction alone: the bases are fixed at the first call, and the measured
        # direction moves with the accelerometer's parameters.
        return np.einsum("kcj,kj->kc", self.bases[1:], pred - a[:, 1:].T).ravel()

    def angles_deg(self, mg, nu, t_ref):
        a = self.directions(nu[:9])
        rot = self.rotations(mg, nu[9:12], nu[12:15], t_ref)
        pred = np.einsum("kji,jk->ki", rot, a[:, :-1])
        c = np.clip(np.einsum("ki,ik->k", pred, a[:, 1:]), -1.0, 1.0)
        return np.degrees(np.arccos(c))

    def whitened(self, mg, nu, t_ref):
        r = self.raw(mg, nu, t_ref)
        return r if self.white is None else linalg.solve_triangular(self.white, r, lower=True)


def _bias_model(t, gyro, starts, stops):
    """Gyro bias constant + slope over the static poses (weighted by samples), per axis, with u."""
    k_n = starts.size
    tm = np.array([t[a:b].mean() for a, b in zip(starts, stops)])
    mk = np.array([gyro[:, a:b].mean(axis=1) for a, b in zip(starts, stops)])  # (K, 3)
    nk = (stops - starts).astype(float)
    var = np.array([gyro[:, a:b].var(axis=1, ddof=1) * (b - a - 1) for a, b in zip(starts, stops)]).sum(axis=0)
    noise = np.sqrt(var / max(float(nk.sum() - k_n), 1.0))
    t_ref = float(np.sum(nk * tm) / nk.sum())
    dt = tm - t_ref
    sw, swt2 = nk.sum(), np.sum(nk * dt * dt)
    c = (nk[:, None] * mk).sum(axis=0) / sw
    s = (nk[:, None] * dt[:, None] * mk).sum(axis=0) / swt2 if swt2 > 0 else np.zeros(3)
    resid = mk - c[None, :] - dt[:, None] * s[None, :]
    dof = k_n - 2
    # Window means scatter more than sigma/sqrt(n) under coloured noise: when their chi-square exceeds its
    # 99.9 % point their own scatter scales the u (always scaling up by max(1, chi2/dof) over-covered: 98 %).
    chi2 = (nk[:, None] * resid ** 2).sum(axis=0) / noise ** 2
    scale = (np.where(chi2 > stats.chi2.ppf(0.999, dof), np.sqrt(chi2 / dof), 1.0) if dof > 0
             else np.ones(3))
    u_c = noise / math.sqrt(sw) * scale
    u_s = (noise / math.sqrt(swt2) if swt2 > 0 else np.full(3, np.inf)) * scale
    return c, u_c, s, u_s, t_ref, noise, chi2, dof


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
                  accel_channels: Sequence[str] = ("ax", "ay", "az"), source: str = "the recording") -> ImuResult:
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

    Returns
    -------
    ImuResult

    Raises
    ------
    InputError
        No static poses, a single pose, non-finite readings (one line, with the fix).
    """
    from senscal.triaxial import calibrate, fit_ml
    from senscal.triaxial.estimators import residuals, unpack

    t = np.asarray(t, float)
    accel = np.asarray(accel, float)
    gyro = np.asarray(gyro, float)
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

    def quick_rms(means):
        try:
            f = fit_ml(means, "full", field=gravity, with_covariance=False, tol=1e-8)
        except Exception:  # noqa: BLE001 - a degenerate pose set only loses the sweep's vote
            return math.nan
        r = residuals("full", f.values, means, gravity)
        return float(np.sqrt(np.mean(r * r)))

    sweep = sweep_static(accel, fs, quick_rms, window_s=window_s, min_pose_s=min_pose_s, init_s=init_s,
                         multiples=multiples, source=source)
    st = sweep.static
    # The triaxial engine on the pose means: its diagnostics and warnings; the full model, field = g.
    ra = calibrate(st.means, field=gravity, method="ml", model="full", outlier_sigma=None, unit=accel_unit,
                   channels=tuple(accel_channels), time_terms=False)
    fa = fit_ml(st.means, "full", field=gravity, start=np.array([ra.value(n) for n in ACCEL_NAMES]))
    warnings.extend(ra.warnings)
    _, _, _, var_a = _accel_covariance(st, fa.values, gravity)

    c, u_c, s, u_s, t_ref, gnoise, _, _ = _bias_model(t, gyro, st.starts, st.stops)
    if np.any(np.abs(s) > stats.norm.ppf(1 - 0.0005) * u_s):
        ax = ", ".join("xyz"[i] for i in np.flatnonzero(np.abs(s) > 3.29 * u_s))
        warnings.append(named("gyro-bias-drift", f"the gyro bias of axis {ax} changes during the session "
                              f"({', '.join(f'{v:.3g}' for v in s)} per s); it is modelled linear in time over the "
                              "static poses: keep poses short and the session steady"))
    prob = _GyroProblem(t, gyro, st.starts, st.stops, st.means, gravity)
    nu = np.concatenate([fa.values, c, s])
    cov_b = np.diag(np.concatenate([u_c, u_s]) ** 2)

    # Nominal scale: a one-parameter search (readings may be counts of unknown scale).
    def cost(lg):
        return float(np.mean(prob.raw(10.0 ** lg * np.eye(3), nu, t_ref) ** 2))

    grid = np.arange(-3.0, 6.0001, 0.1)
    lg0 = float(grid[int(np.argmin([cost(g) for g in grid]))])
    fine = lg0 + np.arange(-0.1, 0.1001, 0.01)
    s0 = float(10.0 ** fine[int(np.argmin([cost(g) for g in fine]))])
    nominal = 1.0 if gyro_unit.strip().lower() in ("rad/s", "rad s^-1", "rad/sec") else s0
    n_r = st.n_poses - 1

    def gyro_only(th):
        return prob.whitened(th.reshape(3, 3) * s0, nu, t_ref)

    sol = optimize.least_squares(gyro_only, np.eye(3).ravel(), method="lm", x_scale="jac", xtol=1e-12,
                                 ftol=1e-12)
    mg1 = sol.x.reshape(3, 3) * s0
    # The noise model at the first estimate: integrated gyro noise per rotation, pose-mean direction noise.
    a = prob.directions(nu[:9])
    rot = prob.rotations(mg1, c, s, t_ref)
    minv = np.linalg.inv(mg1)
    var_w = float(np.mean(np.diag(minv @ np.diag(gnoise ** 2) @ minv.T)))
    dtm = prob.duration / np.maximum(prob.n_steps, 1)
    var_th = var_w * dtm ** 2 * (prob.n_steps + 1)
    ma, ba, _ = unpack("full", nu[:9], gravity)
    mai = np.linalg.inv(ma)
    cf = np.array([mai @ np.diag(st.stds[:, k] ** 2 / st.counts[k]) @ mai.T for k in range(st.n_poses)])
    fn = np.linalg.norm(mai @ (st.means - ba[:, None]), axis=0)
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
    u_b = np.sqrt(np.diag(cov_b))
    jb = np.empty((sig.shape[0], 6))
    for i in range(6):
        h = np.zeros_like(nu)
        hi = u_b[i] if u_b[i] > 0 else 1e-12
        h[9 + i] = hi
        jb[:, i] = (prob.raw(mg1, nu + h, t_ref) - prob.raw(mg1, nu - h, t_ref)) / (2 * hi)
    prob.white = linalg.cholesky(sig + jb @ cov_b @ jb.T, lower=True)
    # Joint maximum likelihood: the pose means' magnitude (radial noise) and the rotations' predicted
    # directions (tangential noise) share the accelerometer's parameters; fitting them together carries the
    # accelerometer's error into the gyro's u with its correlations (a two-step fit understated it).
    sd_a = np.sqrt(var_a)
    inflate = np.ones(2)

    def joint(phi):
        nu_j = np.concatenate([phi[:9], nu[9:]])
        ra_ = residuals("full", phi[:9], st.means, gravity) / sd_a
        rg_ = prob.whitened(phi[9:].reshape(3, 3) * s0, nu_j, t_ref)
        return np.concatenate([ra_ / inflate[0], rg_ / inflate[1]])

    phi = np.concatenate([fa.values, sol.x])
    n_a = st.n_poses
    dof_a, dof = n_a - 9, 2 * n_r - 9
    q_a, q_g = stats.chi2.ppf(0.999, max(dof_a, 1)), stats.chi2.ppf(0.999, dof)
    # A block whose residuals exceed its noise model (chi-square above the 99.9 % point) gets its noise scaled
    # by its excess and the fit is repeated: a misfitting gyro must not drag the accelerometer's parameters.
    for _ in range(4):
        sol = optimize.least_squares(joint, phi, method="lm", x_scale="jac", xtol=1e-12, ftol=1e-12)
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
    nu = np.concatenate([fa_values, c, s])
    mg = phi[9:].reshape(3, 3) * s0
    cov_m = cov_phi[9:, 9:] * s0 * s0
    der, cov_d = _delta(_derived, mg.ravel(), cov_m, np.maximum(np.sqrt(np.diag(cov_m)), 1e-12 * abs(s0)))
    u_d = np.sqrt(np.clip(np.diag(cov_d), 0, None))
    # Identifiability: how much each axis was turned about.
    rates = prob.rates(mg, c, s, t_ref)
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
    before = prob.angles_deg(nominal * np.eye(3), nu, t_ref)
    after = prob.angles_deg(mg, nu, t_ref)
    gyro_cal = GyroCalibration(matrix=mg, covariance=cov_m, scale=der[:3], u_scale=u_d[:3], angles=der[3:],
                               u_angles=u_d[3:], bias=c, u_bias=u_c, bias_rate=s, u_bias_rate=u_s, t_ref=t_ref)
    return ImuResult(accelerometer=ra, accel_values=np.asarray(fa_values, float), accel_covariance=cov_a,
                     accel_chi2=chi2_a, accel_dof=dof_a, gyroscope=gyro_cal, poses=sweep,
                     residual_before_deg=before, residual_after_deg=after, nominal_scale=nominal, chi2=chi2, dof=dof,
                     noise_scale=ns, excitation_rad=exc, gyro_noise=gnoise, gravity=float(gravity),
                     warnings=tuple(dict.fromkeys(warnings)))
