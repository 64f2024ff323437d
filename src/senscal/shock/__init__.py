"""Shock calibration of accelerometers: ISO 16063-22 (comparison) and ISO 16063-13 (laser primary).

Pure numeric engine: :func:`shock_pulses` gives, for every half-sine pulse of a
record, the peak-ratio sensitivity and the transfer function with their u.
"""

from senscal.shock.core import ShockPulse, TransferFunction, differentiate, find_pulses, lowpass, shock_pulses

__all__ = ["ShockPulse", "TransferFunction", "differentiate", "find_pulses", "lowpass", "shock_pulses"]
