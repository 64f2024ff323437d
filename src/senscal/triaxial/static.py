"""Static-interval detection in a continuous multi-position recording.

An accelerometer measures gravity alone only while it is still; the moving
segments between poses add the hand's acceleration and must be left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from senscal._result import ResultMixin
from senscal.errors import InputError, TooFewSamplesError

__all__ = ["StaticIntervals", "detect_static", "true_runs", "intervals_of"]


@dataclass(frozen=True)
class StaticIntervals(ResultMixin):
    """Static poses found in a recording.

    Attributes
    ----------
    starts, stops : ndarray of int
        Sample index ranges ``[start, stop)`` of each pose.
    means : ndarray, shape (3, K)
        Mean of each axis over each pose (sensor units).
    stds : ndarray, shape (3, K)
        Per-axis standard deviation within each pose (sensor units).
    counts : ndarray of int
    threshold : float
        Moving-variance threshold used (sensor units squared, summed over axes).
    noise_variance : float
        Reference per-window variance of a still sensor (sum over axes).
    """

    starts: np.ndarray
    stops: np.ndarray
    means: np.ndarray
    stds: np.ndarray
    counts: np.ndarray
    threshold: float
    noise_variance: float

    @property
    def n_poses(self) -> int:
        return int(self.starts.size)


def detect_static(x: np.ndarray, fs: float, *, window_s: float = 0.5, min_duration_s: float = 1.0,
                  factor: float = 3.0, threshold: float | None = None) -> StaticIntervals:
    """Find the intervals where a three-axis sensor is still.

    Parameters
    ----------
    x : ndarray, shape (3, N)
        Samples (sensor units).
    fs : float
        Sample rate in Hz.
    window_s : float
        Length of the centred moving-variance window in s.
    min_duration_s : float
        Shortest pose kept, in s.
    factor : float
        A window is still when its variance (summed over axes) is below
        ``factor**2`` times the reference variance of a still sensor, taken as
        the 10th percentile of all window variances (most of a calibration
        session is still).
    threshold : float, optional
        Explicit variance threshold (sensor units squared), overriding ``factor``.

    Returns
    -------
    StaticIntervals
    """
    x = np.asarray(x, float)
    if x.ndim != 2 or x.shape[0] != 3:
        raise InputError(f"static detection needs 3 axes x N samples, got shape {x.shape}")
    if not fs > 0:
        raise InputError(f"sample rate must be positive, got {fs!r}")
    if not (math.isfinite(window_s) and window_s > 0 and math.isfinite(min_duration_s) and min_duration_s >= 0):
        raise InputError(f"the static window must be a positive number of seconds and the shortest pose "
                         f"non-negative, got {window_s!r} and {min_duration_s!r}")
    w = max(int(round(window_s * fs)), 3)
    if x.shape[1] < 2 * w:
        raise TooFewSamplesError(f"static detection with a {window_s:g} s window needs at least {2 * w} samples, "
                                 f"got {x.shape[1]}; record longer or shorten --static-window")
    mean = uniform_filter1d(x, w, axis=1, mode="nearest")
    var = np.clip(uniform_filter1d(x * x, w, axis=1, mode="nearest") - mean * mean, 0.0, None).sum(axis=0)
    ref = float(np.percentile(var, 10))
    thr = float(threshold) if threshold is not None else factor ** 2 * max(ref, 1e-300)
    still = var <= thr
    # Runs of still window centres: each centre's whole window is still, so the
    # run itself stays half a window clear of the moving segments.
    starts, stops = true_runs(still)
    keep = (stops - starts) >= max(int(round(min_duration_s * fs)), 2)
    return intervals_of(x, starts[keep], stops[keep], thr, ref)


def true_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and stop indices (stop exclusive) of the runs of True in a boolean vector."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]])))
    return edges[0::2], edges[1::2]


def intervals_of(x: np.ndarray, starts, stops, threshold: float, noise_variance: float) -> StaticIntervals:
    """The still intervals ``[starts, stops)`` of ``x`` (3, N) with their means, standard deviations and counts.

    ``threshold`` and ``noise_variance`` (sensor units squared) are recorded as the detector's.
    """
    starts = np.asarray(starts, int)
    stops = np.asarray(stops, int)
    means = np.array([x[:, a:b].mean(axis=1) for a, b in zip(starts, stops)]).T.reshape(3, -1)
    stds = np.array([x[:, a:b].std(axis=1, ddof=1) for a, b in zip(starts, stops)]).T.reshape(3, -1)
    return StaticIntervals(starts=starts, stops=stops, means=means, stds=stds, counts=stops - starts,
                           threshold=threshold, noise_variance=noise_variance)
