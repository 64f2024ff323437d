"""Slow changes during a calibration session: an offset drift and a field step, chosen by evidence.

The exact models assume the offsets and the field stay put while the sensor
is turned.  Two departures are common and matter most when the orientations
follow time (a tumble from Z up to Z down): the offsets drift while the
sensor warms up, and the field steps when something nearby switches on.

* **offset drift**: ``B(t) = B + D tau`` with ``tau`` the session time
  scaled to [-1/2, 1/2] (reading order), so ``B`` is the mid-session offset
  and ``D = (dBx, dBy, dBz)`` the change over the session;
* **field step**: ``F(t) = F + dF ([t >= t_s] - f_after)``, ``f_after``
  the fraction of readings after the step, so that ``F`` is the
  session-average field (what a fit without the term estimates when the
  orientations are in random order) and ``dF`` the step; ``t_s`` is scanned
  over a grid of session fractions.

Each term is added when the data ask for it: an F test of the residual sum
of squares at 5 % (the drift, 3 degrees of freedom; a score test on the
model linearised at the static answer), and for the step the largest F
over the scanned times with a Bonferroni-corrected level (5 % / number of
scanned times); the adopted terms are then fitted by maximum likelihood.  Whether a term *could* hide in the parameters
(the orientations follow time, so a drift looks like an angle or a gain) is
computed from the design: a term at the size the test detects half of the
time (noncentrality ``lambda_50``) shifts parameter ``k`` by
``sqrt(lambda_50 (VIF_k - 1) / q)`` of its u, RMS over the directions of a
``q``-component term (at most ``sqrt(q)`` times that in the worst
direction), and for the step RMS over the scanned step times; ``VIF_k`` is
the variance inflation of ``k`` when the term is added.  Above 0.43 u (coverage of a k=2 interval below 93 %) the
calibration names it (``time-confounded``): a term not detected may have
biased the parameters, and a term detected rests on its assumed shape in
time (linear drift, one step), since the orientations alone cannot tell it
from the parameters.

References
----------
.. [1] H. Scheffe, *The analysis of variance*, Wiley 1959 (F test of nested
   linear models; noncentral chi-square power).
.. [2] D. W. K. Andrews, "Tests for parameter instability and structural
   change with unknown change point", Econometrica 61 (1993) 821-856 (the
   scan over change points; here made conservative by Bonferroni).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import optimize, stats

from senscal._result import ResultMixin
from senscal.triaxial.estimators import _axes, _covariance, _jacobian, unpack

__all__ = ["session_time", "residuals_with_terms", "TimeFit", "fit_with_terms", "term_evidence", "ALPHA_TERMS",
           "STEP_GRID", "BIAS_LIMIT_U", "lambda_half_power", "DRIFT_NAMES"]

ALPHA_TERMS = 0.05  # k = 2: a term is added when the data reject its absence at 5 %
STEP_GRID = tuple(np.round(np.linspace(0.1, 0.9, 17), 3))  # scanned step times (session fractions)
BIAS_LIMIT_U = 0.43  # an N(delta, 1) estimate's +-2 interval covers >= 93 % while |delta| <= 0.43
DRIFT_NAMES = ("dBx", "dBy", "dBz")


def session_time(idx: np.ndarray, n_total: int) -> np.ndarray:
    """Session time of readings ``idx`` of ``n_total`` (reading order) scaled to [-1/2, 1/2]."""
    return np.asarray(idx, float) / max(n_total - 1, 1) - 0.5


def residuals_with_terms(model: str, theta: np.ndarray, h: np.ndarray, tau: np.ndarray, field: float | None,
                         n_base: int, drift: bool, step: np.ndarray | None) -> np.ndarray:
    """Maximum-likelihood magnitude residuals (sensor units) of a 3-D model with time terms.

    ``theta`` is the base model's vector, then ``dBx, dBy, dBz`` (``drift``),
    then ``dF`` (``step``: the indicator of the readings after the step minus
    its mean, so the base field is the session average).
    """
    base = theta[:n_base]
    k = n_base
    m, b, f = unpack(model, base, field)
    hc = h
    if drift:
        hc = h - np.asarray(theta[k:k + 3], float)[:, None] * tau[None, :]
        k += 3
    minv = np.linalg.inv(m)
    u = minv @ (hc - b[:, None])
    r = np.sqrt(np.einsum("ij,ij->j", u, u))
    nn = u / np.where(r > 0, r, 1.0)
    w = minv.T @ nn
    ff = f + (theta[k] * step if step is not None else 0.0)
    return (r - ff) / np.sqrt(np.einsum("ij,ij->j", w, w))


@dataclass(frozen=True)
class TimeFit(ResultMixin):
    """A base model fitted with time terms.

    Attributes
    ----------
    values : ndarray
        Base parameters, then the terms.
    covariance : ndarray
    names : tuple of str
    rss : float
        Residual sum of squares (sensor units squared).
    dof : int
    """

    values: np.ndarray
    covariance: np.ndarray
    names: tuple[str, ...]
    rss: float
    dof: int


def fit_with_terms(model: str, h: np.ndarray, tau: np.ndarray, field: float | None, base_names, base_theta,
                   drift: bool, step: np.ndarray | None, prior: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> TimeFit:
    """Maximum likelihood of the base model plus the chosen terms, started at the static answer.

    ``prior`` (centre, weight) pins base directions the data cannot see, as
    :func:`senscal.triaxial.estimators.fit_ml` does; the terms are free.
    """
    n_base = len(base_names)
    names = tuple(base_names) + (DRIFT_NAMES if drift else ()) + (("dF",) if step is not None else ())
    theta0 = np.concatenate([np.asarray(base_theta, float), np.zeros(len(names) - n_base)])
    if prior is not None:
        c0 = np.concatenate([prior[0], np.zeros(len(names) - n_base)])
        wt = np.concatenate([prior[1], np.zeros(len(names) - n_base)])

        def fun(th):
            return np.concatenate([residuals_with_terms(model, th, h, tau, field, n_base, drift, step),
                                   wt * (th - c0)])
    else:
        def fun(th):
            return residuals_with_terms(model, th, h, tau, field, n_base, drift, step)

    sol = optimize.least_squares(fun, theta0, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10)
    th = sol.x
    r = residuals_with_terms(model, th, h, tau, field, n_base, drift, step)
    dof = r.size - len(names)
    cov = _covariance(_jacobian(fun, th), float(r @ r), dof)
    return TimeFit(values=th, covariance=cov, names=names, rss=float(r @ r), dof=int(dof))


def lambda_half_power(q: int, alpha: float) -> float:
    """Noncentrality at which a chi-square test with ``q`` dof at level ``alpha`` detects half of the time."""
    crit = stats.chi2.ppf(1.0 - alpha, q)
    return float(optimize.brentq(lambda lam: stats.ncx2.sf(crit, q, lam) - 0.5, 1e-9, 1e4))


def _project_out(j: np.ndarray, g: np.ndarray) -> np.ndarray:
    """``(I - P_J) g``: the part of the term columns the parameters cannot absorb."""
    q, r = np.linalg.qr(j)
    keep = np.abs(np.diag(r)) > 1e-10 * max(np.abs(np.diag(r)).max(), 1e-300)
    q = q[:, keep]
    return g - q @ (q.T @ g)


def _vif(j: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Variance inflation of each parameter (columns of ``j``) when the columns ``g`` are added."""
    a = j.T @ j
    full = np.block([[a, j.T @ g], [g.T @ j, g.T @ g]])
    try:
        v0 = np.diag(np.linalg.inv(a))
        v1 = np.diag(np.linalg.pinv(full))[: j.shape[1]]
    except np.linalg.LinAlgError:
        return np.full(j.shape[1], np.inf)
    return v1 / v0


