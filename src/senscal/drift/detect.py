"""Drift-onset detection: two-sided CUSUM on normalised innovations.

Under the no-drift model the standardised innovations are N(0, 1) and
white; a drift that starts at ``t0`` shifts their mean.  Page's CUSUM with
reference ``k`` (half the shift to detect, in standard deviations) raises an
alarm when a cumulative sum passes ``h``; the onset estimate is the last
time the alarming sum was zero.  ``h`` is set from the in-control average
run length (the inverse of the false-alarm rate a user gives), computed by
the Brook-Evans Markov-chain method rather than an asymptotic formula.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numba as nb
import numpy as np
from scipy.optimize import brentq
from scipy.special import ndtr  # the normal cdf without importing scipy.stats

from senscal._result import ResultMixin
from senscal.drift._blas import one_blas_thread
from senscal.errors import InputError

__all__ = ["CusumResult", "cusum_arl", "cusum_threshold", "cusum"]


def cusum_arl(h: float, k: float, shift: float = 0.0, *, n_states: int = 200) -> float:
    """Average run length of a one-sided CUSUM on N(shift, 1) samples [samples].

    Brook & Evans (1972): the statistic discretised into ``n_states``
    cells on ``[0, h)``; the ARL from state 0 solves ``(I - P) L = 1``.

    Parameters
    ----------
    h : float
        Decision threshold [standard deviations].
    k : float
        Reference value [standard deviations].
    shift : float
        Mean of the samples [standard deviations].

    Returns
    -------
    float
    """
    w = h / (n_states - 0.5)
    centers = np.arange(n_states) * w
    # From cell i, the next value z_i + x - k falls in cell j.
    edges_hi = (np.arange(n_states) + 0.5) * w
    edges_lo = np.concatenate([[-np.inf], edges_hi[:-1]])
    mu = centers[:, None] - k + shift
    P = ndtr(edges_hi[None, :] - mu) - ndtr(edges_lo[None, :] - mu)
    # One BLAS thread: a threaded solve of this small system took 0.7 s
    # instead of milliseconds on a loaded two-core machine (see senscal.drift._blas).
    with one_blas_thread():
        L = np.linalg.solve(np.eye(n_states) - P, np.ones(n_states))
    return float(L[0])


def cusum_threshold(arl0: float, k: float = 0.5) -> float:
    """Threshold h of a two-sided CUSUM with in-control ARL ``arl0`` [samples].

    Two one-sided charts that alarm independently: ``1/ARL = 2/ARL_one``.
    Solved to 1e-4 relative in ARL (cached: detection reruns it often).
    """
    return _threshold(float(f"{float(arl0):.6g}"), float(k))


@lru_cache(maxsize=256)
def _threshold(arl0: float, k: float) -> float:
    if not arl0 > 2.0:
        raise InputError(f"the in-control run length must exceed 2 samples (false-alarm rate too high), got {arl0:.3g}")
    target = 2.0 * arl0
    f = lambda h: np.log(cusum_arl(h, k)) - np.log(target)  # noqa: E731
    hi = 1.0
    while f(hi) < 0:
        hi *= 2.0
        if hi > 1e3:
            raise InputError(f"false-alarm rate too small to reach (run length {arl0:.3g} samples)")
    h = brentq(f, 1e-6, hi, xtol=1e-5, rtol=1e-5)
    # The ARL's linear solve rounds differently with another BLAS thread count (a Dask
    # worker against the command line); six digits, well inside the solver's tolerance,
    # make the threshold -- and the alarms it decides -- the same in every process.
    return float(f"{h:.6g}")


@nb.njit(cache=True)
def _cusum_kernel(z, k, h):
    """First alarm and onset of a two-sided CUSUM per row of z (NaN skipped)."""
    m, T = z.shape
    alarm = np.full(m, -1, dtype=np.int64)
    onset = np.full(m, -1, dtype=np.int64)
    sign = np.zeros(m, dtype=np.int64)
    for i in range(m):
        gp = 0.0
        gm = 0.0
        lastp = 0
        lastm = 0
        for t in range(T):
            x = z[i, t]
            if np.isnan(x):
                continue
            gp = max(0.0, gp + x - k)
            gm = max(0.0, gm - x - k)
            if gp == 0.0:
                lastp = t + 1
            if gm == 0.0:
                lastm = t + 1
            if gp > h or gm > h:
                alarm[i] = t
                if gp > h:
                    onset[i] = min(lastp, t)
                    sign[i] = 1
                else:
                    onset[i] = min(lastm, t)
                    sign[i] = -1
                break
    return alarm, onset, sign


@dataclass(frozen=True)
class CusumResult(ResultMixin):
    """First drift alarm per channel.

    Attributes
    ----------
    alarm : ndarray of int, (m,)
        Sample index of the alarm, -1 if none.
    onset : ndarray of int, (m,)
        Estimated first sample of the drift, -1 if none.
    direction : ndarray of int, (m,)
        +1 upward, -1 downward, 0 none.
    threshold : float
        h [standard deviations].
    reference : float
        k [standard deviations].
    arl0 : float
        In-control average run length [samples].
    """

    alarm: np.ndarray
    onset: np.ndarray
    direction: np.ndarray
    threshold: float
    reference: float
    arl0: float


def cusum(z: np.ndarray, arl0: float, *, k: float = 0.5) -> CusumResult:
    """Two-sided CUSUM drift detection on standardised residuals.

    Parameters
    ----------
    z : ndarray, (m, T) or (T,)
        Standardised innovations (N(0, 1) without drift) [1]; NaN skipped.
    arl0 : float
        Mean samples between false alarms per channel (``1 / rate``).
    k : float
        Reference value: half the mean shift to detect [standard deviations].

    Returns
    -------
    CusumResult

    References
    ----------
    E. S. Page, "Continuous inspection schemes", Biometrika 41 (1954)
    100-115; D. Brook, D. A. Evans, "An approach to the probability
    distribution of CUSUM run length", Biometrika 59 (1972) 539-549.
    """
    if not k > 0:
        raise InputError(f"the CUSUM reference k must be > 0, got {k}")
    z2 = np.atleast_2d(np.asarray(z, dtype=float))
    h = cusum_threshold(arl0, k)
    alarm, onset, sign = _cusum_kernel(np.ascontiguousarray(z2), float(k), h)
    return CusumResult(alarm=alarm, onset=onset, direction=sign, threshold=h, reference=float(k), arl0=float(arl0))
