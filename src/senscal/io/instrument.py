"""What the acquisition chain did to a channel: clipping and quantisation (shared by every job).

A recording's samples carry the marks of the analogue-to-digital converter
that took them: a saturated input piles samples up at the ends of the range
(clipping), and a finite resolution puts every sample on a grid of levels one
LSB apart (quantisation).  Neither is noise: clipping is a bias no noise model
covers, and a quantiser that the analogue noise does not dither (noise below
about half an LSB) makes an error that follows the signal instead of
averaging out.

This module finds both from the samples alone (:func:`inspect_channel`), and
judges them against a fitted model where a job has one
(:func:`clipping_test`, :func:`quantisation_effect`).  Everything is pure:
arrays and numbers in, frozen dataclasses out.  A job puts
:meth:`InstrumentFindings.to_dict` in its JSON (``instrument``) and the named
warnings (``clipped``, ``under-dithered``) in its result.

Examples
--------
>>> import numpy as np
>>> from senscal.io.instrument import inspect_channel
>>> y = np.clip(np.round(np.sin(np.linspace(0, 20, 500)) * 100) / 100, -0.9, 0.9)
>>> f = inspect_channel(y)
>>> round(f.lsb, 6), f.n_at_high > 1
(0.01, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from senscal._result import ResultMixin, to_jsonable
from senscal.diagnostics import named

__all__ = ["InstrumentFindings", "ClippingTest", "QuantisationEffect", "inspect_channel", "clipping_test",
           "clip_guard_mask", "quantisation_effect", "CLIP_ALPHA", "BIAS_FRACTION"]

# False-alarm probability of the clipping test (per side).
CLIP_ALPHA = 1e-3
# A bias below 0.3 u leaves the k=2 coverage at >= 94.5 % (P(|z + 0.3| < 2) for standard normal z):
# the quantiser's signal-dependent error is named when its bound exceeds this fraction of u.
BIAS_FRACTION = 0.3
# Relative tolerance of "a multiple of the LSB" (values written as text lose digits: codes x scale
# read back from a CSV match their grid to ~1e-9; a continuous signal's gaps do not).
_GRID_TOL = 1e-3


@dataclass(frozen=True)
class InstrumentFindings(ResultMixin):
    """What the samples of one channel show about the converter that took them.

    Attributes
    ----------
    n_samples : int
        Finite samples inspected.
    low, high : float
        Smallest and largest sample (unit of the channel).
    n_at_low, n_at_high : int
        Samples equal to ``low`` / ``high`` (1 for a continuous, unclipped
        signal; many when the converter saturated there).
    levels : int
        Number of distinct sample values.
    lsb : float or None
        Quantisation step (unit of the channel): the smallest gap between
        distinct values when every gap is a whole multiple of it; None when
        the values lie on no grid coarser than the number format (a
        continuous signal, or one resampled/filtered after the converter).
    clipped_low, clipped_high : bool or None
        Clipping found at that end (None: not judged; a model is needed to
        judge a quantised channel, see :func:`clipping_test`).
    n_clipped : int
        Samples at a clipped end.
    under_dithered : bool or None
        True when the analogue noise is too small to dither the quantiser
        for the job's uncertainties (see :func:`quantisation_effect`);
        None when not judged.
    noise_lsb : float or None
        Analogue noise estimated from the fit residual, in LSB.
    handled : tuple of str
        What the job did about the findings, in words (e.g. ``"fit used
        1540 of 2000 samples, away from the clip level"``).
    """

    n_samples: int
    low: float
    high: float
    n_at_low: int
    n_at_high: int
    levels: int
    lsb: float | None
    clipped_low: bool | None = None
    clipped_high: bool | None = None
    n_clipped: int = 0
    under_dithered: bool | None = None
    noise_lsb: float | None = None
    handled: tuple[str, ...] = field(default_factory=tuple)

    @property
    def clipped(self) -> bool:
        """True when either end was found clipped."""
        return bool(self.clipped_low) or bool(self.clipped_high)

    def to_dict(self) -> dict[str, Any]:
        """JSON fields (the ``instrument`` object of a job's document)."""
        d = {k: to_jsonable(getattr(self, k)) for k in self.__dataclass_fields__}
        d["clipped"] = self.clipped
        d["handled"] = list(self.handled)
        return d


def _grid_step(values: np.ndarray) -> float | None:
    """Smallest gap of sorted distinct ``values`` when all gaps are multiples of it, else None."""
    if values.size < 3:
        return None
    gaps = np.diff(values)
    scale = max(abs(float(values[0])), abs(float(values[-1])), float(values[-1] - values[0]))
    # Gaps at the number format's resolution are not a converter's grid.
    gaps = gaps[gaps > 1e-12 * scale]
    if gaps.size < 2:
        return None
    step = float(gaps.min())
    ratio = gaps / step
    if np.max(np.abs(ratio - np.round(ratio))) > _GRID_TOL:
        return None
    # A continuous signal's distinct values are about as many as its samples; a grid that is
    # barely finer than the gaps themselves (most gaps one step) is only a real grid when the
    # values repeat: without repeats the "step" is just the smallest of N random gaps.
    return step


def inspect_channel(y) -> InstrumentFindings:
    """Find quantisation and the model-free signs of clipping in one channel's samples.

    Parameters
    ----------
    y : array_like, shape (N,)
        Samples (unit of the channel); NaN/inf are ignored.

    Returns
    -------
    InstrumentFindings
        ``clipped_*`` is decided here only for a channel on no grid (a
        continuous signal): two or more samples exactly at the maximum (or
        minimum) have probability zero without saturation.  For a quantised
        channel the extremes repeat anyway, so ``clipped_*`` is None until
        :func:`clipping_test` judges them against a model.
    """
    y = np.asarray(y, dtype=float).ravel()
    y = y[np.isfinite(y)]
    n = int(y.size)
    if n == 0:
        return InstrumentFindings(0, math.nan, math.nan, 0, 0, 0, None)
    lo, hi = float(y.min()), float(y.max())
    n_lo, n_hi = int(np.count_nonzero(y == lo)), int(np.count_nonzero(y == hi))
    values = np.unique(y)
    lsb = _grid_step(values)
    if lsb is not None and values.size > 0.5 * n:
        # As many levels as samples: a continuous signal whose gaps happen to share a divisor
        # (text with few decimals) -- the grid is the number format, not a converter.
        lsb = None
    clo = chi = None
    n_clip = 0
    if lsb is None and values.size > 2:
        clo, chi = n_lo >= 2, n_hi >= 2
        n_clip = (n_lo if clo else 0) + (n_hi if chi else 0)
    return InstrumentFindings(n, lo, hi, n_lo, n_hi, int(values.size), lsb, clo, chi, n_clip)


@dataclass(frozen=True)
class ClippingTest(ResultMixin):
    """Clipping judged against a model of the unclipped signal.

    Attributes
    ----------
    expected_beyond_low, expected_beyond_high : float
        Samples the model predicts beyond the lowest / highest reading (by
        more than half an LSB): none were read, which has probability
        ``exp(-expected)`` without saturation.
    clipped_low, clipped_high : bool
        ``expected > -ln(alpha)``: the model reaches past the reading more
        often than chance allows, so the converter saturated there.
    alpha : float
        False-alarm probability per end.
    """

    expected_beyond_low: float
    expected_beyond_high: float
    clipped_low: bool
    clipped_high: bool
    alpha: float


def clipping_test(y, model, sigma: float, *, lsb: float | None = None, alpha: float = CLIP_ALPHA) -> ClippingTest:
    """Test the extremes of ``y`` for saturation against a model of the signal.

    Parameters
    ----------
    y : array_like, shape (N,)
        Samples (unit of the channel).
    model : array_like, shape (N,)
        The model's value at each sample, fitted to the samples *not* at the
        extremes (so that clipping does not pull it in).
    sigma : float or array_like, shape (N,)
        Standard deviation of the noise about the model (unit of the
        channel), one number or one per sample (a phase-dependent variance).
    lsb : float, optional
        Quantisation step; a reading holds values within half an LSB.
    alpha : float
        False-alarm probability per end.

    Returns
    -------
    ClippingTest

    Notes
    -----
    Without saturation, the number of samples the model puts beyond the
    largest reading is what one expects beyond the largest of N draws:
    ``sum_i P(Y_i > max)`` is about exponentially distributed with mean one
    (``N (1 - F(max))`` for the maximum of N independent draws).  Seeing no
    sample beyond a level the model crosses ``E`` times has probability
    ``exp(-E)``; ``E > -ln(alpha)`` rejects at level ``alpha``.
    """
    from scipy.special import ndtr

    y = np.asarray(y, dtype=float)
    m = np.asarray(model, dtype=float)
    s = np.broadcast_to(np.asarray(sigma, dtype=float), y.shape)
    ok = np.isfinite(y) & np.isfinite(m) & np.isfinite(s) & (s > 0)
    y, m, s = y[ok], m[ok], s[ok]
    half = 0.5 * lsb if lsb else 0.0
    if not y.size:
        return ClippingTest(0.0, 0.0, False, False, alpha)
    e_hi = float(np.sum(ndtr((m - (y.max() + half)) / s)))
    e_lo = float(np.sum(ndtr(((y.min() - half) - m) / s)))
    lim = -math.log(alpha)
    return ClippingTest(e_lo, e_hi, e_lo > lim, e_hi > lim, alpha)


def clip_guard_mask(y, model, sigma: float, *, low: float | None, high: float | None,
                    lsb: float | None = None) -> np.ndarray:
    """Samples a fit may use when the signal was clipped at ``low`` and/or ``high``.

    Dropping only the samples at the clip level leaves the ones whose noise
    happened to keep them just inside: a truncated sample, biased towards the
    middle.  The remedy drops every sample whose *model* value lies within
    ``z sigma`` of a clip level, with ``z`` such that the kept samples hold
    fewer than half a clipped sample in expectation (``P = 0.5 / N`` per
    sample): the selection then depends on the time only, not on the noise,
    and the fit of the kept samples is unbiased.

    Parameters
    ----------
    y, model : array_like, shape (N,)
        Samples and the model's value at each (unit of the channel).
    sigma : float or array_like, shape (N,)
        Noise standard deviation about the model (one number or per sample).
    low, high : float or None
        Clip levels (None: that end is not clipped).
    lsb : float, optional
        Quantisation step (a clipped reading is within half an LSB of the level).

    Returns
    -------
    ndarray of bool, shape (N,)
        True for samples to keep.
    """
    from scipy.special import ndtri

    y = np.asarray(y, dtype=float)
    m = np.asarray(model, dtype=float)
    n = max(y.size, 1)
    z = float(ndtri(1.0 - 0.5 / n))
    half = 0.5 * lsb if lsb else 0.0
    keep = np.isfinite(y)
    if high is not None:
        keep &= (m < high - half - z * sigma) & (y < high)
    if low is not None:
        keep &= (m > low + half + z * sigma) & (y > low)
    return keep


@dataclass(frozen=True)
class QuantisationEffect(ResultMixin):
    """Whether a quantiser was dithered enough for a fit's uncertainties.

    Attributes
    ----------
    lsb : float
        Quantisation step (unit of the channel).
    noise : float
        Analogue noise standard deviation estimated from the residual,
        ``sqrt(max(rms^2 - LSB^2/12, 0))`` (unit of the channel).
    noise_lsb : float
        ``noise / lsb``.
    bias_bound : float
        Amplitude of the quantiser's signal-dependent mean error,
        ``(LSB / pi) exp(-2 pi^2 noise^2 / LSB^2)`` (first term of the
        Widrow series): a bound on the bias it adds to an offset (a mean) and,
        times 4/pi, to an amplitude.
    u_reference : float
        The smallest standard uncertainty it was compared with.
    under_dithered : bool
        ``bias_bound > BIAS_FRACTION * u_reference``.
    """

    lsb: float
    noise: float
    noise_lsb: float
    bias_bound: float
    u_reference: float
    under_dithered: bool

    def warning(self, what: str = "the amplitude, phase and offset") -> str:
        """The ``under-dithered`` named warning."""
        return named("under-dithered", (
            f"the samples lie on a grid of {self.lsb:.3g} (one ADC LSB) and the analogue noise is only about "
            f"{self.noise_lsb:.2f} LSB, too little to dither the quantiser: its error follows the signal "
            f"(up to {self.bias_bound:.2g}, {self.bias_bound / self.u_reference:.1f} u) instead of averaging out, "
            f"so u of {what} does not cover; add analogue noise or dither of >= 0.5 LSB, or use a finer "
            f"ADC range"))


def quantisation_effect(lsb: float, residual_rms: float, u_reference: float) -> QuantisationEffect:
    """Judge whether a quantised channel's fit is under-dithered.

    Parameters
    ----------
    lsb : float
        Quantisation step (unit of the channel).
    residual_rms : float
        RMS of the fit residual (analogue noise and quantisation error).
    u_reference : float
        The smallest standard uncertainty of a quoted value in the unit of
        the channel (for a sine fit ``min(u(offset), u(amplitude))``).

    Returns
    -------
    QuantisationEffect

    Notes
    -----
    With Gaussian analogue noise ``s`` ahead of a quantiser of step ``q``,
    the mean of the quantisation error given the signal ``x`` is
    ``sum_k (-1)^(k+1) (q / (pi k)) exp(-2 pi^2 k^2 s^2 / q^2) sin(2 pi k x / q)``
    (Widrow's series); its first term bounds it.  That part is not noise: it
    repeats wherever the signal repeats, so it does not average down as the
    fit's u assumes.  When the bound is below ``0.3 u`` it cannot move the
    coverage below 94.5 %; above, it is named.  The residual variance is
    ``s^2 + q^2 / 12`` (Sheppard), which gives ``s``.
    """
    q = float(lsb)
    noise = math.sqrt(max(float(residual_rms) ** 2 - q * q / 12.0, 0.0))
    bound = (q / math.pi) * math.exp(-2.0 * math.pi**2 * (noise / q) ** 2)
    u = float(u_reference)
    return QuantisationEffect(q, noise, noise / q, bound, u, bool(bound > BIAS_FRACTION * u))
