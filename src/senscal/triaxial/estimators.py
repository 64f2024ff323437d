"""Estimators of the three-axis error models.

* the seed's linearised 8-parameter model by direct least squares
  (:func:`fit_linear`) and by the seed's single linear neuron trained with
  the LMS rule (:func:`fit_lms`);
* the exact models (``full``, ``diagonal``, ``offsets``, ``planar``) by an
  algebraic quadric fit (:func:`fit_algebraic`) refined by maximum
  likelihood on the field magnitude (:func:`fit_ml`).

Every estimator returns a :class:`ModelFit`: parameter vector with names,
covariance (standard uncertainties, k=1), the calibration to apply, and the
residual noise.

References
----------
.. [1] "三轴磁敏传感器转向误差建模与辨识" (Steering-error modelling and
   identification of a three-axis magnetic sensor), seed 004, METHODS.md s. 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy import optimize

from senscal._result import ResultMixin
from senscal.errors import ConvergenceError, DegenerateGeometryError, InputError, TooFewSamplesError
from senscal.triaxial.models import LINEAR_NAMES, TriaxialCalibration, linear_features, sensor_matrix

__all__ = ["ModelFit", "param_names", "unpack", "fit_algebraic", "fit_ml", "fit_linear", "fit_lms",
           "residuals", "lms_scale"]

AXES = "xyz"
# Small-angle names of the off-diagonal elements M[0,1], M[0,2], M[1,2].
PAIR_ANGLE = {(0, 1): "gamma", (0, 2): "alpha", (1, 2): "beta"}


@dataclass(frozen=True)
class ModelFit(ResultMixin):
    """One estimator's answer.

    Attributes
    ----------
    model, method : str
    names : tuple of str
        Parameter names (angles in rad, gains dimensionless or sensor unit per
        field unit, offsets and field in their units).
    values : ndarray
    covariance : ndarray or None
        Parameter covariance (None when the estimator gives none: LMS).
    calibration : TriaxialCalibration
    noise : float
        Residual standard deviation of one sample, sensor units.
    field : float
        Field magnitude used or estimated (field units).
    field_estimated : bool
    n_used : int
    """

    model: str
    method: str
    names: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray | None
    calibration: TriaxialCalibration
    noise: float
    field: float
    field_estimated: bool
    n_used: int

    @property
    def uncertainties(self) -> np.ndarray:
        """Standard uncertainties (NaN where there is no covariance)."""
        if self.covariance is None:
            return np.full(len(self.names), np.nan)
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))


def param_names(model: str, field_known: bool, plane: tuple[int, int] | None = None) -> tuple[str, ...]:
    """Names of the free parameters of an exact model."""
    f = () if field_known else ("field",)
    if model == "full":
        k = ("Kx", "Ky", "Kz") if field_known else ("Kx", "Ky")
        return k + ("alpha", "beta", "gamma", "Bx", "By", "Bz") + f
    if model == "diagonal":
        k = ("Kx", "Ky", "Kz") if field_known else ("Kx", "Ky")
        return k + ("Bx", "By", "Bz") + f
    if model == "offsets":
        return (("K",) if field_known else ()) + ("Bx", "By", "Bz") + f
    if model == "planar":
        i, j = plane  # type: ignore[misc]
        return (f"K{AXES[i]}", PAIR_ANGLE[(i, j)], f"B{AXES[i]}", f"B{AXES[j]}", "plane_field")
    raise InputError(f"unknown model {model!r}; use one of full, diagonal, offsets, planar")


def unpack(model: str, theta: np.ndarray, field: float | None,
           plane: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """``(M, B, F)`` of an exact model from its parameter vector."""
    th = [float(v) for v in theta]
    known = field is not None
    if model == "full":
        if known:
            kx, ky, kz, a, b, g, bx, by, bz = th
            f = field
        else:
            kx, ky, a, b, g, bx, by, bz, f = th
            kz = 1.0
        return sensor_matrix(kx, ky, kz, a, b, g), np.array([bx, by, bz]), f
    if model == "diagonal":
        if known:
            kx, ky, kz, bx, by, bz = th
            f = field
        else:
            kx, ky, bx, by, bz, f = th
            kz = 1.0
        return np.diag([kx, ky, kz]), np.array([bx, by, bz]), f
    if model == "offsets":
        if known:
            k, bx, by, bz = th
            f = field
        else:
            bx, by, bz, f = th
            k = 1.0
        return k * np.eye(3), np.array([bx, by, bz]), f
    if model == "planar":
        i, j = plane  # type: ignore[misc]
        ki, ang, bi, bj, f = th
        m = np.eye(3)
        m[i, i], m[i, j] = ki * math.cos(ang), ki * math.sin(ang)
        b = np.zeros(3)
        b[i], b[j] = bi, bj
        return m, b, f
    raise InputError(f"unknown model {model!r}")


def _axes(model: str, plane: tuple[int, int] | None) -> list[int]:
    return list(plane) if model == "planar" else [0, 1, 2]


def residuals(model: str, theta: np.ndarray, h: np.ndarray, field: float | None,
              plane: tuple[int, int] | None = None) -> np.ndarray:
    """Magnitude residuals scaled to sensor noise (the maximum-likelihood residual).

    ``r = (|u| - F) / |M^-T n|`` with ``u = M^-1 (H_hat - B)``, ``n = u/|u|``:
    to first order its standard deviation is the per-axis sensor noise
    (isotropic Gaussian noise of standard deviation sigma on H_hat), so least
    squares on ``r`` is the maximum-likelihood estimate.
    """
    m, b, f = unpack(model, theta, field, plane)
    ax = _axes(model, plane)
    minv = np.linalg.inv(m[np.ix_(ax, ax)])
    u = minv @ (h[ax] - b[ax, None])
    r = np.sqrt(np.einsum("ij,ij->j", u, u))
    n = u / np.where(r > 0, r, 1.0)
    w = minv.T @ n  # M^-T n
    return (r - f) / np.sqrt(np.einsum("ij,ij->j", w, w))


def _jacobian(fun, theta: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian (for covariances; the optimiser has its own)."""
    theta = np.asarray(theta, float)
    cols = []
    for k in range(theta.size):
        step = 1e-6 * max(abs(theta[k]), 1e-3)
        tp, tm = theta.copy(), theta.copy()
        tp[k] += step
        tm[k] -= step
        cols.append((fun(tp) - fun(tm)) / (2 * step))
    return np.column_stack(cols)


