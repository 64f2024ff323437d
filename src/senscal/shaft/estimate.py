"""Linear estimation with coloured noise: instrumental variables and a spectral sandwich covariance.

The gravity fit of :mod:`senscal.shaft.model` is linear in its parameters
once the angle is known, but its residual is not white: the encoder's
angular acceleration, which the fit subtracts, carries the Savitzky-Golay
differentiator's quantisation noise (large per sample, almost all of it far
above the rotation frequency), and real accelerometers add coloured noise.
What sets the uncertainty of a parameter is the noise density where its
regressor's energy is, so the covariance here is a sandwich whose middle is
``sum_f |W(f)|^2 S(f)`` with ``S`` the residual's smoothed periodogram [1]_,
not the residual variance times the inverse normal matrix.

References
----------
.. [1] Percival D. B., Walden A. T., "Spectral Analysis for Physical
   Applications", Cambridge University Press (1993), ch. 6: the smoothed
   (Daniell) periodogram and its leakage.
.. [2] Wooldridge J. M., "Econometric Analysis of Cross Section and Panel
   Data", MIT Press (2010), ch. 5: instrumental variables and their
   sandwich covariance.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.fft import next_fast_len, rfft

__all__ = ["iv_fit", "project_out", "spectral_meat", "synchronous_residual"]


def spectral_meat(w: np.ndarray, e: np.ndarray, half_width: int, exclude=()) -> np.ndarray:
    """Covariance of ``w^T e`` for stationary noise ``e`` with the residual's own, smoothed spectrum.

    ``Var(sum_j w_j e_j) = sum_f |W(f)|^2 S(f)``: each column picks the noise
    density where its own energy is (the gravity sinusoid at the rotation
    frequency, the offset at zero, the speed ripple at its frequencies).

    Parameters
    ----------
    w : ndarray, shape (N, p)
        Instruments (deterministic columns), in time order.
    e : ndarray, shape (N,)
        Residual on a uniform time base.
    half_width : int
        Half width, in frequency bins of ``1 / (N dt)``, of the Daniell
        (moving-average) smoother of the periodogram: the number of turns in
        the record puts the band at +/- the rotation frequency, about four
        degrees of freedom per turn.  Near zero frequency the band is shifted
        up so that it keeps its width.
    exclude : sequence of int
        Bins left out of every average: those the fit emptied (zero and the
        rotation frequency, with their neighbours), which would otherwise
        bias the density low.

    Returns
    -------
    ndarray, shape (p, p)
        Equals ``sigma^2 w^T w`` (in expectation) for white noise of variance ``sigma^2``.

    Notes
    -----
    The periodogram is not tapered: its leakage falls as the square of the
    distance in bins, so the encoder differentiator's noise (thousands of
    times the accelerometer's, tens of hertz up) adds well under 1 % at the
    rotation frequency of a record many turns long.  The columns should be
    tapered (see :func:`iv_fit`) so that they do not pick up that noise
    through their own truncation sidelobes.
    """
    n = e.size
    # Zero-padded to a length with small prime factors (a large prime factor makes the FFT tens of times
    # slower); the sums below stay exact, on a grid finer by ``scale``.
    nfft = next_fast_len(n, real=True)
    scale = nfft / n
    per = np.abs(rfft(e, nfft)) ** 2 / n  # variance per bin: sigma^2 for white noise
    nb = per.size
    use = np.ones(nb, dtype=bool)
    reach = int(round(scale)) - 1
    ex = np.asarray(sorted({int(round(k * scale)) + d for k in exclude for d in range(-reach, reach + 1)}), dtype=int)
    ex = ex[(ex >= 0) & (ex < nb)]
    use[ex] = False
    h = int(max(1, min(round(half_width * scale), (nb - 1) // 2)))
    cs = np.concatenate([[0.0], np.cumsum(np.where(use, per, 0.0))])
    cn = np.concatenate([[0], np.cumsum(use)])
    lo = np.clip(np.arange(nb) - h, 0, max(nb - 2 * h - 1, 0))
    hi = np.minimum(lo + 2 * h + 1, nb)
    cnt = cn[hi] - cn[lo]
    dens = (cs[hi] - cs[lo]) / np.maximum(cnt, 1)
    if np.any(cnt == 0):
        # A record too short to leave any bin in the band: the residual's mean square (white noise).
        dens[cnt == 0] = float(np.mean(per[use])) if use.any() else float(np.mean(per)) * nb / max(nb - len(ex), 1)
    wf = rfft(w, nfft, axis=0)
    c = np.full(nb, 2.0)
    c[0] = 1.0
    if nfft % 2 == 0:
        c[-1] = 1.0
    wk = wf * np.sqrt(c * dens / nfft)[:, None]
    return np.real(wk.conj().T @ wk)


def project_out(d: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Residual of the columns of ``v`` after least squares on the columns of ``d`` (Frisch-Waugh-Lovell)."""
    coef, *_ = np.linalg.lstsq(d, v, rcond=None)
    return v - d @ coef


