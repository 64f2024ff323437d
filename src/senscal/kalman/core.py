"""Kalman filter, Rauch-Tung-Striebel and fixed-lag smoothers."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import DataError, InputError
from senscal.kalman import _kernels as K
from senscal.kalman.model import StateSpaceModel

__all__ = ["KalmanResult", "SmootherResult", "kalman_filter", "rts_smoother", "fixed_lag_smoother",
           "log_likelihood"]


@dataclass(frozen=True)
class KalmanResult(ResultMixin):
    """Output of :func:`kalman_filter` (time on the last axis).

    For S independent series every array gains a leading S axis and
    ``loglik`` / ``steady_state_from`` become arrays of length S.

    Attributes
    ----------
    x : ndarray, (n, T)
        Filtered mean E[x_t | y_0..y_t] [state units].
    P : ndarray, (n, n, T)
        Filtered covariance [state units^2].
    x_pred, P_pred : ndarray, (n, T) and (n, n, T)
        Predicted mean and covariance E[x_t | y_0..y_{t-1}] (at t = 0 the prior).
    innovation : ndarray, (m, T)
        ``y_t - H_t x_pred_t`` [measurement units]; NaN where y is missing.
    innovation_cov : ndarray, (m, m, T)
        ``H_t P_pred_t H_t^T + R_t`` [measurement units^2].
    normalized_innovation : ndarray, (m, T)
        Innovation whitened by the Cholesky factor of the covariance of the
        observed components (standard normal under the model) [1]; NaN where
        missing.
    loglik : float
        Gaussian log-likelihood of the accepted measurements [nats].
    rejected : ndarray of bool, (T,)
        Steps whose measurement failed the chi-square gate (not used).
    steady_state_from : int
        First step filtered with the frozen steady-state gain, -1 if none.
    """

    x: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    innovation: np.ndarray
    innovation_cov: np.ndarray
    normalized_innovation: np.ndarray
    loglik: Any
    rejected: np.ndarray
    steady_state_from: Any = -1

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each filtered state, (n, T) [state units]."""
        return np.sqrt(np.maximum(np.diagonal(self.P, axis1=-3, axis2=-2), 0.0)).swapaxes(-1, -2)


