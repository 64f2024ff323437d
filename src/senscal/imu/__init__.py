"""IMU calibration: accelerometer and gyroscope together from one multi-pose session (issue 27).

Static poses by a threshold sweep (:mod:`senscal.imu.static`), the
accelerometer by the triaxial engine on the pose means, the gyroscope by
integrating the rotation between poses (:mod:`senscal.imu.calibrate`).
"""

from senscal.imu.calibrate import ACCEL_NAMES, GYRO_ANGLES, GyroCalibration, ImuResult, calibrate_imu
from senscal.imu.static import MIN_POSES, MULTIPLES, PoseSweep, sweep_static

__all__ = ["ACCEL_NAMES", "GYRO_ANGLES", "GyroCalibration", "ImuResult", "calibrate_imu", "MIN_POSES", "MULTIPLES",
           "PoseSweep", "sweep_static"]
