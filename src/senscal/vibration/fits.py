"""Sine fits shared by the vibration jobs: a pair of channels on one frequency,
and double-centrifuge records synchronised to the turntable angle.

References
----------
.. [1] Yang et al., "Sinusoidal excitation calibration with a least-squares
   sine fit with offset", Transducer and Microsystem Technologies, 2014
   (seed 000; ``shared/METHODS.md`` sections 1a, 1b).
.. [2] Qin Chaojun, "Three-parameter cosine fit in double-centrifuge dynamic
   calibration of linear accelerometers" (seed 003; METHODS.md section 4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import DataError, TooFewSamplesError
from senscal.sinefit import SineFit, fit_sine, wrap_phase

__all__ = ["PairFit", "fit_pair", "AngleSync", "cut_whole_revolutions", "fit_against_angle"]

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class PairFit(ResultMixin):
    """Two channels fitted at one shared frequency.

    Attributes
    ----------
    frequency : float
        Shared frequency in Hz (given, or estimated from the reference channel).
    reference_amplitude, output_amplitude : float
        Peak amplitudes in the channels' units.
    phase_difference : float
        ``phase_output - phase_reference`` in rad, wrapped to (-pi, pi].
    covariance : ndarray, shape (4, 4)
        Covariance of ``(reference_amplitude, output_amplitude,
        phase_difference, frequency)``, including the effect of the shared
        frequency estimate on both fits.
    reference, output : SineFit
        The two fits (the output fit is at the reference's frequency; its
        ``u_phase`` is conditional on that frequency).
    u_output_phase : float
        Standard uncertainty of the output's phase at t = 0 including the
        shared frequency's uncertainty (rad).
    """

    frequency: float
    reference_amplitude: float
    output_amplitude: float
    phase_difference: float
    covariance: np.ndarray
    reference: SineFit
    output: SineFit
    u_output_phase: float

    @property
    def u_frequency(self) -> float:
        return math.sqrt(self.covariance[3, 3])


def fit_pair(reference, output, t, *, freq: float | None = None, drift: bool = False, harmonics: int = 1) -> PairFit:
    """Fit a reference and an output channel at one shared frequency.

    The frequency (when not given) comes from a four-parameter fit of the
    reference channel, which has the better signal-to-noise ratio; the output
    is then fitted at that frequency with the closed-form three-parameter fit.
    The error of the shared frequency moves both fits; its effect on the
    output amplitude and phase is taken from a central difference of the
    output fit and propagated with the reference fit's covariance.

    Parameters
    ----------
    reference, output : array_like, shape (N,)
        Samples of the two channels (any units).
    t : array_like, shape (N,)
        Time stamps in s.
    freq : float, optional
        Known excitation frequency in Hz.
    drift : bool
        Fit a linear drift of both offsets.
    harmonics : int
        Harmonics of the excitation fitted with the fundamental in both
        channels (a distorted excitation: the harmonics then neither leak into
        the fundamental of a record of non-whole periods nor count as noise).

    Returns
    -------
    PairFit
    """
    fr = fit_sine(reference, t, freq=freq, drift=drift, harmonics=harmonics)
    f = float(fr.frequency)
    fo = fit_sine(output, t, freq=f, drift=drift, harmonics=harmonics)
    names = fr.parameter_names
    i_a, i_p = names.index("amplitude"), names.index("phase")
    ref_idx = [i_a, i_p] + ([names.index("frequency")] if "frequency" in names else [])
    cov_r = np.asarray(fr.covariance)[np.ix_(ref_idx, ref_idx)]
    cov_o = np.asarray(fo.covariance)[np.ix_([0, 1], [0, 1])]
    if freq is None:
        u_f = float(fr.u_frequency)
        h = max(u_f, 1e-9 * f)
        plus = fit_sine(output, t, freq=f + h, drift=drift, harmonics=harmonics)
        minus = fit_sine(output, t, freq=f - h, drift=drift, harmonics=harmonics)
        d_amp = (plus.amplitude - minus.amplitude) / (2 * h)
        d_ph = float(wrap_phase(plus.phase - minus.phase)) / (2 * h)
        # z = (A_ref, phi_ref, f, A_out | f, phi_out | f): independent blocks.
        cz = np.zeros((5, 5))
        cz[:3, :3] = cov_r
        cz[3:, 3:] = cov_o
        jac = np.array([
            [1, 0, 0, 0, 0],
            [0, 0, d_amp, 1, 0],
            [0, -1, d_ph, 0, 1],
            [0, 0, 1, 0, 0],
        ], dtype=float)
    else:
        cz = np.zeros((4, 4))
        cz[:2, :2] = cov_r
        cz[2:, 2:] = cov_o
        jac = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 1], [0, 0, 0, 0]], dtype=float)
        d_ph = 0.0
    cov = jac @ cz @ jac.T
    u_out_ph = math.sqrt(cov_o[1, 1] + d_ph**2 * cov[3, 3])
    return PairFit(f, float(fr.amplitude), float(fo.amplitude), float(wrap_phase(fo.phase - fr.phase)), cov, fr, fo,
                   u_out_ph)


@dataclass(frozen=True)
class AngleSync(ResultMixin):
    """Where a double-centrifuge record was cut, and the turntable rate.

    Attributes
    ----------
    start, stop : int
        Sample range ``start:stop`` kept: it starts at the first sample after
        a 360 deg crossing and ends before the crossing ``revolutions`` later.
    revolutions : int
        Whole turntable revolutions in the kept record.
    direction : int
        +1 when the angle increases, -1 when it decreases.
    frequency, u_frequency : float
        Turntable rotation frequency and its standard uncertainty in Hz (slope
        of a straight line through angle vs time).
    """

    start: int
    stop: int
    revolutions: int
    direction: int
    frequency: float
    u_frequency: float


def cut_whole_revolutions(angle_deg, t) -> AngleSync:
    """Cut a record to start at a 360 deg crossing and hold whole revolutions.

    This is the seed's acquisition rule (trigger when ``floor(angle / 360)``
    steps) done in software, so every record of a run has the same phase
    origin and holds whole periods.

    Parameters
    ----------
    angle_deg : array_like, shape (N,)
        Turntable angle in degrees, cumulative or wrapped to 360.
    t : array_like, shape (N,)
        Time stamps in s.

    Returns
    -------
    AngleSync

    Raises
    ------
    DataError
        The angle does not turn monotonically one way.
    TooFewSamplesError
        Fewer than one whole revolution lies between two 360 deg crossings.

    References
    ----------
    .. [1] Qin Chaojun (seed 003; ``shared/METHODS.md`` section 4, "Acquisition").
    """
    a = np.unwrap(np.asarray(angle_deg, dtype=float), period=360.0)
    t = np.asarray(t, dtype=float)
    if a.size < 3:
        raise TooFewSamplesError("the angle channel needs at least 3 samples")
    direction = 1 if a[-1] >= a[0] else -1
    psi = direction * a
    d = np.diff(psi)
    if np.any(d <= 0) or np.any(d >= 180.0):
        i = int(np.flatnonzero((d <= 0) | (d >= 180.0))[0]) + 1
        raise DataError(
            f"turntable angle does not turn steadily one way at sample {i} (step {direction * d[i - 1]:g} deg); "
            "the angle channel must be in degrees and sampled at least 2 times per revolution"
        )
    k = np.floor(psi / 360.0)
    steps = np.flatnonzero(np.diff(k) != 0) + 1
    revs = int(k[steps[-1]] - k[steps[0]]) if steps.size >= 2 else 0
    if revs < 1:
        span = (psi[-1] - psi[0]) / 360.0
        raise TooFewSamplesError(
            f"the record holds fewer than one whole turntable revolution between 360 deg crossings "
            f"({span:.2f} revolutions in all); record at least two revolutions"
        )
    start, stop = int(steps[0]), int(steps[-1])
    from scipy.stats import linregress

    tt, pp = t[start:stop], psi[start:stop] / 360.0
    if tt.size < 3:
        raise TooFewSamplesError("fewer than 3 samples in the whole revolutions; sample faster")
    lr = linregress(tt, pp)
    return AngleSync(start, stop, revs, direction, float(lr.slope), float(lr.stderr))


def fit_against_angle(y, angle_deg, *, harmonics: int = 1, drift: bool = False) -> SineFit:
    """Three-parameter fit of an output against the turntable angle.

    Model ``y = A sin(psi + phi) + C`` with ``psi`` the unwrapped angle in rad
    (made increasing): the abscissa is the angle itself, so speed ripple of the
    turntable does not smear the fit, and ``phi`` is the phase at angle 0.

    Parameters
    ----------
    y : array_like, shape (N,)
        Output samples of an already cut record.
    angle_deg : array_like, shape (N,)
        Turntable angle in degrees over the same samples.
    harmonics : int
        Harmonics of the revolution fitted with the fundamental.
    drift : bool
        Also fit an offset drift linear in the angle (in time, at constant speed).

    Returns
    -------
    SineFit
        With ``frequency = 1 / (2 pi)`` cycles per rad.
    """
    a = np.unwrap(np.asarray(angle_deg, dtype=float), period=360.0)
    psi = np.radians(a if a[-1] >= a[0] else -a)
    return fit_sine(y, psi, freq=1.0 / TWO_PI, harmonics=harmonics, drift=drift)
