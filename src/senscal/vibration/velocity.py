"""Velocity-sensor sensitivity against a position reference (hydraulic rig).

References
----------
.. [1] Yang et al., "Sinusoidal excitation calibration with a least-squares
   sine fit with offset", Transducer and Microsystem Technologies, 2014
   (seed 000, experiment 1; ``shared/METHODS.md`` section 1b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError
from senscal.sinefit import wrap_phase
from senscal.vibration.budget import UncertaintyBudget, make_budget, mean_with_budget, unique_warnings
from senscal.vibration.fits import fit_pair

__all__ = ["VelocityPoint", "VelocityCalibration", "velocity_point", "velocity_calibration", "reference_sanity",
           "MAX_PLAUSIBLE_MOTION"]

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class VelocityPoint(ResultMixin):
    """Sensitivity of a velocity sensor at one excitation frequency.

    Attributes
    ----------
    source : str
        Where the record came from (file name), may be empty.
    frequency, u_frequency : float
        Excitation frequency and its standard uncertainty, Hz.
    position_amplitude, u_position_amplitude : float
        Peak displacement ``A_p`` in m.
    output_amplitude, u_output_amplitude : float
        Peak sensor output ``A_s`` in the output unit (V).
    sensitivity, u_sensitivity : float
        ``S = A_s / (w A_p)`` in output unit per m/s, standard uncertainty
        (type A from the fits, covariances and the shared frequency included,
        combined with the type B position-reference component).
    phase, u_phase : float
        Phase of the sensor output relative to the true velocity in rad
        (0 for an ideal sensor, negative = lag).
    budget : UncertaintyBudget
        The sensitivity's budget.
    snr_db : float
        Signal-to-noise ratio of the sensor channel fit.
    warnings : tuple of str
        Named warnings raised by the sine fits.
    """

    source: str
    frequency: float
    u_frequency: float
    position_amplitude: float
    u_position_amplitude: float
    output_amplitude: float
    u_output_amplitude: float
    sensitivity: float
    u_sensitivity: float
    phase: float
    u_phase: float
    budget: UncertaintyBudget
    snr_db: float
    warnings: tuple[str, ...] = ()


def velocity_point(position, output, t, *, freq: float | None = None, drift: bool = True, harmonics: int = 1,
                   u_position: float = 0.0, source: str = "", unit: str = "V/(m/s)") -> VelocityPoint:
    """Sensitivity and phase of a velocity sensor from one sinusoidal record.

    Both channels are fitted at one frequency (given, or estimated from the
    position channel); ``S = A_s / (2 pi f A_p)``.  The true velocity is the
    derivative of the position, ``w A_p cos(w t + phi_p)``, so the phase
    relative to it is ``phi_s - phi_p - pi/2``.

    Parameters
    ----------
    position : array_like, shape (N,)
        Position reference in m.
    output : array_like, shape (N,)
        Velocity-sensor output (V).
    t : array_like, shape (N,)
        Time stamps in s.
    freq : float, optional
        Known excitation frequency in Hz.
    drift : bool
        Fit a linear offset drift in both channels (default True: real
        sensors drift, and an unmodelled ramp leaks into the amplitude of a
        record of non-whole periods).
    harmonics : int
        Harmonics of the motion fitted with the fundamental (a servo
        cylinder's motion is not a pure sine; 1 = fundamental only).
    u_position : float
        Type B relative standard uncertainty of the position reference's
        scale (e.g. 0.001 for 0.1 %).
    source : str
        Label (file name) stored with the result.
    unit : str
        Unit of the sensitivity (for the budget).

    Returns
    -------
    VelocityPoint

    References
    ----------
    .. [1] Yang et al. 2014 (seed 000), experiment 1.
    """
    if u_position < 0:
        raise InputError(f"u_position must be a non-negative relative uncertainty, got {u_position!r}")
    pf = fit_pair(position, output, t, freq=freq, drift=drift, harmonics=harmonics)
    f, a_p, a_s = pf.frequency, pf.reference_amplitude, pf.output_amplitude
    if a_p <= 0:
        raise InputError("the position channel has no sinusoidal motion; check --position")
    s = a_s / (TWO_PI * f * a_p)
    jac = np.array([-s / a_p, s / a_s if a_s > 0 else 1.0 / (TWO_PI * f * a_p), 0.0, -s / f])
    u_fit = math.sqrt(max(float(jac @ pf.covariance @ jac), 0.0))
    dof = float(min(getattr(pf.reference, "dof_effective", None) or pf.reference.dof,
                    getattr(pf.output, "dof_effective", None) or pf.output.dof))
    budget = make_budget("sensitivity", s, unit, [("sine fits", "A", u_fit, dof),
                                                  ("position reference", "B", u_position * s)])
    phase = float(wrap_phase(pf.phase_difference - 0.5 * math.pi))
    u_phase = math.sqrt(pf.covariance[2, 2])
    sanity = reference_sanity(f, a_p, phase, u_phase)
    return VelocityPoint(
        source=source, frequency=f, u_frequency=pf.u_frequency,
        position_amplitude=a_p, u_position_amplitude=math.sqrt(pf.covariance[0, 0]),
        output_amplitude=a_s, u_output_amplitude=math.sqrt(pf.covariance[1, 1]),
        sensitivity=s, u_sensitivity=budget.combined,
        phase=phase, u_phase=u_phase,
        budget=budget, snr_db=float(pf.output.snr_db),
        warnings=unique_warnings(*(getattr(f, "warnings", ()) or () for f in (pf.reference, pf.output)), sanity),
    )


#: Largest peak motion a position-referenced velocity calibration plausibly has: displacement (m),
#: velocity (m/s) and acceleration (m/s^2).  Long-stroke hydraulic and electrodynamic exciters move at
#: most about +/-0.5 m, 2-3 m/s and a few hundred m/s^2; a factor of a few above that is no rig, and a
#: reference read in the wrong unit (mm or um taken as m) lands 10^3 or 10^6 beyond it.
MAX_PLAUSIBLE_MOTION = {"displacement": 1.0, "velocity": 10.0, "acceleration": 1.0e4}

#: Two-sided 99.9 % normal quantile: the phase must depart from quadrature by this many u(phase).
_Z_PHASE = 3.29


def reference_sanity(frequency: float, position_amplitude: float, phase: float, u_phase: float) -> tuple[str, ...]:
    """Named warnings when the position reference and the velocity output cannot be what they claim.

    Parameters
    ----------
    frequency : float
        Excitation frequency, Hz.
    position_amplitude : float
        Peak displacement of the position reference, m.
    phase, u_phase : float
        Phase of the sensor output relative to the derivative of the position, and its standard
        uncertainty, rad.

    Returns
    -------
    tuple of str
        ``velocity-not-derivative`` when the output is in antiphase with the derivative of the
        position (``|phase| > 90 deg`` by more than 3.29 u: its in-phase part has the wrong sign):
        the channels are swapped (a velocity leads its position by +90 deg, a swapped pair lags by
        90, so the phase reads about -180 deg), the polarity is inverted, or the sensor works far
        below its natural frequency; ``position-amplitude-implausible`` when the peak displacement,
        velocity ``w A`` or acceleration ``w^2 A`` exceeds :data:`MAX_PLAUSIBLE_MOTION` (a reference
        in mm or um read as m).
    """
    from senscal.diagnostics import named

    out = []
    if abs(phase) > 0.5 * math.pi + _Z_PHASE * u_phase:
        out.append(named("velocity-not-derivative", (
            f"the sensor output is {math.degrees(phase):+.1f} deg from the derivative of the position, i.e. in "
            "antiphase with the velocity (a velocity leads its position by +90 deg; swapped channels read about "
            "-180 deg): check that --position and --velocity are not swapped and the sensor's polarity; only a "
            "sensor far below its natural frequency legitimately shows this")))
    w = TWO_PI * frequency
    motion = {"displacement": position_amplitude, "velocity": w * position_amplitude,
              "acceleration": w * w * position_amplitude}
    over = [k for k, v in motion.items() if v > MAX_PLAUSIBLE_MOTION[k]]
    if over:
        units = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}
        said = ", ".join(f"peak {k} {motion[k]:.3g} {units[k]} (limit {MAX_PLAUSIBLE_MOTION[k]:g})" for k in over)
        out.append(named("position-amplitude-implausible", (
            f"the position reference moves {said} at {frequency:.4g} Hz, beyond any displacement exciter: the "
            "position is probably in mm or um but read as m; give its unit in the header ('position [mm]')")))
    return tuple(out)


@dataclass(frozen=True)
class VelocityCalibration(ResultMixin):
    """Velocity-sensor calibration over several frequency points.

    Attributes
    ----------
    points : tuple of VelocityPoint
    sensitivity : float
        Mean sensitivity over the points, output unit per m/s.
    sensitivity_std : float
        Experimental standard deviation of the point sensitivities.
    u_sensitivity : float
        Combined standard uncertainty of the mean (see ``budget``).
    budget : UncertaintyBudget
        Type A: the fits' own uncertainty of the mean when a chi-square test
        finds the points consistent with it, else the spread over points
        ``s / sqrt(n)`` with ``n - 1`` degrees of freedom and Student k
        (:func:`~senscal.vibration.budget.mean_with_budget`); type B:
        position reference.
    unit : str
    birge_ratio, chi2_p : float
        Scatter of the point sensitivities relative to their fit
        uncertainties, and the chi-square test's p value.
    warnings : tuple of str
        ``excess-scatter`` (the sensitivity varies between points more than
        the fits explain: a frequency dependence or a change between records)
        and the points' fit warnings.
    """

    points: tuple[VelocityPoint, ...]
    sensitivity: float
    sensitivity_std: float
    u_sensitivity: float
    budget: UncertaintyBudget
    unit: str
    birge_ratio: float = float("nan")
    chi2_p: float = float("nan")
    warnings: tuple[str, ...] = ()


def velocity_calibration(points: Sequence[VelocityPoint], *, u_position: float = 0.0,
                         unit: str = "V/(m/s)") -> VelocityCalibration:
    """Mean sensitivity, spread and combined uncertainty over frequency points.

    Parameters
    ----------
    points : sequence of VelocityPoint
        One per record (frequency).
    u_position : float
        Type B relative standard uncertainty of the position reference.
    unit : str
        Sensitivity unit.

    References
    ----------
    .. [1] Yang et al. 2014 (seed 000): mean and standard deviation over the
       ten frequency points of experiment 1.
    """
    if not points:
        raise InputError("give at least one velocity calibration point")
    comps = [p.budget.component("sine fits") for p in points]
    m = mean_with_budget([p.sensitivity for p in points], [c.standard_uncertainty for c in comps],
                         [("position reference", u_position)], "mean sensitivity", unit,
                         fit_dof=[c.dof for c in comps])
    warns = unique_warnings(m.warnings, *(p.warnings for p in points))
    return VelocityCalibration(tuple(points), m.mean, m.std, m.budget.combined, m.budget, unit, m.birge_ratio,
                               m.chi2_p, warns)