def _covariance(jac: np.ndarray, rss: float, dof: int) -> np.ndarray:
    s2 = rss / max(dof, 1)
    return s2 * np.linalg.pinv(jac.T @ jac)


def _calibration(model: str, method: str, theta, field, plane, unit, channels) -> TriaxialCalibration:
    m, b, f = unpack(model, theta, field, plane)
    return TriaxialCalibration(model=model, method=method, matrix=m, offsets=b, field=float(f), unit=unit,
                               channels=tuple(channels), plane_axes=tuple(plane) if plane else None)


# -- algebraic (quadric) fits -------------------------------------------------

def _design(model: str, x: np.ndarray) -> np.ndarray:
    """Quadric regressors on normalised coordinates (target 1, or |x|^2 for the sphere)."""
    if model == "full":
        a, b, c = x
        return np.column_stack([a * a, b * b, c * c, 2 * b * c, 2 * a * c, 2 * a * b, 2 * a, 2 * b, 2 * c])
    if model == "diagonal":
        a, b, c = x
        return np.column_stack([a * a, b * b, c * c, 2 * a, 2 * b, 2 * c])
    if model == "offsets":
        a, b, c = x
        return np.column_stack([2 * a, 2 * b, 2 * c, np.ones_like(a)])
    a, b = x
    return np.column_stack([a * a, b * b, 2 * a * b, 2 * a, 2 * b])


