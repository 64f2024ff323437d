"""Vibration calibration: velocity-sensor sensitivity against a position
reference, accelerometer frequency response (known input or back-to-back),
double-centrifuge angle synchronisation, amplitude linearity, GUM budgets.

References
----------
.. [1] Yang et al., Transducer and Microsystem Technologies 2014 (seed 000;
   ``shared/METHODS.md`` section 1b).
.. [2] Qin Chaojun, double-centrifuge dynamic calibration (seed 003;
   METHODS.md section 4).
.. [3] ISO 16063-21:2003, calibration by comparison to a reference transducer.
"""

from senscal.vibration.budget import (BudgetComponent, MeanBudget, UncertaintyBudget, coverage_factor, make_budget,
                                     mean_with_budget, welch_satterthwaite)
from senscal.vibration.fits import AngleSync, PairFit, cut_whole_revolutions, fit_against_angle, fit_pair
from senscal.vibration.linearity import AmplitudeLinearity, LinearityPoint, amplitude_linearity
from senscal.vibration.response import (FrequencyResponse, PhaseReference, RepeatedPoint, ResponsePoint,
                                        apply_phase_reference, combine_repeats, frequency_response, load_response,
                                        phase_reference_run, response_point, save_response)
from senscal.vibration.velocity import VelocityCalibration, VelocityPoint, velocity_calibration, velocity_point

__all__ = [
    "BudgetComponent", "MeanBudget", "UncertaintyBudget", "coverage_factor", "make_budget", "mean_with_budget",
    "welch_satterthwaite",
    "AngleSync", "PairFit", "cut_whole_revolutions", "fit_against_angle", "fit_pair",
    "AmplitudeLinearity", "LinearityPoint", "amplitude_linearity",
    "FrequencyResponse", "PhaseReference", "RepeatedPoint", "ResponsePoint", "apply_phase_reference",
    "combine_repeats", "frequency_response", "phase_reference_run", "response_point",
    "save_response", "load_response",
    "VelocityCalibration", "VelocityPoint", "velocity_calibration", "velocity_point",
]
