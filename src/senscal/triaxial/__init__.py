"""Three-axis magnetometer / accelerometer calibration (METHODS.md section 5).

The seed's linearised steering-error model (LMS neuron and least squares),
the exact model ``H_hat = K S H + B`` (algebraic ellipsoid fit, maximum
likelihood on the field magnitude), simpler models for poor data, coverage
and identifiability diagnostics, and static-pose detection for
accelerometers.
"""

from senscal.triaxial.calibrate import METHODS, TriaxialResult, calibrate
from senscal.triaxial.estimators import ModelFit, fit_algebraic, fit_linear, fit_lms, fit_ml
from senscal.triaxial.models import (
    LINEAR_NAMES, MODELS, TriaxialCalibration, linear_features, load_calibration, matrix_to_angles, sensor_matrix,
)
from senscal.triaxial.static import StaticIntervals, detect_static

__all__ = [
    "calibrate", "TriaxialResult", "METHODS", "MODELS", "LINEAR_NAMES", "TriaxialCalibration", "load_calibration",
    "sensor_matrix", "matrix_to_angles", "linear_features", "ModelFit", "fit_algebraic", "fit_ml", "fit_linear",
    "fit_lms", "StaticIntervals", "detect_static",
]