def _coef_to_theta(model: str, coef: np.ndarray, mu: np.ndarray, s: float, field: float | None,
                   plane) -> np.ndarray:
    """Quadric coefficients (normalised coordinates) -> model parameters."""
    if model == "offsets":
        c0 = coef[:3]
        rad = math.sqrt(max(coef[3] + c0 @ c0, 0.0))
        if rad <= 0:
            raise DegenerateGeometryError("sphere fit failed: the points do not lie on a sphere")
        b = s * c0 + mu
        if field is None:
            return np.concatenate([b, [s * rad]])
        return np.concatenate([[s * rad / field], b])
    if model == "full":
        a_, b_, c_, f_, g_, h_, p, q, r = coef
        A = np.array([[a_, h_, g_], [h_, b_, f_], [g_, f_, c_]])
        lin = np.array([p, q, r])
    elif model == "diagonal":
        A = np.diag(coef[:3])
        lin = coef[3:6]
    else:
        a_, b_, h_, p, q = coef
        A = np.array([[a_, h_], [h_, b_]])
        lin = np.array([p, q])
    try:
        c0 = -np.linalg.solve(A, lin)
    except np.linalg.LinAlgError:
        raise DegenerateGeometryError("ellipsoid fit is singular: the orientations do not determine the "
                                      "model; collect more orientations or choose a simpler --model") from None
    k = 1.0 + c0 @ A @ c0
    try:
        L = np.linalg.cholesky(A / k)
    except np.linalg.LinAlgError:
        raise DegenerateGeometryError("the fitted quadric is not an ellipsoid (the data do not constrain all "
                                      "axes); collect more orientations or choose a simpler --model") from None
    mp = np.linalg.inv(L.T)  # upper triangular, unit-sphere -> normalised data
    b = s * c0 + mu
    if model == "planar":
        i, j = plane
        mm = s * mp  # maps a unit circle; in-plane field magnitude fixed by Kj = 1
        f = mm[1, 1]
        mm = mm / f
        ki = float(np.hypot(mm[0, 0], mm[0, 1]))
        return np.array([ki, math.atan2(mm[0, 1], mm[0, 0]), b[0], b[1], f])
    if field is None:
        f = s * mp[2, 2]  # Kz = 1: field expressed in Z-axis units
    else:
        f = field
    m = s * mp / f
    kx = float(np.linalg.norm(m[0]))
    ky = float(np.linalg.norm(m[1, 1:]))
    kz = float(m[2, 2])
    if model == "diagonal":
        k3 = [kx, ky, kz] if field is not None else [kx, ky]
        return np.array(k3 + list(b) + ([] if field is not None else [f]))
    a = math.atan2(m[0, 2], m[0, 0])
    bt = math.atan2(m[1, 2], m[1, 1])
    g = math.asin(max(-1.0, min(1.0, m[0, 1] / kx)))
    k3 = [kx, ky, kz] if field is not None else [kx, ky]
    return np.array(k3 + [a, bt, g] + list(b) + ([] if field is not None else [f]))