@dataclass(frozen=True)
class SmootherResult(ResultMixin):
    """Output of :func:`rts_smoother` / :func:`fixed_lag_smoother`.

    Attributes
    ----------
    x : ndarray, (n, T)
        Smoothed mean [state units].
    P : ndarray, (n, n, T)
        Smoothed covariance [state units^2].
    lag : int or None
        Samples of future data used (None: all, the full RTS smoother).
    """

    x: np.ndarray
    P: np.ndarray
    lag: int | None = None

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each smoothed state, (n, T) [state units]."""
        return np.sqrt(np.maximum(np.diagonal(self.P, axis1=-3, axis2=-2), 0.0)).swapaxes(-1, -2)


def _series(model: StateSpaceModel, y: Any, u: Any) -> tuple[np.ndarray, np.ndarray, bool]:
    """Time-major y (S, T, m) and u (S, T, k), and whether the input was batched."""
    m, k = model.n_measurements, model.n_inputs
    try:
        yy = np.array(y, dtype=float)
    except (TypeError, ValueError):
        raise InputError("y must be a numeric array of shape (m, T) or (S, m, T)") from None
    if yy.ndim == 1 and m == 1:
        yy = yy[None]
    if yy.ndim not in (2, 3) or yy.shape[-2] != m:
        raise InputError(f"y must have shape ({m}, T) or (S, {m}, T) for a model with {m} measurements, got {yy.shape}")
    batched = yy.ndim == 3
    if not batched:
        yy = yy[None]
    T = yy.shape[-1]
    if T < 1:
        raise DataError("y has no samples")
    if np.any(np.isinf(yy)):
        raise DataError("y contains inf; use NaN for a missing measurement")
    if model.n_steps is not None and model.n_steps != T:
        raise InputError(f"the model's per-step matrices cover {model.n_steps} steps but y has {T} samples")
    S = yy.shape[0]
    if k == 0:
        if u is not None and np.size(u) > 0:
            raise InputError("u was given but the model has no control matrix B")
        uu = np.zeros((S, T, 0))
    else:
        if u is None:
            raise InputError(f"the model has a control matrix B with {k} inputs: give u of shape ({k}, T)")
        uu = np.array(u, dtype=float)
        if uu.ndim == 1 and k == 1:
            uu = uu[None]
        if uu.ndim == 2:
            uu = np.broadcast_to(uu, (S,) + uu.shape)
        if uu.shape != (S, k, T):
            raise InputError(f"u must have shape ({k}, {T}) or ({S}, {k}, {T}), got {np.shape(u)}")
        if not np.all(np.isfinite(uu)):
            raise DataError("u contains NaN or inf; a control input cannot be missing")
        uu = np.ascontiguousarray(np.swapaxes(uu, -1, -2))
    return np.ascontiguousarray(np.swapaxes(yy, -1, -2)), uu, batched


def kalman_filter(model: StateSpaceModel, y: Any, u: Any = None, *, gate: float | None = None,
                  steady_state: bool = True) -> KalmanResult:
    """Kalman filter with Joseph-form updates, missing data and gating.

    Parameters
    ----------
    model : StateSpaceModel
    y : array_like, (m, T) or (S, m, T)
        Measurements [measurement units], time on the last axis; NaN marks a
        missing component (that part of the update is skipped).  A leading S
        axis filters S independent series with the same model.
    u : array_like, (k, T) or (S, k, T), optional
        Control input [control units]; ``u[:, t-1]`` drives the prediction
        of step t.  Required when the model has B.
    gate : float, optional
        Chi-square threshold on the normalised innovation squared (e.g.
        ``scipy.stats.chi2.ppf(0.999, m)``); a measurement beyond it is not
        used and its step is flagged in ``rejected``.
    steady_state : bool
        Freeze the gain once the covariance has converged (time-invariant
        model without missing data or gating only; otherwise ignored).  The
        result agrees with the exact recursion to rounding.

    Returns
    -------
    KalmanResult

    References
    ----------
    R. E. Kalman (1960); P. D. Joseph's stabilised covariance update, in
    R. S. Bucy and P. D. Joseph, *Filtering for Stochastic Processes with
    Applications to Guidance* (1968).  Seed: patent CN102564486A (step c).
    """
    if not isinstance(model, StateSpaceModel):
        raise InputError("model must be a senscal.kalman.StateSpaceModel")
    yy, uu, batched = _series(model, y, u)
    g = 0.0 if gate is None else float(gate)
    if gate is not None and not g > 0.0:
        raise InputError(f"gate must be a positive chi-square threshold, got {gate}")
    S, T, m = yy.shape
    n = model.n_states
    xf = np.empty((S, T, n))
    Pf = np.empty((S, T, n, n))
    xp = np.empty((S, T, n))
    Pp = np.empty((S, T, n, n))
    v = np.empty((S, T, m))
    Sc = np.empty((S, T, m, m))
    e = np.empty((S, T, m))
    rej = np.zeros((S, T), dtype=bool)
    ll = np.empty(S)
    ssf = np.empty(S, dtype=np.int64)
    for s in range(S):
        allow = bool(steady_state and not model.time_varying and gate is None and not np.isnan(yy[s]).any())
        ll[s], ssf[s] = K.filter_series(model._F, model._B, model._H, model._Q, model._R, model.x0, model.P0,
                                        yy[s], uu[s], g, allow, True, xf[s], Pf[s], xp[s], Pp[s], v[s], Sc[s],
                                        e[s], rej[s])
        if ssf[s] == -2:
            raise _not_pd()

    def tl(a: np.ndarray) -> np.ndarray:
        # time-major -> time-last views
        out = np.moveaxis(a, 1, -1)
        return out if batched else out[0]

    return KalmanResult(x=tl(xf), P=tl(Pf), x_pred=tl(xp), P_pred=tl(Pp), innovation=tl(v),
                        innovation_cov=tl(Sc), normalized_innovation=tl(e),
                        loglik=ll if batched else float(ll[0]), rejected=rej if batched else rej[0],
                        steady_state_from=ssf if batched else int(ssf[0]))


def _not_pd() -> DataError:
    return DataError("the innovation covariance lost positive definiteness; check that R is not negligible "
                     "against the signal's scale and that P0 is not absurdly large")


def log_likelihood(model: StateSpaceModel, y: Any, u: Any = None) -> float | np.ndarray:
    """Gaussian log-likelihood of the measurements under the model [nats].

    The same recursion as :func:`kalman_filter` without storing the states:
    the objective of maximum-likelihood noise estimation.

    Parameters
    ----------
    model : StateSpaceModel
    y : array_like, (m, T) or (S, m, T)
        Measurements, NaN = missing.
    u : array_like, optional
        Control input.

    Returns
    -------
    float, or ndarray (S,) for batched y
    """
    yy, uu, batched = _series(model, y, u)
    S, T, m = yy.shape
    n = model.n_states
    ll = np.empty(S)
    d1 = np.empty((1, n))
    d2 = np.empty((1, n, n))
    dm = np.empty((1, m))
    dmm = np.empty((1, m, m))
    rej = np.zeros(T, dtype=bool)
    for s in range(S):
        allow = bool(not model.time_varying and not np.isnan(yy[s]).any())
        ll[s], code = K.filter_series(model._F, model._B, model._H, model._Q, model._R, model.x0, model.P0,
                                      yy[s], uu[s], 0.0, allow, False, d1, d2, d1, d2, dm, dmm, dm, rej)
        if code == -2:
            raise _not_pd()
    return ll if batched else float(ll[0])


def _time_major(res: KalmanResult) -> tuple[np.ndarray, ...]:
    """(S, T, ...) contiguous arrays of a result (views when possible)."""
    batched = res.x.ndim == 3
    out = []
    for a in (res.x, res.P, res.x_pred, res.P_pred):
        b = a if batched else a[None]
        out.append(np.ascontiguousarray(np.moveaxis(b, -1, 1)))
    return tuple(out) + (batched,)


def _filtered(model: StateSpaceModel, res_or_y: Any, u: Any) -> KalmanResult:
    if isinstance(res_or_y, KalmanResult):
        return res_or_y
    return kalman_filter(model, res_or_y, u)


def _smooth(model: StateSpaceModel, res: KalmanResult, lag: int | None) -> SmootherResult:
    xf, Pf, xp, Pp, batched = _time_major(res)
    S, T, n = xf.shape
    if model.n_states != n:
        raise InputError(f"the filter result has {n} states but the model has {model.n_states}")
    xs = np.empty_like(xf)
    Ps = np.empty_like(Pf)
    for s in range(S):
        C = K.smoother_gains(model._F, Pf[s], Pp[s])
        if lag is None:
            K.rts_series(C, xf[s], Pf[s], xp[s], Pp[s], xs[s], Ps[s])
        else:
            K.fixed_lag_series(C, xf[s], Pf[s], xp[s], Pp[s], int(lag), xs[s], Ps[s])
    x = np.moveaxis(xs, 1, -1)
    P = np.moveaxis(Ps, 1, -1)
    return SmootherResult(x=x if batched else x[0], P=P if batched else P[0], lag=lag)


def rts_smoother(model: StateSpaceModel, res_or_y: Any, u: Any = None) -> SmootherResult:
    """Rauch-Tung-Striebel fixed-interval smoother.

    Parameters
    ----------
    model : StateSpaceModel
        The model the filter ran with.
    res_or_y : KalmanResult or array_like
        A filter result, or measurements (m, T) / (S, m, T) to filter first.
    u : array_like, optional
        Control input when ``res_or_y`` is measurements.

    Returns
    -------
    SmootherResult
        E[x_t | all data] and its covariance.

    References
    ----------
    H. E. Rauch, F. Tung, C. T. Striebel, "Maximum likelihood estimates of
    linear dynamic systems", AIAA J. 3 (1965) 1445-1450.
    """
    return _smooth(model, _filtered(model, res_or_y, u), None)


def fixed_lag_smoother(model: StateSpaceModel, res_or_y: Any, lag: int, u: Any = None) -> SmootherResult:
    """Fixed-lag smoother: the estimate at t uses data up to ``t + lag``.

    The time window of the drift patent (step b): a latency of ``lag``
    samples buys the estimate the smoothing of ``lag`` future samples.
    ``lag = 0`` is the filter; ``lag >= T - 1`` is the RTS smoother.  Cost
    O(T * lag * n^3).

    Parameters
    ----------
    model : StateSpaceModel
    res_or_y : KalmanResult or array_like
        A filter result, or measurements to filter first.
    lag : int
        Window length L in samples (>= 0).
    u : array_like, optional
        Control input when ``res_or_y`` is measurements.

    Returns
    -------
    SmootherResult

    References
    ----------
    Patent CN102564486A (Shanghai Dianji University, 2012), step b;
    B. D. O. Anderson, J. B. Moore, *Optimal Filtering* (1979), ch. 7.
    """
    if int(lag) != lag or lag < 0:
        raise InputError(f"lag must be a whole number of samples >= 0, got {lag}")
    return _smooth(model, _filtered(model, res_or_y, u), int(lag))
