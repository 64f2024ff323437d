"""Amplitude linearity: output amplitude against input amplitude at a fixed frequency.

References
----------
.. [1] Qin Chaojun, "Three-parameter cosine fit in double-centrifuge dynamic
   calibration of linear accelerometers" (seed 003; ``shared/METHODS.md``
   section 4, "Amplitude linearity").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError, TooFewSamplesError

__all__ = ["LinearityPoint", "AmplitudeLinearity", "amplitude_linearity"]


@dataclass(frozen=True)
class LinearityPoint(ResultMixin):
    """One input level.

    Attributes
    ----------
    source : str
    input_amplitude : float
        Peak input (m/s^2).
    output_amplitude, u_output_amplitude : float
        Fitted peak output and its standard uncertainty (output unit).
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
    full_scale_output : float
        Largest output amplitude (output unit).
    linearity_percent : float
        Largest |deviation| relative to the full-scale output, percent.
    u_linearity_percent : float
        Standard uncertainty of the deviation at the worst point from the
        output fit alone (percent): a linearity well above it is real.
    """

    points: tuple[LinearityPoint, ...]
    slope: float
    u_slope: float
    intercept: float
    u_intercept: float
    full_scale_output: float
    linearity_percent: float
    u_linearity_percent: float


def amplitude_linearity(input_amplitudes: Sequence[float], output_amplitudes: Sequence[float],
                        u_output: Sequence[float] | None = None,
                        sources: Sequence[str] | None = None) -> AmplitudeLinearity:
    """Fit the best (least-squares) straight line and report the linearity.

    Parameters
    ----------
    input_amplitudes : sequence of float
        Peak input accelerations in m/s^2 (at least 3 distinct levels).
    output_amplitudes : sequence of float
        Fitted peak outputs (output unit).
    u_output : sequence of float, optional
        Standard uncertainties of the outputs.
    sources : sequence of str, optional
        Labels (file names).

    Returns
    -------
    AmplitudeLinearity
        Slope and intercept uncertainties come from the straight-line
        residuals (they contain the nonlinearity, which is what a user
        quoting the slope over this range must carry).

    References
    ----------
    .. [1] Qin Chaojun (seed 003): linearity is the largest deviation of the
       output amplitude from the best straight line, relative to the
       full-scale output.
    """
    x = np.asarray(input_amplitudes, dtype=float)
    y = np.asarray(output_amplitudes, dtype=float)
    if x.shape != y.shape or x.ndim != 1:
        raise InputError(f"give one output amplitude per input amplitude (got {x.size} inputs, {y.size} outputs)")
    if np.unique(x).size < 3:
        raise TooFewSamplesError(f"a straight line with an uncertainty needs at least 3 distinct input amplitudes, got {np.unique(x).size}")
    if not np.all(np.isfinite(x)) or np.any(x <= 0):
        raise InputError("input amplitudes must be positive numbers (m/s^2)")
    u = np.zeros_like(y) if u_output is None else np.asarray(u_output, dtype=float)
    from scipy.stats import linregress

    lr = linregress(x, y)
    dev = y - (lr.slope * x + lr.intercept)
    fs = float(np.max(np.abs(y)))
    dev_pct = 100.0 * dev / fs
    worst = int(np.argmax(np.abs(dev)))
    labels = list(sources) if sources is not None else [""] * x.size
    pts = tuple(LinearityPoint(labels[i], float(x[i]), float(y[i]), float(u[i]), float(dev[i]), float(dev_pct[i]))
                for i in range(x.size))
    return AmplitudeLinearity(pts, float(lr.slope), float(lr.stderr), float(lr.intercept),
                              float(lr.intercept_stderr), fs, float(abs(dev_pct[worst])),
                              100.0 * float(u[worst]) / fs if math.isfinite(u[worst]) else math.nan)
