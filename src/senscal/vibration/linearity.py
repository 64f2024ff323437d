"""Amplitude linearity: output amplitude against input amplitude at a fixed frequency.

References
----------
.. [1] Qin Chaojun, "Three-parameter cosine fit in double-centrifuge dynamic
   calibration of linear accelerometers" (seed 003; ``shared/METHODS.md``
   section 4, "Amplitude linearity").
.. [2] JCGM 100:2008 (GUM) G.3, G.4: Student t and Welch-Satterthwaite.
.. [3] JCGM 101:2008, propagation of distributions by Monte Carlo.
.. [4] R. T. Birge, Phys. Rev. 40, 207 (1932): internal and external consistency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import InputError, TooFewSamplesError
from senscal.vibration.budget import CONSISTENCY_ALPHA, coverage_factor

__all__ = ["LinearityPoint", "AmplitudeLinearity", "amplitude_linearity", "MC_DRAWS"]

# Monte-Carlo draws for the linearity statistic: its u is then known to
# 1/sqrt(2 M) = 1.6 % relative (JCGM 101 7.2), far below the 2 % coverage tolerance.
MC_DRAWS = 2000
_P_K2 = 0.9772498680518208  # one-sided probability of k = 2 (two-sided 95.45 %)


@dataclass(frozen=True)
class LinearityPoint(ResultMixin):
    """One input level.

    Attributes
    ----------
    source : str
    input_amplitude : float
        Peak input (m/s^2).
    output_amplitude, u_output_amplitude : float
        Fitted peak output and its standard uncertainty (output unit), the
        input level's type B part included when given.
    deviation : float
        ``output - (slope * input + intercept)`` (output unit).
    deviation_percent : float
        Deviation relative to the full-scale output, percent.
    """

    source: str
    input_amplitude: float
    output_amplitude: float
    u_output_amplitude: float
    deviation: float
    deviation_percent: float


@dataclass(frozen=True)
class AmplitudeLinearity(ResultMixin):
    """Best straight line through (input, output amplitude) and the linearity.

    Attributes
    ----------
    points : tuple of LinearityPoint
    slope, u_slope : float
        Sensitivity (output unit per m/s^2) and its standard uncertainty.
    intercept, u_intercept : float
        Output at zero input and its standard uncertainty.
    coverage_factor : float
        ``k`` of the slope's and intercept's expanded uncertainty: 2 when the
        per-point u carry them (many degrees of freedom), Student's t for
        ``dof`` when they come from the residuals.
    dof : float or None
        Degrees of freedom of ``u_slope`` / ``u_intercept`` (None: infinite).
    full_scale_output : float
        Largest output amplitude (output unit).
    linearity_percent : float
        Largest |deviation| relative to the full-scale output, percent.
    u_linearity_percent : float
        Standard uncertainty of ``linearity_percent`` by Monte Carlo (JCGM
        101): the outputs drawn from their u, the line refitted and the worst
        deviation taken again (leverage and the choice of the worst point
        included).
    linearity_bound_percent : float
        95.45 % quantile of the Monte-Carlo linearity: the upper bound to
        quote when the linearity is not resolved.
    linearity_resolved : bool or None
        True when the points depart from the straight line beyond their u
        (chi-square test at 1 %), False when they do not (the warning
        ``linearity-not-resolved``), None without per-point u.
    birge_ratio, chi2_p : float
        ``sqrt(chi2 / (n - 2))`` of the weighted straight-line residuals and
        the chi-square test's p value (nan without per-point u).
    weighted : bool
        True when the line is weighted by the per-point u.
    warnings : tuple of str
        Named warnings: ``linearity-not-resolved``, ``linearity-excess-scatter``.
    """

    points: tuple[LinearityPoint, ...]
    slope: float
    u_slope: float
    intercept: float
    u_intercept: float
    full_scale_output: float
    linearity_percent: float
    u_linearity_percent: float
    coverage_factor: float = 2.0
    dof: float | None = None
    linearity_bound_percent: float = math.nan
    linearity_resolved: bool | None = None
    birge_ratio: float = math.nan
    chi2_p: float = math.nan
    weighted: bool = False
    warnings: tuple[str, ...] = ()


def _wls(x: np.ndarray, y: np.ndarray, w: np.ndarray):
    """Weighted straight line: (beta, covariance (X'WX)^-1, residuals); y may be (M, n)."""
    X = np.column_stack([x, np.ones_like(x)])
    A = X.T @ (w[:, None] * X)
    cov = np.linalg.inv(A)  # 2 x 2, well conditioned after the scaling in the caller
    beta = (y * w) @ X @ cov.T
    res = y - beta @ X.T
    return beta, cov, res


def amplitude_linearity(input_amplitudes: Sequence[float], output_amplitudes: Sequence[float],
                        u_output: Sequence[float] | None = None,
                        sources: Sequence[str] | None = None, *, u_input: float = 0.0,
                        seed: int = 0) -> AmplitudeLinearity:
    """Fit the best straight line and report slope, intercept and linearity with honest u.

    The rule, stated once:

    * **Line.** The paper's best straight line (ordinary least squares):
      under a real nonlinearity a line weighted by noisy u_i would move with
      the noise in the weights (by several u for a 0.2 % cubic), so the
      measurand stays the unweighted line through the sensor's true outputs
      at these levels.  Its covariance uses the per-point u (the sine fits'
      u of each output amplitude, combined with ``u_input * output`` when
      the input levels have a random relative uncertainty) by the law of
      propagation, ``(X'X)^-1 X' diag(u^2) X (X'X)^-1``: exact for a
      linear estimator, and the u_i are known from records of hundreds of
      samples, so k = 2.  Without per-point u, u comes from the residuals
      with ``n - 2`` degrees of freedom and ``k = t_{95.45}(n - 2)`` (3.31
      for 5 levels).
    * **Consistency.** ``chi2`` of the residuals of the line weighted by
      ``1/u_i^2`` on ``n - 2`` dof (Birge ratio ``sqrt(chi2/(n-2))``).  ``p >= 0.01``: the points lie on a
      straight line within their u, so the linearity is *not resolved* and
      ``linearity-not-resolved`` says to quote the upper bound instead.
      ``p < 0.01``: the departure is real; it is a smooth nonlinearity when a
      cubic (quadratic for 4 levels) through the points is consistent with
      their u, and the slope and intercept keep their u (they estimate the
      best line through the sensor's true outputs at these levels).  When
      not even the cubic fits (``p < 0.01``, 5 or more levels), the levels
      scatter beyond their u (input levels not repeatable, not in
      ``u_input``): ``linearity-excess-scatter``, and the slope's and
      intercept's u are scaled by the Birge ratio with ``k = t(n - 2)``.
    * **Linearity.** Monte Carlo (JCGM 101, ``MC_DRAWS`` draws): outputs
      drawn from ``N(y_i, u_i^2)``, line refitted, worst deviation taken;
      ``u_linearity_percent`` is the standard deviation of the draws and
      ``linearity_bound_percent`` their 95.45 % quantile.

    Parameters
    ----------
    input_amplitudes : sequence of float
        Peak input accelerations in m/s^2 (at least 3 distinct levels).
    output_amplitudes : sequence of float
        Fitted peak outputs (output unit).
    u_output : sequence of float, optional
        Standard uncertainties of the outputs (output unit).
    sources : sequence of str, optional
        Labels (file names).
    u_input : float
        Relative standard uncertainty of each input level, independent from
        level to level (e.g. the main-arm speed set anew); a scale error
        common to all levels moves the slope only and belongs to the slope's
        type B budget, not here.
    seed : int
        Seed of the Monte-Carlo draws (results are reproducible).

    Returns
    -------
    AmplitudeLinearity

    References
    ----------
    .. [1] Qin Chaojun (seed 003): linearity is the largest deviation of the
       output amplitude from the best straight line, relative to the
       full-scale output.
    .. [2] JCGM 101:2008, 5.9 and 7.
    """
    from scipy.stats import chi2 as chi2_dist

    x = np.asarray(input_amplitudes, dtype=float)
    y = np.asarray(output_amplitudes, dtype=float)
    if x.shape != y.shape or x.ndim != 1:
        raise InputError(f"give one output amplitude per input amplitude (got {x.size} inputs, {y.size} outputs)")
    if np.unique(x).size < 3:
        raise TooFewSamplesError(f"a straight line with an uncertainty needs at least 3 distinct input amplitudes, got {np.unique(x).size}")
    if not np.all(np.isfinite(x)) or np.any(x <= 0):
        raise InputError("input amplitudes must be positive numbers (m/s^2)")
    if not np.all(np.isfinite(y)):
        raise InputError("output amplitudes must be finite numbers")
    if not (math.isfinite(u_input) and u_input >= 0):
        raise InputError(f"u_input must be a non-negative relative standard uncertainty, got {u_input!r}")
    n = x.size
    # Scale both axes to O(1) so (X'WX) is well conditioned whatever the units.
    sx, sy = float(np.max(np.abs(x))), float(np.max(np.abs(y))) or 1.0
    xs, ys = x / sx, y / sy
    weighted = u_output is not None
    warns: list[str] = []
    birge = p_line = math.nan
    resolved = None
    dof = None
    if weighted:
        u = np.asarray(u_output, dtype=float)
        if u.shape != y.shape or not np.all(np.isfinite(u)) or np.any(u <= 0):
            raise InputError("per-point output uncertainties must be positive finite numbers, one per level")
        u = np.hypot(u, u_input * np.abs(y))
        us = u / sy
        _, _, res_w = _wls(xs, ys, 1.0 / us**2)
        c2 = float(np.sum((res_w / us) ** 2))
        birge = math.sqrt(c2 / (n - 2)) if n > 2 else math.nan
        p_line = float(chi2_dist.sf(c2, n - 2)) if n > 2 else math.nan
        resolved = bool(p_line < CONSISTENCY_ALPHA)
        scale = 1.0
        if resolved and n >= 5:
            deg = 3 if n >= 5 else 2
            V = np.vander(xs, deg + 1)
            wsq = 1.0 / us
            coef, *_ = np.linalg.lstsq(V * wsq[:, None], ys * wsq, rcond=None)
            c2s = float(np.sum(((ys - V @ coef) / us) ** 2))
            p_smooth = float(chi2_dist.sf(c2s, n - deg - 1))
            if p_smooth < CONSISTENCY_ALPHA:
                scale, dof = max(1.0, birge), float(n - 2)
                warns.append(named("linearity-excess-scatter", (
                    f"the output amplitudes scatter about any smooth curve beyond their u (cubic fit chi2 p = "
                    f"{p_smooth:.2g}; straight-line Birge ratio {birge:.3g}): the input levels are not repeatable "
                    f"or their u is missing; slope and intercept u are scaled by the Birge ratio with k = "
                    f"{coverage_factor(n - 2):.3g} ({n - 2} dof) and the linearity contains the scatter; give "
                    "--u-input (random per level) or repeat the levels")))
        u_mc = u * scale
        beta, cov0, _ = _wls(xs, ys, np.ones(n))
        X = np.column_stack([xs, np.ones(n)])
        g = cov0 @ X.T  # rows: d(beta)/d(y)
        cov = (g * (us * scale) ** 2) @ g.T
    else:
        beta, cov, res = _wls(xs, ys, np.ones(n))
        s2 = float(np.sum(res**2)) / (n - 2)
        cov = cov * s2
        dof = float(n - 2)
        u_mc = np.full(n, math.sqrt(s2) * sy)
    k = coverage_factor(dof)
    slope, intercept = float(beta[0]) * sy / sx, float(beta[1]) * sy
    u_slope = math.sqrt(cov[0, 0]) * sy / sx
    u_intercept = math.sqrt(cov[1, 1]) * sy
    dev = y - (slope * x + intercept)
    fs = float(np.max(np.abs(y)))
    dev_pct = 100.0 * dev / fs
    lin = float(np.max(np.abs(dev_pct)))
    # JCGM 101: propagate the outputs' distributions through the whole statistic.
    rng = np.random.default_rng(seed)
    draws = y[None, :] + rng.standard_normal((MC_DRAWS, n)) * u_mc[None, :]
    _, _, res_mc = _wls(xs, draws / sy, np.ones(n))
    lin_mc = 100.0 * np.max(np.abs(res_mc), axis=1) * sy / np.max(np.abs(draws), axis=1)
    u_lin = float(np.std(lin_mc, ddof=1))
    bound = float(np.quantile(lin_mc, _P_K2))
    if resolved is False:
        warns.append(named("linearity-not-resolved", (
            f"the levels lie on a straight line within their u (chi2 p = {p_line:.2g}), so the largest deviation "
            f"{lin:.3g} % is noise, not the sensor's linearity; quote 'linearity below {bound:.2g} % of full "
            f"scale' (95 % Monte-Carlo bound), or reduce the noise / lengthen the records to resolve it")))
    labels = list(sources) if sources is not None else [""] * n
    u_pt = u if weighted else np.full(n, math.nan)
    pts = tuple(LinearityPoint(labels[i], float(x[i]), float(y[i]), float(u_pt[i]), float(dev[i]), float(dev_pct[i]))
                for i in range(n))
    return AmplitudeLinearity(pts, slope, u_slope, intercept, u_intercept, fs, lin, u_lin, k, dof, bound,
                              resolved, birge, p_line, weighted, tuple(warns))
