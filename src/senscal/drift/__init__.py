"""Slow-drift bias correction with an augmented Kalman filter (patent CN102564486A).

>>> from senscal.drift import redundant_setup, correct_drift
>>> setup = redundant_setup(["ref", "drift", "thermal"], trusted=["ref"], covariate="temperature")
>>> res = correct_drift(setup, y, t, {"temperature": temp})   # doctest: +SKIP
>>> res.corrected, res.bias, res.bias_std, res.onset_t          # doctest: +SKIP
"""

from senscal.drift.core import DEFAULT_FALSE_ALARM_RATE, DriftResult, correct_drift
from senscal.drift.detect import CusumResult, cusum, cusum_arl, cusum_threshold
from senscal.drift.estimate import NoiseParameter, estimate_levels
from senscal.drift.adequacy import InnovationCheck, innovation_checks, moment_levels
from senscal.drift.model import (Bias, DriftSetup, SignalModel, augmented_model, check_observable, covariate_setup,
                                 known_setup, load_model_yaml, redundant_setup)

__all__ = ["Bias", "SignalModel", "DriftSetup", "redundant_setup", "covariate_setup", "known_setup", "load_model_yaml",
           "InnovationCheck", "innovation_checks", "moment_levels",
           "augmented_model", "check_observable", "correct_drift", "DriftResult", "NoiseParameter",
           "estimate_levels", "cusum", "cusum_arl", "cusum_threshold", "CusumResult", "DEFAULT_FALSE_ALARM_RATE"]
