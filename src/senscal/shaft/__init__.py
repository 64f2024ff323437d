"""Rotating shaft: gravity identification and compensation; angular acceleration from one accelerometer.

A single-axis accelerometer mounted tangentially on a shaft measures
``r * alpha`` plus the component of gravity along the tangent, a sinusoid of
the shaft angle unless the shaft is vertical.  :func:`calibrate_gravity`
identifies that sinusoid from a constant-speed run against the encoder
angle; :func:`compensate` removes it from any later run and returns the
tangential and angular acceleration, validated against the encoder's own
second derivative (``shared/METHODS.md`` section 1c, seed 000).
"""

from senscal.shaft.angle import EncoderKinematics, angle_to_rad, encoder_kinematics
from senscal.shaft.compensate import ShaftCompensation, centripetal_leakage, compensate
from senscal.shaft.model import G, GravityModel, calibrate_gravity, load_model

__all__ = ["G", "GravityModel", "EncoderKinematics", "ShaftCompensation", "angle_to_rad", "calibrate_gravity",
           "centripetal_leakage", "compensate", "encoder_kinematics", "load_model"]