def fit_algebraic(h: np.ndarray, model: str = "full", *, field: float | None = None,
                  plane: tuple[int, int] | None = None, unit: str = "",
                  channels=("x", "y", "z")) -> ModelFit:
    """Algebraic (linear least-squares) quadric fit of an exact model.

    Parameters
    ----------
    h : ndarray, shape (3, N)
        Measured field, sensor units.
    model : {"full", "diagonal", "offsets", "planar"}
    field : float, optional
        Field magnitude (field units).  None: estimated, and the overall
        scale is then arbitrary (gains relative to the Z axis).
    plane : (int, int), optional
        The two axes of a planar rotation (``model="planar"``).

    Returns
    -------
    ModelFit
        Covariance from the coefficient covariance of the linear fit
        propagated through the coefficient -> parameter map (delta method).
    """
    ax = _axes(model, plane)
    x = np.asarray(h, float)[ax]
    mu = x.mean(axis=1)
    s = float(np.sqrt(np.mean(np.sum((x - mu[:, None]) ** 2, axis=0))))
    if not s > 0:
        raise DegenerateGeometryError("all samples are identical; rotate the sensor through many orientations")
    xn = (x - mu[:, None]) / s
    d = _design(model, xn)
    y = np.sum(xn * xn, axis=0) if model == "offsets" else np.ones(xn.shape[1])
    n, p = d.shape
    if n <= p:
        raise TooFewSamplesError(f"the {model} model has {p} algebraic coefficients and needs more than {p} "
                                 f"samples, got {n}; record more orientations")
    coef, rss, rank, sv = np.linalg.lstsq(d, y, rcond=None)
    if rank < p:
        raise DegenerateGeometryError(f"the orientations do not determine the {model} model (algebraic design "
                                      f"rank {rank} < {p}); collect more orientations or choose a simpler --model")
    res = y - d @ coef
    ccov = float(res @ res) / max(n - p, 1) * np.linalg.inv(d.T @ d)
    theta = _coef_to_theta(model, coef, mu, s, field, plane)
    # Delta method through the (smooth) coefficient -> parameter map.
    jac = _jacobian(lambda c: _coef_to_theta(model, c, mu, s, field, plane), coef)
    cov = jac @ ccov @ jac.T
    r = residuals(model, theta, np.asarray(h, float), field, plane)
    names = param_names(model, field is not None, plane)
    cal = _calibration(model, "ellipsoid", theta, field, plane, unit, channels)
    _, _, f = unpack(model, theta, field, plane)
    return ModelFit(model=model, method="ellipsoid", names=names, values=theta, covariance=cov, calibration=cal,
                    noise=float(np.sqrt(r @ r / max(r.size - len(names), 1))), field=float(f),
                    field_estimated=field is None or model == "planar", n_used=int(r.size))


def fit_ml(h: np.ndarray, model: str = "full", *, field: float | None = None,
           plane: tuple[int, int] | None = None, start: np.ndarray | None = None, unit: str = "",
           channels=("x", "y", "z"), prior: tuple[np.ndarray, np.ndarray] | None = None,
           tol: float = 1e-12, with_covariance: bool = True, max_nfev: int | None = None) -> ModelFit:
    """Maximum-likelihood fit on the field magnitude (Gauss-Newton / Levenberg-Marquardt).

    Parameters
    ----------
    h : ndarray, shape (3, N)
        Measured field, sensor units.
    model, field, plane :
        As :func:`fit_algebraic`.
    start : ndarray, optional
        Starting parameters; default the algebraic fit.
    prior : (ndarray, ndarray), optional
        ``(centre, weight)``: adds pseudo-residuals ``weight * (theta - centre)``
        (weight 0 = free).  Used to pin directions the data cannot determine
        so that the rest of the fit converges; those parameters must then not
        be reported as measured.
    tol : float
        Relative tolerance of the optimiser (looser for warm-started
        cross-validation fits, whose held-out residuals need far fewer digits).
    with_covariance : bool
        False skips the covariance (None), for fits used only to predict.
    max_nfev : int, optional
        Cap on residual evaluations; when given, reaching it is accepted (a
        prediction-only fit started at the answer does not need to finish
        crawling along a flat, pinned direction).

    Returns
    -------
    ModelFit
        Covariance ``s^2 (J^T J)^-1`` of the noise-scaled magnitude residuals
        at the optimum, ``s`` the residual standard deviation.
    """
    h = np.asarray(h, float)
    names = param_names(model, field is not None, plane)
    if h.shape[1] <= len(names):
        raise TooFewSamplesError(f"the {model} model has {len(names)} parameters and needs more than "
                                 f"{len(names)} samples, got {h.shape[1]}; record more orientations")
    theta0 = fit_algebraic(h, model, field=field, plane=plane).values if start is None else np.asarray(start, float)

    if prior is None:
        def fun(th):
            return residuals(model, th, h, field, plane)
    else:
        c0, wt = (np.asarray(a, float) for a in prior)

        def fun(th):
            return np.concatenate([residuals(model, th, h, field, plane), wt * (th - c0)])

    sol = optimize.least_squares(fun, theta0, method="lm", x_scale="jac", xtol=tol, ftol=tol, gtol=tol,
                                 max_nfev=max_nfev or 200 * (len(names) + 1))
    if not (sol.success or (max_nfev and sol.status == 0)) or not np.all(np.isfinite(sol.x)):
        raise ConvergenceError(f"maximum-likelihood fit of the {model} model did not converge ({sol.message}); "
                               "try --method ellipsoid or a simpler --model")
    theta = sol.x
    r = fun(theta)[: h.shape[1]]
    dof = r.size - len(names)
    cov = _covariance(_jacobian(fun, theta), float(r @ r), dof) if with_covariance else None
    _, _, f = unpack(model, theta, field, plane)
    cal = _calibration(model, "ml", theta, field, plane, unit, channels)
    return ModelFit(model=model, method="ml", names=names, values=theta, covariance=cov, calibration=cal,
                    noise=float(np.sqrt(r @ r / max(dof, 1))), field=float(f),
                    field_estimated=field is None or model == "planar", n_used=int(r.size))


