"""Maximum-likelihood estimation of the drift model's noise levels."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import minimize

from senscal._result import ResultMixin
from senscal.errors import ConvergenceError
from senscal.kalman import StateSpaceModel, log_likelihood

__all__ = ["NoiseParameter", "estimate_levels"]

# Search range of a level around its data-driven starting value, in
# natural-log units: from 1e-7 (practically absent) to 1e4 times the guess.
_LOG_LO, _LOG_HI = np.log(1e-7), np.log(1e4)


@dataclass(frozen=True)
class NoiseParameter(ResultMixin):
    """One noise level of the drift model.

    Attributes
    ----------
    name : str
        ``A_noise_std``, ``signal_rate_std``, ``B_bias_rate_std`` ...
    value : float
        Standard deviation [unit] or random-walk rate [unit/sqrt(s)].
    std : float or None
        Its standard uncertainty (k=1) from the curvature of the
        log-likelihood; None when given by the user or at a search bound.
    estimated : bool
        True when estimated from the data.
    at_bound : bool
        The estimate sits at the edge of the search range (e.g. a bias that
        does not drift: its rate is below what the record can resolve).
    """

    name: str
    value: float
    std: float | None
    estimated: bool
    at_bound: bool = False


def _hessian(f: Callable[[np.ndarray], float], x: np.ndarray, h: float) -> np.ndarray:
    """Central-difference Hessian."""
    p = x.size
    H = np.empty((p, p))
    f0 = f(x)
    E = np.eye(p) * h
    fp = np.array([f(x + E[i]) for i in range(p)])
    fm = np.array([f(x - E[i]) for i in range(p)])
    for i in range(p):
        H[i, i] = (fp[i] - 2 * f0 + fm[i]) / h**2
        for j in range(i):
            H[i, j] = H[j, i] = (f(x + E[i] + E[j]) - f(x + E[i] - E[j]) - f(x - E[i] + E[j])
                                 + f(x - E[i] - E[j])) / (4 * h**2)
    return H


def estimate_levels(build: Callable[[Mapping[str, float]], StateSpaceModel], y: np.ndarray,
                    free: Mapping[str, float], given: Mapping[str, float], *,
                    starts: Sequence[Mapping[str, float]] = (),
                    progress: Callable[[], None] | None = None) -> tuple[list[NoiseParameter], float]:
    """Maximise the Kalman log-likelihood over the free noise levels.

    Parameters
    ----------
    build : callable
        Levels (every name) -> StateSpaceModel.
    y : ndarray, (m, T)
        Measurements (NaN = missing).
    free : mapping
        Free levels and their starting values (> 0).
    given : mapping
        Fixed levels.
    starts : sequence of mapping, optional
        Further starting points (same keys as ``free``); the search runs from
        each and keeps the highest likelihood, so that one poor start (e.g.
        a noise level guessed from increments the quantity dominates) cannot
        trap it in a collapsed corner.
    progress : callable, optional
        Called after each likelihood evaluation.

    Returns
    -------
    parameters : list of NoiseParameter
        Free and given levels.
    loglik : float
        Maximised log-likelihood [nats].

    Notes
    -----
    The levels are searched on a log scale (L-BFGS-B, bounded to
    ``[1e-7, 1e4]`` times the first start, from every start); their standard uncertainties come from
    the inverse Hessian of the log-likelihood by the delta method.

    References
    ----------
    F. C. Schweppe, "Evaluation of likelihood functions for Gaussian
    signals", IEEE Trans. Inf. Theory 11 (1965) 61-70 (prediction-error
    decomposition); patent CN102564486A (noise covariances Q, R, G).
    """
    names = list(free)
    start = np.log(np.array([free[k] for k in names], dtype=float))
    lo, hi = start + _LOG_LO, start + _LOG_HI
    T = y.shape[-1]

    def levels(theta: np.ndarray) -> dict[str, float]:
        d = dict(given)
        d.update({k: float(np.exp(v)) for k, v in zip(names, theta)})
        return d

    def nll(theta: np.ndarray) -> float:
        if progress is not None:
            progress()
        try:
            ll = log_likelihood(build(levels(theta)), y)
        except Exception:  # a level so extreme the model is invalid
            return 1e10
        return -ll / T if np.isfinite(ll) else 1e10

    params: list[NoiseParameter] = [NoiseParameter(k, float(v), None, False) for k, v in given.items()]
    if not names:
        return params, float(log_likelihood(build(dict(given)), y))
    if nll(start) >= 1e10:
        raise ConvergenceError("the likelihood of the drift model is not finite at the starting noise levels; "
                               "check the data for outliers or give the noise levels in a model YAML")
    # Stop when an iteration gains less than a thousandth of a nat in total:
    # far below the likelihood's statistical resolution (~1 nat).
    best = None
    for st in [start] + [np.log(np.array([s_[k] for k in names], dtype=float)) for s_ in starts]:
        st = np.clip(st, lo + 1e-3, hi - 1e-3)
        if st is not start and nll(st) >= 1e10:
            continue
        # Stop when an iteration gains less than 1e-5 nat in total: far
        # below the likelihood's statistical resolution (~1 nat), and tight
        # enough that the curvature below is taken at the maximum.
        r = minimize(nll, st, method="L-BFGS-B", bounds=list(zip(lo, hi)),
                     options={"eps": 1e-6, "maxiter": 300, "ftol": 1e-5 / T, "gtol": 1e-5 / T})
        if best is None or r.fun < best.fun:
            best = r
    res = best
    if not np.all(np.isfinite(res.x)) or res.fun >= 1e10:
        raise ConvergenceError("the noise-level estimation failed (likelihood not finite); give the noise levels "
                               "in a model YAML or check the data for outliers")
    theta = res.x
    at_bound = (theta - lo < 1e-2) | (hi - theta < 1e-2)
    inner = ~at_bound
    cov = np.full((len(names), len(names)), np.nan)
    if inner.any():
        idx = np.flatnonzero(inner)

        def nll_inner(t_in: np.ndarray) -> float:
            th = theta.copy()
            th[idx] = t_in
            return nll(th)

        Hm = _hessian(nll_inner, theta[idx], 1e-3) * T
        try:
            w = np.linalg.eigvalsh(Hm)
            if w.min() > 0:
                cov[np.ix_(idx, idx)] = np.linalg.inv(Hm)
        except np.linalg.LinAlgError:
            pass
    for i, k in enumerate(names):
        val = float(np.exp(theta[i]))
        u = val * np.sqrt(cov[i, i]) if np.isfinite(cov[i, i]) else None
        params.append(NoiseParameter(k, val, u, True, bool(at_bound[i])))
    return params, float(-res.fun * T)
