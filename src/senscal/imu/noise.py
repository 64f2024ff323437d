"""IMU noise parameters from the still start: kalibr-style YAML and ROS covariance.

The still start (the session's first static pose) is corrected with the calibration and each axis goes
through the Allan analysis of ``senscal allan`` (:func:`senscal.drift.allan.allan_deviation`,
:func:`~senscal.drift.allan.identify_noise`): the white-noise density ``N`` (the -1/2 line at tau = 1 s)
and the random walk ``K`` (+1/2 line at tau = 3 s).  kalibr's IMU file wants one number per triad:
the largest axis's (a filter tuned with it is not over-confident on any axis).

When the still start is too short for the +1/2 line to show, ``K`` is not identified; the file then holds
an upper bound read off the longest cluster time (the Allan variance is a sum of non-negative terms, so
``K^2 tau / 3 <= adev(tau)^2``, with ``adev`` at its upper one-sigma limit) and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from senscal._result import ResultMixin

__all__ = ["ImuNoise", "noise_parameters"]


@dataclass(frozen=True)
class ImuNoise(ResultMixin):
    """Noise of both triads from the still start.

    Attributes
    ----------
    accel_density, gyro_density : ndarray, shape (3,)
        White-noise density per axis: m/s^2/sqrt(Hz), rad/s/sqrt(Hz) (NaN where the curve shows none).
    accel_random_walk, gyro_random_walk : ndarray, shape (3,)
        Random walk per axis: m/s^3/sqrt(Hz), rad/s^2/sqrt(Hz); an upper bound where not identified.
    accel_rw_bound, gyro_rw_bound : ndarray of bool, shape (3,)
        True where the random walk is only an upper bound.
    accel_std, gyro_std : ndarray, shape (3,)
        Per-sample standard deviation (m/s^2, rad/s): the ROS covariance's square roots.
    fs : float
        Sample rate, Hz.
    duration_s : float
        Length of the still start analysed.
    """

    accel_density: np.ndarray
    gyro_density: np.ndarray
    accel_random_walk: np.ndarray
    gyro_random_walk: np.ndarray
    accel_rw_bound: np.ndarray
    gyro_rw_bound: np.ndarray
    accel_std: np.ndarray
    gyro_std: np.ndarray
    fs: float
    duration_s: float

    def ros_covariance(self) -> dict[str, list[float]]:
        """``sensor_msgs/Imu`` covariances (row-major 3x3, per sample: m^2/s^4 and rad^2/s^2)."""
        return {"linear_acceleration_covariance": np.diag(self.accel_std ** 2).ravel().tolist(),
                "angular_velocity_covariance": np.diag(self.gyro_std ** 2).ravel().tolist()}

    def kalibr_yaml(self, topic: str = "/imu0") -> str:
        """The IMU block of a kalibr ``imu.yaml`` (largest axis of each triad)."""

        def big(v):
            v = np.asarray(v, float)
            return float(np.nanmax(v)) if np.isfinite(v).any() else float("nan")

        note_a = "  # upper bound: the still start is too short to show the random walk" if self.accel_rw_bound.any() else ""
        note_g = "  # upper bound: the still start is too short to show the random walk" if self.gyro_rw_bound.any() else ""
        return ("# IMU noise from the still start of a senscal imu calibrate session "
                f"({self.duration_s:.0f} s; Allan deviation, largest axis)\n"
                f"accelerometer_noise_density: {big(self.accel_density):.6g}  # m/s^2/sqrt(Hz)\n"
                f"accelerometer_random_walk: {big(self.accel_random_walk):.6g}  # m/s^3/sqrt(Hz){note_a}\n"
                f"gyroscope_noise_density: {big(self.gyro_density):.6g}  # rad/s/sqrt(Hz)\n"
                f"gyroscope_random_walk: {big(self.gyro_random_walk):.6g}  # rad/s^2/sqrt(Hz){note_g}\n"
                f"rostopic: {topic}\n"
                f"update_rate: {self.fs:.6g}  # Hz\n")


def _axis(y: np.ndarray, fs: float) -> tuple[float, float, bool]:
    from senscal.drift.allan import allan_deviation, identify_noise

    res = allan_deviation(y, fs)
    lev = identify_noise(res)
    # Without a -1/2 region the shortest cluster's deviation times sqrt(tau0) is the white density's bound.
    n = float(lev.N) if lev.N is not None else float(res.dev[0] / math.sqrt(fs))
    if lev.K is not None:
        return n, float(lev.K), False
    i = int(np.nanargmax(res.taus))
    return n, float(res.upper[i] * math.sqrt(3.0 / res.taus[i])), True


def noise_parameters(f: np.ndarray, w: np.ndarray, fs: float) -> ImuNoise:
    """Allan noise levels of corrected still data.

    Parameters
    ----------
    f, w : ndarray, shape (3, N)
        Specific force (m/s^2) and rate (rad/s) over the still start, calibrated.
    fs : float
        Sample rate, Hz.

    Returns
    -------
    ImuNoise

    Raises
    ------
    TooFewSamplesError
        The still start holds too few samples for an Allan deviation.
    """
    acc = [_axis(f[i], fs) for i in range(3)]
    gyr = [_axis(w[i], fs) for i in range(3)]
    return ImuNoise(accel_density=np.array([a[0] for a in acc]), gyro_density=np.array([g[0] for g in gyr]),
                    accel_random_walk=np.array([a[1] for a in acc]), gyro_random_walk=np.array([g[1] for g in gyr]),
                    accel_rw_bound=np.array([a[2] for a in acc]), gyro_rw_bound=np.array([g[2] for g in gyr]),
                    accel_std=np.std(f, axis=1, ddof=1), gyro_std=np.std(w, axis=1, ddof=1), fs=float(fs),
                    duration_s=f.shape[1] / fs)
