"""Do fits on separate parts of a session agree within their stated uncertainties?

A calibration's u assumes the sensor and the field stayed the same while it
was turned.  Fitting the same model on the first and the second half of the
session (or on any blocks of it) and comparing the estimates against their
own covariances tests that: for independent blocks with a common truth the
difference ``d = theta_1 - theta_2`` has covariance ``C_1 + C_2`` and
``d^T (C_1 + C_2)^+ d`` is chi-square with as many degrees of freedom as the
rank of ``C_1 + C_2``.  The function is generic (arrays in, statistics out)
so that other jobs can use it; it lives here until a shared home exists.

References
----------
.. [1] G. C. Chow, "Tests of equality between sets of coefficients in two
   linear regressions", Econometrica 28 (1960) 591-605.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import stats

from senscal._result import ResultMixin

__all__ = ["BlockConsistency", "inconsistent_blocks", "ALPHA_CONSISTENCY"]

#: A false alarm in 1 % of consistent sessions: the chi-square 99 % quantile.
ALPHA_CONSISTENCY = 0.01


@dataclass(frozen=True)
class BlockConsistency(ResultMixin):
    """Agreement of per-block estimates.

    Attributes
    ----------
    chi2 : float
        Sum over consecutive block pairs of ``d^T (C_a + C_b)^+ d``.
    dof : int
        Degrees of freedom (ranks of the pair covariances, summed).
    p_value : float
        Chance of a chi-square this large when the blocks agree.
    inconsistent : bool
        ``p_value < alpha``.
    worst : str or None
        The parameter whose difference is largest in its own u.
    worst_z : float or None
        That difference in units of its standard uncertainty.
    alpha : float
    """

    chi2: float
    dof: int
    p_value: float
    inconsistent: bool
    worst: str | None
    worst_z: float | None
    alpha: float


def inconsistent_blocks(estimates: Sequence[np.ndarray], covariances: Sequence[np.ndarray],
                        names: Sequence[str], alpha: float = ALPHA_CONSISTENCY) -> BlockConsistency:
    """Chi-square test that estimates from consecutive blocks share one truth.

    Parameters
    ----------
    estimates : sequence of ndarray, shape (p,)
        One estimate per block, in time order, same parameters.
    covariances : sequence of ndarray, shape (p, p)
        Their covariances (the blocks' own stated u).
    names : sequence of str
        Parameter names (for ``worst``).
    alpha : float
        Significance level.

    Returns
    -------
    BlockConsistency
    """
    chi2 = 0.0
    dof = 0
    worst, worst_z = None, None
    for a in range(len(estimates) - 1):
        d = np.asarray(estimates[a + 1], float) - np.asarray(estimates[a], float)
        c = np.asarray(covariances[a], float) + np.asarray(covariances[a + 1], float)
        ok = np.isfinite(d) & np.all(np.isfinite(c), axis=1) & (np.diag(c) > 0)
        if not ok.any():
            continue
        d, c = d[ok], c[np.ix_(ok, ok)]
        # Scale to unit diagonal first: parameters in nT and in rad share one matrix.
        s = np.sqrt(np.diag(c))
        cs = c / np.outer(s, s)
        w, v = np.linalg.eigh(cs)
        keep = w > 1e-10 * w.max()
        proj = v[:, keep].T @ (d / s)
        chi2 += float(np.sum(proj ** 2 / w[keep]))
        dof += int(keep.sum())
        z = np.abs(d / s)
        k = int(np.argmax(z))
        if worst_z is None or z[k] > worst_z:
            worst, worst_z = [n for n, o in zip(names, ok) if o][k], float(z[k])
    p = float(stats.chi2.sf(chi2, dof)) if dof else math.nan
    return BlockConsistency(chi2=chi2, dof=dof, p_value=p, inconsistent=bool(dof and p < alpha), worst=worst,
                            worst_z=worst_z, alpha=alpha)