# -- the seed's linearised model ------------------------------------------------

LINEAR_SUBSETS = {
    "full": LINEAR_NAMES,
    "diagonal": ("dKx", "dKy", "Bx", "By", "Bz"),
    "offsets": ("Bx", "By", "Bz"),
}


def lms_scale(h: np.ndarray, field: float | None) -> float:
    """Scale that makes the LMS features O(1): the field magnitude (or the median |H_hat|)."""
    return float(field) if field is not None else float(np.median(np.linalg.norm(h, axis=0)))


def _linear_problem(h: np.ndarray, field: float | None, model: str):
    """Scaled features, target, names, scale for the linearised model.

    Features are computed on ``h / s`` with ``s`` the field magnitude: the
    squared and cross terms and the linear terms are then all O(1), the
    weights dK, angles (rad) and B/s dimensionless and small, and the LMS
    step with learning rate 0.01 is stable (``lr * |X|^2 << 2``).
    """
    if model not in LINEAR_SUBSETS:
        raise InputError(f"the linearised (lms/linear) methods support --model full, diagonal or offsets, "
                         f"not {model!r}; use --method ml or ellipsoid for the planar model")
    s = lms_scale(h, field)
    hs = np.asarray(h, float) / s
    names = LINEAR_SUBSETS[model]
    idx = [LINEAR_NAMES.index(n) for n in names]
    x = linear_features(hs)[:, idx]
    y = 0.5 * np.sum(hs * hs, axis=0)
    if field is not None:
        y = y - 0.5
    else:
        # |H|^2 / 2 in scaled units becomes one more weight on a constant regressor.
        x = np.column_stack([x, np.ones(x.shape[0])])
        names = names + ("field",)
    return x, y, names, s


def _linear_result(w: np.ndarray, cov, names, s, field, model, method, x, y, unit, channels) -> ModelFit:
    vals = np.array(w, float)
    scale = np.ones(len(names))
    for k, n in enumerate(names):
        if n.startswith("B"):
            scale[k] = s
    f = field
    if field is None:
        c = vals[-1]
        if c <= 0:
            raise DegenerateGeometryError("linearised fit gives a negative field magnitude; the data do not "
                                          "fit the small-error model, use --method ml")
        f = s * math.sqrt(2 * c)
    out = vals * scale
    if field is None:
        out[-1] = f
    cov_out = None
    if cov is not None:
        jac = np.diag(scale)
        if field is None:
            jac[-1, -1] = s / math.sqrt(2 * vals[-1])
        cov_out = jac @ cov @ jac.T
    full = dict.fromkeys(LINEAR_NAMES, 0.0)
    full.update({n: v for n, v in zip(names, out)})
    m = np.array([[1 + full["dKx"], full["gamma"], full["alpha"]],
                  [0.0, 1 + full["dKy"], full["beta"]],
                  [0.0, 0.0, 1.0]])
    cal = TriaxialCalibration(model="linearised", method=method, matrix=m,
                              offsets=np.array([full["Bx"], full["By"], full["Bz"]]), field=float(f), unit=unit,
                              channels=tuple(channels))
    r = (y - x @ w) * s  # sensor units: e ~ |H| * dH / s^2 * s^2 / |H|
    dof = len(y) - len(names)
    return ModelFit(model=model, method=method, names=tuple(names), values=out, covariance=cov_out,
                    calibration=cal, noise=float(np.sqrt(r @ r / max(dof, 1))), field=float(f),
                    field_estimated=field is None, n_used=int(len(y)))


