"""Static poses of a multi-pose IMU session by a threshold sweep (the IMU-TK protocol).

IMU-TK (Tedaldi, Pretto, Menegatti, ICRA 2014) marks a sample static when the
accelerometer's moving variance is below ``k`` times the variance of the
initial still period, tries ``k = 1 .. 10`` and keeps the threshold whose
static poses give the smallest accelerometer calibration residual.  The
detector itself is :func:`senscal.triaxial.detect_static`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError
from senscal.triaxial.static import StaticIntervals, detect_static

__all__ = ["PoseSweep", "sweep_static", "MULTIPLES", "MIN_POSES"]

#: Threshold multiples of the still variance tried (IMU-TK's 1 .. 10).
MULTIPLES = tuple(float(m) for m in range(1, 11))

#: Poses the accelerometer model needs: 9 parameters and at least 3 degrees of freedom left for its u.
MIN_POSES = 12


@dataclass(frozen=True)
class PoseSweep(ResultMixin):
    """The chosen static poses and what the sweep tried.

    Attributes
    ----------
    static : StaticIntervals
        Poses at the chosen threshold.
    multiple : float
        Chosen multiple of the still variance.
    reference_variance : float
        Variance of a still accelerometer per window, summed over axes (sensor units squared).
    tried : tuple of dict
        Per multiple: ``{"multiple", "threshold", "n_poses", "rms"}`` (rms of ``|f| - g`` over the pose means
        after a quick fit, NaN when too few poses).
    """

    static: StaticIntervals
    multiple: float
    reference_variance: float
    tried: tuple[dict, ...]


def sweep_static(accel: np.ndarray, fs: float, gravity_of, *, window_s: float = 1.0, min_pose_s: float = 1.0,
                 init_s: float | None = None, multiples=MULTIPLES, min_poses: int = MIN_POSES,
                 source: str = "the recording") -> PoseSweep:
    """Static poses by a threshold sweep, with an explanation when none fits.

    Parameters
    ----------
    accel : ndarray, shape (3, N)
        Accelerometer readings (sensor units).
    fs : float
        Sample rate, Hz.
    gravity_of : callable
        ``gravity_of(means) -> rms`` of ``|f| - g`` over pose means (shape (3, K)) after a quick
        calibration (NaN when it fails); the sweep keeps the multiple with the smallest.
    window_s : float
        Moving-variance window, s.
    min_pose_s : float
        Shortest pose kept, s.
    init_s : float, optional
        Length of the still start, s: its variance is the reference (IMU-TK's ``init interval``);
        None: the 10th percentile of all window variances.
    multiples : sequence of float
        Threshold multiples of the reference tried.
    min_poses : int
        Poses the model needs.

    Raises
    ------
    InputError
        No multiple gives ``min_poses`` poses: the message names how many were found, how many the model needs
        and the thresholds tried.
    """
    x = np.asarray(accel, float)
    w = max(int(round(window_s * fs)), 3)
    if init_s is not None:
        n0 = int(round(init_s * fs))
        if n0 < 2 * w:
            raise InputError(f"--init-static {init_s:g} s holds fewer than two {window_s:g} s windows; give the "
                             "length of the still start in seconds (IMU-TK's protocol: 30-50 s)")
        seg = x[:, :n0]
        ref = float(sum(np.var(seg[a].reshape(-1)[: (n0 // w) * w].reshape(-1, w), axis=1, ddof=1).mean()
                        for a in range(3)))
    else:
        ref = None
    tried = []
    best = None
    most = 0
    for m in multiples:
        if ref is None:
            st0 = detect_static(x, fs, window_s=window_s, min_duration_s=min_pose_s)
            ref = st0.noise_variance
        thr = m * max(ref, 1e-300)
        st = detect_static(x, fs, window_s=window_s, min_duration_s=min_pose_s, threshold=thr)
        most = max(most, st.n_poses)
        rms = float(gravity_of(st.means)) if st.n_poses >= min_poses else math.nan
        tried.append({"multiple": m, "threshold": thr, "n_poses": st.n_poses, "rms": rms})
        if math.isfinite(rms) and (best is None or rms < best[2]):
            best = (m, st, rms)
    if best is None:
        thr_txt = f"{tried[0]['threshold']:.3g} to {tried[-1]['threshold']:.3g}" if tried else "none"
        raise InputError(f"no static poses in {source}: found at most {most} still windows of >= {min_pose_s:g} s "
                         f"(the accelerometer model needs >= {min_poses}) with variance thresholds {thr_txt} "
                         f"(x{multiples[0]:g}..x{multiples[-1]:g} the still variance); hold the IMU still "
                         f"longer in more orientations, or lower --min-pose / --static-window")
    return PoseSweep(static=best[1], multiple=best[0], reference_variance=float(ref), tried=tuple(tried))
