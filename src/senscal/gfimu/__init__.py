"""Gyro-free angular velocity from an accelerometer array.

Array kinematics for any layout, the three classic methods (integration,
square root, differential), the independent Kalman filter (and an extended
Kalman filter on the quadratic terms), attitude and error statistics.

References
----------
.. [1] Wang W., Dai Y., Chen H., Wang P., "Application of Kalman filter to
   calculate angular velocity of complicated vibration by full acceleration
   sensor", China Measurement & Test, 2017(5) (seed 001).
"""

from senscal.gfimu.attitude import AttitudeError, attitude_error, integrate_attitude
from senscal.gfimu.core import (DEFAULT_BIAS_STD, METHODS, ErrorStatistics, RateEstimate, RestOffsets, ScaleFactorTest,
                               angular_velocity, convergence_index, error_statistics, rest_offsets, scale_factor_test)
from senscal.gfimu.filter import OBSERVATIONS, RateFilterResult, kalman_rate
from senscal.gfimu.layout import (UNKNOWNS, KinematicSolution, Layout, paper_layout, read_layout, solve_kinematics,
                                  write_layout)
from senscal.gfimu.methods import differential_rate, estimate_noise_std, integration_rate, sqrt_rate

__all__ = [
    "AttitudeError", "attitude_error", "integrate_attitude",
    "DEFAULT_BIAS_STD", "METHODS", "ErrorStatistics", "RateEstimate", "RestOffsets", "angular_velocity",
    "error_statistics", "rest_offsets", "ScaleFactorTest", "convergence_index", "scale_factor_test",
    "OBSERVATIONS", "RateFilterResult", "kalman_rate",
    "UNKNOWNS", "KinematicSolution", "Layout", "paper_layout", "read_layout", "solve_kinematics", "write_layout",
    "differential_rate", "estimate_noise_std", "integration_rate", "sqrt_rate",
]