def fit_linear(h: np.ndarray, *, field: float | None = None, model: str = "full", unit: str = "",
               channels=("x", "y", "z")) -> ModelFit:
    """Direct least-squares solution of the seed's linearised model.

    Solves ``(|H_hat|^2 - |H|^2)/2 = X w`` with
    ``X = [Hx^2, Hy^2, HxHy, HxHz, HyHz, Hx, Hy, Hz]`` (measured components)
    for ``w = [dKx, dKy, gamma, alpha, beta, Bx, By, Bz]`` in one step.

    Parameters
    ----------
    h : ndarray, shape (3, N)
        Measured field, same unit as ``field``.
    field : float, optional
        Field magnitude; None adds a constant regressor for it.
    model : {"full", "diagonal", "offsets"}
        Which weights are free (the others are zero).

    Returns
    -------
    ModelFit
        Angles in rad, dK dimensionless, offsets in sensor units; ordinary
        least-squares covariance.
    """
    x, y, names, s = _linear_problem(h, field, model)
    if len(y) <= len(names):
        raise TooFewSamplesError(f"the linearised {model} model has {len(names)} weights and needs more than "
                                 f"{len(names)} samples, got {len(y)}")
    w = np.linalg.lstsq(x, y, rcond=None)[0]
    r = y - x @ w
    cov = _covariance(x, float(r @ r), len(y) - len(names))
    return _linear_result(w, cov, names, s, field, model, "linear", x, y, unit, channels)


@numba.njit(cache=True)
def _lms_kernel(x, y, w, lr, epochs):  # pragma: no cover - compiled
    n, p = x.shape
    for _ in range(epochs):
        for t in range(n):
            e = y[t]
            for k in range(p):
                e -= x[t, k] * w[k]
            for k in range(p):
                w[k] += lr * e * x[t, k]
    return w


def fit_lms(h: np.ndarray, *, field: float | None = None, model: str = "full", lr: float = 0.01,
            epochs: int = 50, unit: str = "", channels=("x", "y", "z")) -> ModelFit:
    """The seed's single linear neuron trained by the LMS rule.

    ``w <- w + lr * e(t) X(t)`` over the samples in recording order, for
    ``epochs`` passes, starting from ``w = 0``, on the scaled features of
    :func:`fit_linear` (features computed on ``H_hat / |H|``, so the seed's
    defaults lr = 0.01 and 50 epochs are stable).

    Returns
    -------
    ModelFit
        No covariance: LMS stops before convergence, so its answer's error is
        dominated by where it stopped, not by noise.  Compare it with
        :func:`fit_linear`.
    """
    if not (lr > 0 and math.isfinite(lr)):
        raise InputError(f"learning rate must be a positive number, got {lr!r}")
    if epochs < 1:
        raise InputError(f"epochs must be at least 1, got {epochs}")
    x, y, names, s = _linear_problem(h, field, model)
    if len(y) < 1:
        raise TooFewSamplesError("LMS needs at least one sample")
    w = _lms_kernel(np.ascontiguousarray(x), np.ascontiguousarray(y), np.zeros(x.shape[1]), float(lr), int(epochs))
    if not np.all(np.isfinite(w)):
        raise ConvergenceError(f"LMS diverged with learning rate {lr}; lower --lr")
    return _linear_result(w, None, names, s, field, model, "lms", x, y, unit, channels)