def term_evidence(model: str, h: np.ndarray, tau: np.ndarray, field: float | None, base_names, theta,
                  report: set[str], prior=None, alpha: float = ALPHA_TERMS) -> dict[str, Any]:
    """Which time terms the data ask for, and which could hide in the parameters.

    Parameters
    ----------
    model : {"full", "diagonal", "offsets"}
    h : ndarray, shape (3, N)
        The readings fitted, in time order.
    tau : ndarray, shape (N,)
        Their session time (:func:`session_time`).
    base_names, theta :
        The static fit's parameter names and values.
    report : set of str
        Parameters the result quotes (confounding is judged on these).
    prior :
        As :func:`fit_with_terms`.

    Returns
    -------
    dict
        ``drift`` and ``step``: ``{"F", "p_value", "adopted", ...}``;
        ``fit``: the :class:`TimeFit` with the adopted terms (None: none);
        ``confounded``: per term, ``{"worst", "bias_in_u"}`` when a term at
        the edge of detection would bias a quoted parameter by more than
        :data:`BIAS_LIMIT_U` (the design cannot tell the term from it).
    """
    n_base = len(base_names)
    theta = np.asarray(theta, float)
    n = h.shape[1]
    r0 = residuals_with_terms(model, theta, h, tau, field, n_base, False, None)
    rss0 = float(r0 @ r0)
    jac = _jacobian(lambda th: residuals_with_terms(model, th, h, tau, field, n_base, False, None), theta)
    cols = [k for k, nm in enumerate(base_names) if nm in report]
    jr = jac[:, cols]
    # Term columns at the static answer.  The drift enters as an offset times tau, so d r / d(dB_k) is the
    # offset column times tau; d r / d(dF) is minus the step indicator over the residual's denominator.
    g_drift = jac[:, [list(base_names).index(f"B{a}") for a in "xyz"]] * tau[:, None]
    m_, b_, _ = unpack(model, theta[:n_base], field)
    minv = np.linalg.inv(m_)
    u_ = minv @ (h - b_[:, None])
    w_ = minv.T @ (u_ / np.linalg.norm(u_, axis=0))
    r_den = np.sqrt(np.einsum("ij,ij->j", w_, w_))

    def step_column(mask: np.ndarray) -> np.ndarray:
        return (-mask / r_den)[:, None]
    out: dict[str, Any] = {"alpha": alpha}
    dof_res = n - n_base
    # The tests are score (Lagrange multiplier) tests: the drop of the residual sum of squares when the term
    # columns, made orthogonal to the parameters' columns, are added to the linearised model at the static
    # answer; asymptotically the likelihood-ratio F test, without a refit per candidate.
    def f_test(g: np.ndarray) -> tuple[float, int, int]:
        gp = _project_out(jac, g)
        coef, *_ = np.linalg.lstsq(gp, r0, rcond=None)
        drop = float(r0 @ (gp @ coef))
        q = g.shape[1]
        dof2 = max(dof_res - q, 1)
        return drop / q / (max(rss0 - drop, 1e-300) / dof2), q, dof2

    # -- drift: F test, 3 dof -------------------------------------------------
    f_d, q_d, d2 = f_test(g_drift)
    p_d = float(stats.f.sf(f_d, q_d, d2))
    out["drift"] = {"F": float(f_d), "p_value": p_d, "adopted": bool(p_d < alpha)}
    # -- step: scan over the grid, Bonferroni over the scanned times -----------
    best = None
    k_grid = len(STEP_GRID)
    for frac in STEP_GRID:
        mask = _step_mask(tau, frac)
        if mask is None:
            continue
        f_s, _, d2 = f_test(step_column(mask))
        if best is None or f_s > best[0]:
            best = (f_s, frac, mask, d2)
    if best is not None:
        p_s = min(1.0, float(stats.f.sf(best[0], 1, best[3])) * k_grid)
        out["step"] = {"F": float(best[0]), "p_value": p_s, "adopted": bool(p_s < alpha),
                       "at_fraction": float(best[1])}
    else:
        out["step"] = {"F": None, "p_value": None, "adopted": False, "at_fraction": None}
    # -- the adopted terms together, by maximum likelihood ----------------------
    use_d = out["drift"]["adopted"]
    use_s = out["step"]["adopted"]
    out["fit"] = None
    out["step_mask"] = best[2] if use_s else None
    if use_d or use_s:
        out["fit"] = fit_with_terms(model, h, tau, field, base_names, theta, use_d, best[2] if use_s else None, prior)
    # -- could a term the test did not add hide in the quoted parameters? -------
    conf = {}
    if jr.shape[1]:
        vif = _vif(jr, g_drift)
        bias = np.sqrt(lambda_half_power(3, alpha) * np.clip(vif - 1.0, 0.0, None) / 3)
        conf["drift"] = _worst(bias, [base_names[k] for k in cols])
        # A step is equally likely at any scanned time: RMS of its bias over them.
        lam = lambda_half_power(1, alpha / k_grid)
        b2 = []
        for frac in STEP_GRID:
            mask = _step_mask(tau, frac)
            if mask is None:
                continue
            b2.append(lam * np.clip(_vif(jr, step_column(mask)) - 1.0, 0.0, None))
        if b2:
            conf["step"] = _worst(np.sqrt(np.mean(b2, axis=0)), [base_names[k] for k in cols])
    out["confounded"] = {k: v for k, v in conf.items() if v["bias_in_u"] > BIAS_LIMIT_U}
    out["bias_bound"] = conf
    out["dof_static"] = dof_res
    return out


def _step_mask(tau: np.ndarray, frac: float) -> np.ndarray | None:
    """Readings after a step at session fraction ``frac``, centred (mean 0), or None if a side has < 5."""
    mask = (tau >= frac - 0.5).astype(float)
    if mask.sum() < 5 or mask.sum() > mask.size - 5:
        return None
    return mask - mask.mean()


def _worst(bias: np.ndarray, names) -> dict[str, Any]:
    k = int(np.argmax(bias))
    return {"worst": names[k], "bias_in_u": float(bias[k])}
