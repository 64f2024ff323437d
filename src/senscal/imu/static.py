"""Static poses of a multi-pose IMU session by a threshold sweep (the IMU-TK protocol).

IMU-TK (Tedaldi, Pretto, Menegatti, ICRA 2014) marks a sample static when the
accelerometer's moving variance is below ``k`` times the variance of the
initial still period, tries ``k = 1 .. 10`` and keeps the threshold whose
static poses give the smallest accelerometer calibration residual.  The
detector itself is :func:`senscal.triaxial.detect_static`.

A turn about the vertical leaves gravity fixed in the body frame: the
accelerometer sees one still pose, the gyro a rotation (issue 27).  Each
accelerometer-still run is therefore also checked with the gyro
(:func:`split_by_gyro`): the gyro's moving mean over the same window, less the
run's own bias level (the median of those means, robust to a turn filling less
than half the run; in runs of 4 s or more the line through its two halves' medians, so that a drifting bias is
no turn), is compared with its still scatter (the pooled median
absolute deviation of the runs' moving means, which carries coloured noise
too, floored at the gyro's resolution); beyond :data:`GYRO_SIGMA` of it the sample moves.  Moving samples are
cut out with half a window of margin on each side and the pieces of at least
the shortest pose are kept as poses of their own; a run whose turn leaves no
piece that long is dropped and named (``pose-rotation-unsplit``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scipy import stats
from scipy.ndimage import uniform_filter1d

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import InputError
from senscal.triaxial.static import StaticIntervals, detect_static, intervals_of, true_runs

__all__ = ["PoseSweep", "GyroSplit", "sweep_static", "split_by_gyro", "gyro_resolution", "MULTIPLES", "MIN_POSES", "GYRO_SIGMA"]

#: Threshold multiples of the still variance tried (IMU-TK's 1 .. 10).
MULTIPLES = tuple(float(m) for m in range(1, 11))

#: Poses the accelerometer model needs: 9 parameters and at least 3 degrees of freedom left for its u.
MIN_POSES = 12

#: A still gyro's moving mean beyond this many still deviations (per axis) is motion.  A session holds about
#: ``3 N / w`` independent window means (N samples, w per window: ~1000 for 30 poses at 100 Hz); a two-sided
#: normal tail of 5.7e-7 at 5 deviations gives a false cut in about one session in 1700 (and a false cut
#: only costs a window of still data).  A hand turn of 1 deg over 1 s at MEMS noise (0.002 rad/s per sample,
#: 100 Hz) is 87 deviations.
GYRO_SIGMA = 5.0
#: The gyro's moving-mean window, s: short, so that a cut reaches little beyond the motion (a 1 s window would
#: flag half a second of still samples on each side of a turn and leave no pose between two hand rotations);
#: a 10-sample mean still sees 0.003 rad/s at MEMS noise, where a hand turn runs at 0.5-5 rad/s.
GYRO_WINDOW_S = 0.1
#: Runs at least this long (s) take their level as a line in time (two halves' medians), shorter ones the median.
LEVEL_LINE_S = 4.0


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
    gyro: "GyroSplit | None" = None
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class GyroSplit(ResultMixin):
    """What the gyro check did to the accelerometer's still runs (:func:`split_by_gyro`).

    Attributes
    ----------
    static : StaticIntervals
        The poses after the cuts.
    n_split : int
        Runs cut into two or more poses.
    unsplit : tuple of (float, float, float)
        Runs still at both ends and moving inside, dropped because no piece was long enough (named
        ``pose-rotation-unsplit``): ``(start s, stop s, largest moving-mean deviation)``.
    trimmed : int
        Runs that lost moving samples at an end (one piece kept).
    scale : ndarray, shape (3,)
        The still scatter of the gyro's moving mean per axis (gyro units).
    short : tuple of (float, float, float)
        Runs moving at an end whose still rest is shorter than the shortest pose (dropped, like any short
        window; not named).
    """

    static: StaticIntervals
    n_split: int
    unsplit: tuple
    trimmed: int
    scale: np.ndarray
    short: tuple = ()


def gyro_resolution(gyro: np.ndarray) -> np.ndarray:
    """The smallest nonzero step between consecutive samples per axis, shape (3,) (gyro units; 0 if none)."""
    steps = np.abs(np.diff(np.asarray(gyro, float), axis=1))
    return np.array([float(np.min(r[r > 0])) if np.any(r > 0) else 0.0 for r in steps])


def split_by_gyro(accel: np.ndarray, gyro: np.ndarray, st: StaticIntervals, fs: float, *,
                  window_s: float = GYRO_WINDOW_S, min_pose_s: float = 1.0, sigma: float = GYRO_SIGMA,
                  accel_window_s: float = 1.0, resolution: np.ndarray | None = None) -> GyroSplit:
    """Cut the accelerometer's still runs where the gyro moves (a turn about the vertical).

    Parameters
    ----------
    accel, gyro : ndarray, shape (3, N)
        Readings (sensor units).
    st : StaticIntervals
        The accelerometer's still runs.
    fs : float
        Sample rate, Hz.
    window_s : float
        Moving-mean window of the gyro, s (at least 3 samples).
    min_pose_s : float
        Shortest piece kept, s.
    sigma : float
        Threshold in still deviations of the moving mean.
    accel_window_s : float
        The accelerometer's moving-variance window, s: a run dropped for motion only within half of it from
        an end holds a rotation's tail, not a turn inside the pose (not named).
    resolution : ndarray, shape (3,), optional
        The gyro's resolution per axis (gyro units; default :func:`gyro_resolution` of ``gyro``).

    Returns
    -------
    GyroSplit
    """
    g = np.asarray(gyro, float)
    w = max(int(round(window_s * fs)), 3)
    n_min = max(int(round(min_pose_s * fs)), 2)
    half = w // 2
    edge = max(int(round(0.5 * accel_window_s * fs)), 1)
    n_long = max(int(round(LEVEL_LINE_S * fs)), 4)
    devs = []
    for a, b in zip(st.starts, st.stops):
        mm = uniform_filter1d(g[:, a:b], min(w, b - a), axis=1, mode="nearest")
        n = b - a
        if n >= n_long:
            # A long run (the still start, a merged pose): the level as the line through its two halves'
            # medians, so that a bias drifting with time or a warm-up is no turn.
            h = n // 2
            m1 = np.median(mm[:, :h], axis=1, keepdims=True)
            m2 = np.median(mm[:, h:], axis=1, keepdims=True)
            c1, c2 = (h - 1) / 2.0, h + (n - h - 1) / 2.0
            level = m1 + (m2 - m1) * ((np.arange(n) - c1) / (c2 - c1))[None, :]
        else:
            level = np.median(mm, axis=1, keepdims=True)
        devs.append(mm - level)
    if not devs:
        return GyroSplit(static=st, n_split=0, unsplit=(), trimmed=0, scale=np.zeros(3), short=())
    # The still scatter from the median absolute deviation over all runs (a turn's samples are few).
    pooled = np.concatenate(devs, axis=1)
    # Floored at the gyro's resolution (its smallest step between samples): a gyro quieter than one count has
    # a median absolute deviation of 0, and one count's flip must not pass for a turn.
    lsb = gyro_resolution(g) if resolution is None else np.asarray(resolution, float)
    scale = np.maximum(stats.norm.ppf(0.75) ** -1 * np.median(np.abs(pooled), axis=1), np.maximum(lsb, 1e-300))
    starts, stops, unsplit, short = [], [], [], []
    n_split = trimmed = 0
    for (a, b), dv in zip(zip(st.starts, st.stops), devs):
        z = np.max(np.abs(dv) / scale[:, None], axis=0)
        moving = z > sigma
        if not moving.any():
            starts.append(a)
            stops.append(b)
            continue
        # Half a window of margin: a moving mean below the threshold may still hold the turn's slow tail.
        idx = np.flatnonzero(moving)
        grow = np.zeros(b - a + 1, int)
        np.add.at(grow, np.clip(idx - half, 0, b - a), 1)
        np.add.at(grow, np.clip(idx + half + 1, 0, b - a), -1)
        still = np.cumsum(grow)[:-1] == 0
        pieces = [(a + p, a + q) for p, q in zip(*true_runs(still)) if q - p >= n_min]
        if not pieces:
            if np.any((idx >= edge) & (idx < b - a - edge)):
                # Moving farther inside than the accelerometer's half window reaches: a turn it cannot see,
                # too short to split.
                unsplit.append((a / fs, b / fs, float(z.max())))
            else:
                # Motion within the accelerometer's half window of an end (a rotation's slow tail the variance
                # window let in) leaves too short a pose: left out like any window shorter than --min-pose.
                short.append((a / fs, b / fs, float(z.max())))
            continue
        if len(pieces) > 1:
            n_split += 1
        else:
            trimmed += 1
        for p, q in pieces:
            starts.append(p)
            stops.append(q)
    out = intervals_of(np.asarray(accel, float), starts, stops, st.threshold, st.noise_variance)
    return GyroSplit(static=out, n_split=n_split, unsplit=tuple(unsplit), trimmed=trimmed, scale=scale,
                     short=tuple(short))


def sweep_static(accel: np.ndarray, fs: float, gravity_of, *, window_s: float = 1.0, min_pose_s: float = 1.0,
                 init_s: float | None = None, multiples=MULTIPLES, min_poses: int = MIN_POSES,
                 source: str = "the recording", gyro: np.ndarray | None = None) -> PoseSweep:
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
    gyro : ndarray, shape (3, N), optional
        Gyro readings: each still run is also cut where the gyro moves (:func:`split_by_gyro`), at every
        multiple tried.

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
    lsb = None if gyro is None else gyro_resolution(gyro)  # the same at every multiple
    best = None
    most = 0
    for m in multiples:
        if ref is None:
            st0 = detect_static(x, fs, window_s=window_s, min_duration_s=min_pose_s)
            ref = st0.noise_variance
        thr = m * max(ref, 1e-300)
        st = detect_static(x, fs, window_s=window_s, min_duration_s=min_pose_s, threshold=thr)
        gs = None
        if gyro is not None:
            gs = split_by_gyro(x, gyro, st, fs, min_pose_s=min_pose_s, accel_window_s=window_s, resolution=lsb)
            st = gs.static
        most = max(most, st.n_poses)
        rms = float(gravity_of(st.means)) if st.n_poses >= min_poses else math.nan
        row = {"multiple": m, "threshold": thr, "n_poses": st.n_poses, "rms": rms}
        if gs is not None:
            row.update(gyro_split=gs.n_split, gyro_unsplit=len(gs.unsplit))
        tried.append(row)
        if math.isfinite(rms) and (best is None or rms < best[2]):
            best = (m, st, rms, gs)
    if best is None:
        thr_txt = f"{tried[0]['threshold']:.3g} to {tried[-1]['threshold']:.3g}" if tried else "none"
        raise InputError(f"no static poses in {source}: found at most {most} still windows of >= {min_pose_s:g} s "
                         f"(the accelerometer model needs >= {min_poses}) with variance thresholds {thr_txt} "
                         f"(x{multiples[0]:g}..x{multiples[-1]:g} the still variance); hold the IMU still "
                         f"longer in more orientations, or lower --min-pose / --static-window")
    gs = best[3]
    warnings = []
    if gs is not None and gs.unsplit:
        where = ", ".join(f"{a:.1f}-{b:.1f} s" for a, b, _ in gs.unsplit[:5]) + (" ..." if len(gs.unsplit) > 5 else "")
        warnings.append(named("pose-rotation-unsplit", (
            f"the gyro turns inside {len(gs.unsplit)} still accelerometer window(s) ({where}; up to "
            f"{max(z for *_, z in gs.unsplit):.0f} still deviations of its moving mean): a turn about the vertical "
            f"the accelerometer cannot see, with no still part of >= {min_pose_s:g} s on either side to keep as a "
            "pose; those windows are left out of the poses (the turn joins the rotation between its neighbours): "
            "hold each orientation longer before and after turning, or lower --min-pose")))
    return PoseSweep(static=best[1], multiple=best[0], reference_variance=float(ref), tried=tuple(tried), gyro=gs,
                     warnings=tuple(warnings))
