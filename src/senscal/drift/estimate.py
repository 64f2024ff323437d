"""Maximum-likelihood estimation of the drift model's noise levels."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import minimize

from senscal._result import ResultMixin
from senscal.drift._blas import one_blas_thread
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


def _hessian_from_gradient(g: Callable[[np.ndarray], np.ndarray], x: np.ndarray, h: float,
                           g0: np.ndarray | None = None) -> np.ndarray:
    """Hessian by differences of an analytic gradient, symmetrised.

    With the gradient ``g0`` at ``x`` known (the search's last pass),
    forward differences: ``p`` passes, truncation error ``h/2`` times the
    third derivative (1e-4 relative at ``h = 1e-4`` on log levels, far below
    the curvature's own sampling error); otherwise central differences
    (``2p`` passes).
    """
    p = x.size
    H = np.empty((p, p))
    for i in range(p):
        e = np.zeros(p)
        e[i] = h
        if g0 is not None:
            H[:, i] = (g(x + e) - g0) / h
        else:
            H[:, i] = (g(x + e) - g(x - e)) / (2 * h)
    return 0.5 * (H + H.T)


def _scoring(nll_grad, info, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, T: int,
             max_iter: int = 12) -> np.ndarray:
    """Fisher scoring on the log levels, within bounds: a good start for the polish.

    Each step solves ``I d = g`` on the levels not held at a bound by their
    gradient (``I`` the expected information the score pass accumulates),
    halving it (at most three times) until the likelihood does not fall.
    Where the model is well determined it converges in a few passes where a
    quasi-Newton search from scratch needs tens (8 + 2 against 25 on the
    white-noise pair).  Stops after 12 steps, when the predicted gain ``g'
    d`` is below 1e-6 nat, when a step gains less than 1e-3 nat where less
    than 0.1 was predicted (a flat direction: a level that collapsed to zero,
    whose information vanishes with it) or when a step fails; the caller's
    L-BFGS-B then confirms (usually in one or two passes) or finishes the
    search.

    A secant (BFGS) correction of the information along each step converged
    faster on well-determined fits (a ramp's slope rate: 14 passes instead
    of 37) but took another path along the flat ridges of the coloured-noise
    model, where L-BFGS-B then stopped up to 1.3 nat lower (issue 30): the
    path is kept as it was, so the results are too.
    """
    theta = np.array(x0, dtype=float)
    f, gn = nll_grad(theta)
    I = info(theta)
    if f >= 1e10 or I is None:
        return theta
    for _ in range(max_iter):
        g = -gn * T  # gradient of ln L
        free = ~(((theta <= lo + 1e-9) & (g < 0)) | ((theta >= hi - 1e-9) & (g > 0)))
        if not free.any():
            break
        If = I[np.ix_(free, free)]
        # A level with (almost) no effect has no information: a tiny ridge keeps the step finite.
        ridge = 1e-9 * max(float(np.max(np.abs(np.diag(If)))), 1e-300)
        try:
            d = np.linalg.solve(If + ridge * np.eye(If.shape[0]), g[free])
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(d)):
            break
        pred = float(g[free] @ d)
        if pred < 1e-6:
            break
        # No step longer than a factor e^3 in a level: the quadratic model is local.
        d *= min(1.0, 3.0 / max(float(np.max(np.abs(d))), 1e-300))
        alpha, ok = 1.0, False
        for _ls in range(4):
            new = theta.copy()
            new[free] = np.clip(theta[free] + alpha * d, lo[free], hi[free])
            f2, g2 = nll_grad(new)
            if f2 < 1e10 and f2 <= f + 1e-12:
                ok = True
                break
            alpha *= 0.5
        if not ok:
            break
        gain = (f - f2) * T
        theta, f, gn, I = new, f2, g2, info(new)
        if I is None or (gain < 1e-3 and pred < 0.1):
            break
    return theta


def _search(nll, nll_grad, start, starts, names, lo, hi, T, info=None):
    """L-BFGS-B from every start (after Fisher scoring when ``info`` gives the information); the best result."""
    best = None
    for i, st in enumerate([start] + [np.log(np.array([s_[k] for k in names], dtype=float)) for s_ in starts]):
        st = np.clip(st, lo + 1e-3, hi - 1e-3)
        if i > 0 and nll(st) >= 1e10:
            continue
        if info is not None and nll_grad is not None:
            st = _scoring(nll_grad, info, st, lo, hi, T)
        # Stop when an iteration gains less than 1e-5 nat in total: far
        # below the likelihood's statistical resolution (~1 nat), and tight
        # enough that the curvature below is taken at the maximum.  Its
        # first point is the scoring's last pass (remembered, not rerun).
        if nll_grad is not None:
            r = minimize(nll_grad, st, jac=True, method="L-BFGS-B", bounds=list(zip(lo, hi)),
                         options={"maxiter": 300, "ftol": 1e-5 / T, "gtol": 1e-5 / T})
        else:
            r = minimize(nll, st, method="L-BFGS-B", bounds=list(zip(lo, hi)),
                         options={"eps": 1e-6, "maxiter": 300, "ftol": 1e-5 / T, "gtol": 1e-5 / T})
        if best is None or r.fun < best.fun:
            best = r
    return best


class _Passes:
    """The score passes of one search, remembered by point.

    The search, its polish and the curvature revisit points (the start, the
    last scoring step, the optimum); each pass over a long record costs as
    much as the whole step, so none is run twice.  The expected information
    is kept with its pass.
    """

    def __init__(self, score, levels, progress, p: int, T: int) -> None:
        self.score, self.levels, self.progress, self.p, self.T = score, levels, progress, p, T
        self.memo: dict[bytes, tuple[float, np.ndarray, np.ndarray | None]] = {}

    def __call__(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        key = np.asarray(theta, dtype=float).tobytes()
        hit = self.memo.get(key)
        if hit is None:
            if self.progress is not None:
                self.progress()
            try:
                ll, g = self.score(self.levels(theta), True)
                info = getattr(self.score, "info", None)
            except Exception:  # a level so extreme the model is invalid
                ll, g, info = np.nan, np.zeros(self.p), None
            g = np.asarray(g, dtype=float)
            if not (np.isfinite(ll) and np.all(np.isfinite(g))):
                hit = (1e10, np.zeros(self.p), None)
            else:
                hit = (-ll / self.T, -g / self.T, None if info is None else np.array(info, dtype=float))
            if len(self.memo) > 64:
                self.memo.clear()
            self.memo[key] = hit
        return hit[0], hit[1].copy()

    def info(self, theta: np.ndarray) -> np.ndarray | None:
        hit = self.memo.get(np.asarray(theta, dtype=float).tobytes())
        return None if hit is None else hit[2]

    def has(self, theta: np.ndarray) -> bool:
        return np.asarray(theta, dtype=float).tobytes() in self.memo


def estimate_levels(build: Callable[[Mapping[str, float]], StateSpaceModel], y: np.ndarray,
                    free: Mapping[str, float], given: Mapping[str, float], *,
                    starts: Sequence[Mapping[str, float]] = (),
                    progress: Callable[[], None] | None = None,
                    score: Callable[..., tuple[float, np.ndarray]] | None = None,
                    cov_out: dict | None = None,
                    bounds: Mapping[str, tuple[float, float]] | None = None,
                    curvature: bool = True) -> tuple[list[NoiseParameter], float]:
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
    score : callable, optional
        ``score(levels, grad) -> (ln L, d ln L / d ln(level) of the free
        levels in the order of free)`` (e.g.
        :class:`senscal.drift.likelihood.LevelLikelihood`): the search then
        uses the analytic gradient and the curvature comes from central
        differences of it; ``build`` is not called.
    cov_out : dict, optional
        Filled with ``names`` (the free levels) and ``cov``, the covariance
        of their natural logs (NaN rows for levels at a bound or not
        determined).
    bounds : mapping of str to (float, float), optional
        Search range of some free levels (instead of ``[1e-7, 1e4]`` times
        the start), in their units (e.g. a time constant no longer than the
        record).
    curvature : bool
        Compute the levels' uncertainties (``p`` more passes with
        ``score``); False (a model comparison needs only the maximised
        likelihood) leaves every ``std`` None and ``cov_out`` NaN.

    Returns
    -------
    parameters : list of NoiseParameter
        Free and given levels.
    loglik : float
        Maximised log-likelihood [nats].

    Notes
    -----
    The levels are searched on a log scale, bounded to ``[1e-7, 1e4]``
    times the first start, from every start: with ``score``, Fisher scoring
    and an L-BFGS-B polish; without it, L-BFGS-B.  Their standard
    uncertainties come from the inverse Hessian of the log-likelihood by
    the delta method.  With ``score`` one pass gives the gradient too, no
    pass is run twice (the start, the scoring's last point and the optimum
    are remembered), and the Hessian is the forward difference of the
    gradient from the optimum's own pass (``p`` passes instead of ``2p``).

    References
    ----------
    F. C. Schweppe, "Evaluation of likelihood functions for Gaussian
    signals", IEEE Trans. Inf. Theory 11 (1965) 61-70 (prediction-error
    decomposition); patent CN102564486A (noise covariances Q, R, G).
    """
    names = list(free)
    start = np.log(np.array([free[k] for k in names], dtype=float))
    lo, hi = start + _LOG_LO, start + _LOG_HI
    for i, k in enumerate(names):
        if bounds and k in bounds:
            lo[i], hi[i] = np.log(bounds[k][0]), np.log(bounds[k][1])
            start[i] = min(max(start[i], lo[i] + 1e-3), hi[i] - 1e-3)
    T = y.shape[-1]

    def levels(theta: np.ndarray) -> dict[str, float]:
        d = dict(given)
        d.update({k: float(np.exp(v)) for k, v in zip(names, theta)})
        return d

    def nll(theta: np.ndarray) -> float:
        if progress is not None:
            progress()
        try:
            ll = score(levels(theta), False)[0] if score is not None else log_likelihood(build(levels(theta)), y)
        except Exception:  # a level so extreme the model is invalid
            return 1e10
        return -ll / T if np.isfinite(ll) else 1e10

    passes = _Passes(score, levels, progress, len(names), T) if score is not None else None

    def nll_grad(theta: np.ndarray) -> tuple[float, np.ndarray]:
        return passes(theta)

    params: list[NoiseParameter] = [NoiseParameter(k, float(v), None, False) for k, v in given.items()]
    if cov_out is not None:
        cov_out["names"], cov_out["cov"] = [], np.zeros((0, 0))
    if not names:
        if score is not None:
            return params, float(score(dict(given), False)[0])
        return params, float(log_likelihood(build(dict(given)), y))
    if (nll_grad(start)[0] if score is not None else nll(start)) >= 1e10:
        raise ConvergenceError("the likelihood of the drift model is not finite at the starting noise levels; "
                               "check the data for outliers or give the noise levels in a model YAML")
    with one_blas_thread():
        res = _search(nll, nll_grad if score is not None else None, start, starts, names, lo, hi, T,
                      info=passes.info if score is not None and hasattr(score, "info") else None)
    if not np.all(np.isfinite(res.x)) or res.fun >= 1e10:
        raise ConvergenceError("the noise-level estimation failed (likelihood not finite); give the noise levels "
                               "in a model YAML or check the data for outliers")
    theta = res.x
    at_bound = (theta - lo < 1e-2) | (hi - theta < 1e-2)
    inner = ~at_bound
    cov = np.full((len(names), len(names)), np.nan)
    if inner.any() and curvature:
        idx = np.flatnonzero(inner)

        def nll_inner(t_in: np.ndarray) -> float:
            th = theta.copy()
            th[idx] = t_in
            return nll(th)

        if score is not None:
            def grad_inner(t_in: np.ndarray) -> np.ndarray:
                th = theta.copy()
                th[idx] = t_in
                return nll_grad(th)[1][idx]

            # The optimum's own pass gives the base point of forward differences.
            g0 = nll_grad(theta)[1][idx] if passes.has(theta) else None
            Hm = _hessian_from_gradient(grad_inner, theta[idx], 1e-4, g0) * T
        else:
            Hm = _hessian(nll_inner, theta[idx], 1e-3) * T
        # A direction the data do not curve (e.g. the time constant of a
        # coloured noise whose size went to zero) leaves the others
        # determined: drop the level most involved in it and invert the rest.
        sel = np.arange(idx.size)
        while sel.size:
            try:
                w, V = np.linalg.eigh(Hm[np.ix_(sel, sel)])
            except np.linalg.LinAlgError:
                break
            if w.min() > 1e-12 * max(abs(w).max(), 1e-300):
                cov[np.ix_(idx[sel], idx[sel])] = np.linalg.inv(Hm[np.ix_(sel, sel)])
                break
            sel = np.delete(sel, int(np.argmax(np.abs(V[:, int(np.argmin(w))]))))
    for i, k in enumerate(names):
        val = float(np.exp(theta[i]))
        u = val * np.sqrt(cov[i, i]) if np.isfinite(cov[i, i]) else None
        params.append(NoiseParameter(k, val, u, True, bool(at_bound[i])))
    if cov_out is not None:
        cov_out["names"], cov_out["cov"] = list(names), cov
    return params, float(-res.fun * T)