def synchronous_residual(theta: np.ndarray, v: np.ndarray, bins: int, harmonics: int = 0) -> np.ndarray:
    """The columns of ``v`` minus their synchronous (angle-periodic) part.

    The first ``harmonics`` harmonics of the angle (and the mean) are
    removed by least squares, exactly; what is left of the periodic part
    (higher harmonics) by the synchronous average over the turns, in
    ``bins`` equal angle bins per turn: the least-squares projection onto
    piecewise-constant functions of the angle modulo one turn [3]_, which
    alone would leave a large smooth harmonic's variation within each bin.
    Whatever repeats every turn (gravity,
    ripple locked to the rotation and all its harmonics, an encoder's
    once-per-turn error, quantisation patterns that repeat with the angle)
    is removed, what varies from turn to turn stays.  With ``R`` turns the
    projection also takes ``1/R`` of white noise's variance.

    Parameters
    ----------
    theta : ndarray, shape (N,)
        Unwrapped angle, rad.
    v : ndarray, shape (N,) or (N, p)
    bins : int
        Angle bins per turn (>= 1).
    harmonics : int
        Harmonics of the angle removed by least squares first (0: the mean only).

    Returns
    -------
    ndarray, same shape as ``v``

    References
    ----------
    .. [3] McFadden P. D., "A revised model for the extraction of periodic
       waveforms by time domain averaging", Mechanical Systems and Signal
       Processing 1 (1987) 83-95.
    """
    k = np.arange(1, int(harmonics) + 1)
    phase = np.outer(theta, k)
    basis = np.column_stack([np.ones_like(theta), np.sin(phase), np.cos(phase)])
    v = project_out(basis, np.asarray(v, dtype=float))
    frac = np.mod(theta, 2.0 * math.pi) / (2.0 * math.pi)
    idx = np.minimum((frac * bins).astype(np.int64), bins - 1)
    cnt = np.bincount(idx, minlength=bins).astype(float)
    vv = np.asarray(v, dtype=float)
    cols = vv.reshape(vv.shape[0], -1)
    out = np.empty_like(cols)
    for j in range(cols.shape[1]):
        mean = np.bincount(idx, cols[:, j], minlength=bins) / np.maximum(cnt, 1.0)
        out[:, j] = cols[:, j] - mean[idx]
    return out.reshape(vv.shape)


def iv_fit(y: np.ndarray, m: np.ndarray, w: np.ndarray, half_width: int, exclude=(), taper=None):
    """Just-identified instrumental-variable fit with a block HAC covariance.

    Solves ``w^T diag(taper) (y - m b) = 0`` (each regressor in ``m`` has
    one instrument in ``w``; a regressor that is its own instrument is
    exogenous).

    Parameters
    ----------
    y : ndarray, shape (N,)
    m : ndarray, shape (N, p)
        Regressors.
    w : ndarray, shape (N, p)
        Instruments.
    half_width : int
    exclude : sequence of int
        Smoothing of the residual's periodogram (see :func:`spectral_meat`).
    taper : ndarray, shape (N,), optional
        Sample weights that go smoothly to zero at the record's ends (a
        Tukey window): the columns' spectra then have no truncation
        sidelobes to pick up noise far from their own frequencies.

    Returns
    -------
    coef : ndarray, shape (p,)
    cov : ndarray, shape (p, p)
        ``A^-1 S A^-T`` with ``A = w^T diag(taper) m`` and ``S`` the covariance of
        ``w^T e`` from the residual's spectrum (:func:`spectral_meat`).
    resid : ndarray, shape (N,)
    """
    wt = w if taper is None else w * np.asarray(taper, dtype=float)[:, None]
    a = wt.T @ m
    coef = np.linalg.solve(a, wt.T @ y)
    resid = y - m @ coef
    ainv = np.linalg.inv(a)
    cov = ainv @ spectral_meat(wt, resid, half_width, exclude) @ ainv.T
    return coef, cov, resid
