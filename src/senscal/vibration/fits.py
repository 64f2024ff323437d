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

__all__ = ["PairFit", "fit_pair", "AngleSync", "cut_whole_revolutions", "fit_against_angle", "angle_step",
           "angle_grid", "EncoderAngle", "encoder_angle", "EncoderEffect", "encoder_effect"]

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
            f"turntable angle does not turn steadily one way at data row {i + 1} (step {direction * d[i - 1]:g} deg); "
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
    # The slope's standard error from the residuals directly: linregress's (1 - r^2) form rounds to 0 when
    # the angle is nearly exact (r = 1 to double precision), which would state u = 0.
    res = pp - (lr.intercept + lr.slope * tt)
    sxx = float(np.sum((tt - tt.mean()) ** 2))
    u_f = math.sqrt(float(np.sum(res * res)) / max(tt.size - 2, 1) / sxx) if sxx > 0 else math.inf
    return AngleSync(start, stop, revs, direction, float(lr.slope), u_f)


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


# ---------------------------------------------------------------------------
# Quantised turntable encoders
# ---------------------------------------------------------------------------

# Steps finer than this (deg) are not told from float round-off of a written angle
# (2^28 counts per revolution are 1.3e-6 deg).
_STEP_TOL_DEG = 1e-6
# Offsets of the count grid against the true angle over which the encoder's effect is averaged
# (stratified: the 95 % quantile of a bounded error to about 1/32 of its range).
_GRID_OFFSETS = 32


def _float_gcd(a: float, b: float, tol: float) -> float:
    while b > tol:
        a, b = b, math.fmod(a, b)
        if a - b <= tol:  # remainder one tolerance short of a full step: it is the step
            b = 0.0
    return a


def _grid(values: np.ndarray) -> float | None:
    """Greatest common divisor (1e-6 deg round-off) of positive numbers, when all are whole multiples of it."""
    v = values[values > _STEP_TOL_DEG]
    if v.size < 2:
        return None
    g = float(v.min())
    for x in v:
        g = _float_gcd(float(x), g, _STEP_TOL_DEG)
        if g < 100 * _STEP_TOL_DEG:
            return None
    k = v / g
    return g if np.max(np.abs(k - np.round(k))) <= 0.01 else None


def angle_grid(angle_deg, t) -> tuple[float | None, bool, bool]:
    """The grid a quantised angle channel's readings lie on, and whether they lie on a constant-speed line.

    Parameters
    ----------
    angle_deg : array_like, shape (N,)
        Angle readings in degrees (wrapped or cumulative).
    t : array_like, shape (N,)
        Time stamps in s.

    Returns
    -------
    grid_deg : float or None
        The grid spacing in degrees: the greatest common divisor of the
        readings themselves (with 360: a counter reads whole counts from its
        zero) or, failing that, of the gaps between distinct readings; None
        when the readings lie on no grid.
    through_zero : bool
        The readings are whole multiples of the grid (a counter's readings).
    on_line : bool
        The readings depart from a constant-speed line by less than 1 % of
        the grid: the angle advances a whole number of grid steps per sample,
        so nothing in the record shows how fine the encoder really is.
    """
    a = np.asarray(angle_deg, dtype=float)
    if a.size < 3 or not np.all(np.isfinite(a)):
        return None, False, False
    v = np.unique(np.mod(a, 360.0))
    if v.size < 3:
        return None, False, False
    g_vals = _grid(np.append(v, 360.0))
    g_gaps = _grid(np.diff(v))
    g = g_vals if g_vals is not None else g_gaps
    if g is None:
        return None, False, False
    tc = np.asarray(t, dtype=float) - float(np.mean(t))
    u = np.unwrap(a, period=360.0)
    dev = u - np.polyval(np.polyfit(tc, u, 1), tc)
    return g, g_vals is not None, bool(np.ptp(dev) <= 0.01 * g)


def angle_step(angle_deg, t) -> float | None:
    """Step size of a quantised angle channel (an incremental encoder's count), degrees.

    The readings of an encoder with ``L`` counts per revolution are multiples
    of ``360 / L``.  The step is the greatest common divisor of the readings
    (with 360), or of the gaps between the distinct readings (Euclid's
    algorithm with a round-off tolerance of 1e-6 deg), accepted when every one
    is a whole number of steps to 1 % of a step and the readings depart from a
    constant-speed line by more than 1 % of a step (:func:`angle_grid`).  The
    last condition tells a quantised angle from an exact one sampled at a
    rational fraction of a revolution (10 samples a turn repeat 10 angles, 36
    deg apart, without any quantisation); it also means that a quantised angle
    whose increment per sample is a whole number of steps cannot be measured
    (its readings lie on a line, one constant error below the true angle):
    declare the encoder then (``encoder_lines``).

    Parameters
    ----------
    angle_deg : array_like, shape (N,)
        Angle readings in degrees (wrapped or cumulative).
    t : array_like, shape (N,)
        Time stamps in s.

    Returns
    -------
    float or None
        The step in degrees, or None for a channel that is not quantised
        (a float angle, an interpolated encoder) or where it cannot be told.
    """
    g, _, on_line = angle_grid(angle_deg, t)
    return None if g is None or on_line else g


@dataclass(frozen=True)
class EncoderAngle(ResultMixin):
    """The turntable angle a fit uses, when the encoder is quantised.

    Attributes
    ----------
    step_deg : float or None
        Encoder step in degrees (declared ``360 / lines`` or detected from the
        readings); None when the angle is not quantised.
    detected : bool
        True when the step came from the readings (:func:`angle_step`).
    model : str
        ``"readings"`` (the angle as recorded) or ``"straight line"`` (a
        constant-speed line through the quantised readings, used when the
        readings stay within one step of it: the quantisation is then
        averaged over the record instead of entering every sample).
    angle_deg : ndarray
        The angle the output is fitted against, degrees (unwrapped).
    unresolved_grid_deg : float or None
        Set when the readings are whole multiples of this grid and advance a
        whole number of it per sample, no step being declared: the
        encoder's own step cannot be told from the record (it may be the
        grid or any divisor of it), and every reading may be off by up to
        one count, the same for all.
    """

    step_deg: float | None
    detected: bool
    model: str
    angle_deg: np.ndarray
    unresolved_grid_deg: float | None = None


def encoder_angle(angle_deg, t, *, step_deg: float | None = None) -> EncoderAngle:
    """The angle to fit an already cut record against, and the encoder's step.

    A quantised reading ``r = theta - e`` carries an error ``e`` of up to one
    step in the *regressor*; when the turntable turns at constant speed
    within the quantisation (every reading within one step of a straight line
    in time), the line through the readings is the better angle: it averages
    the steps over the record.  With speed variations larger than a step the
    readings themselves are used.  Either way :func:`encoder_effect` gives the
    error the step leaves in the fitted amplitude and phase.

    Parameters
    ----------
    angle_deg : array_like, shape (N,)
        Angle readings of the cut record, degrees.
    t : array_like, shape (N,)
        Time stamps in s.
    step_deg : float, optional
        Declared step (``360 / counts per revolution``); the detected step is
        used when it is coarser (the readings cannot be finer than they are).

    Returns
    -------
    EncoderAngle
    """
    a = np.unwrap(np.asarray(angle_deg, dtype=float), period=360.0)
    grid, through_zero, on_line = angle_grid(angle_deg, t)
    found = None if on_line else grid
    step, detected = step_deg, False
    if found is not None and (step is None or found > step * (1 + 1e-6)):
        step, detected = found, True
    if step is None:
        return EncoderAngle(None, False, "readings", a, grid if (on_line and through_zero) else None)
    t = np.asarray(t, dtype=float)
    line = np.polyval(np.polyfit(t - t.mean(), a, 1), t - t.mean())
    dev = a - line
    # Pure quantisation keeps every reading within one step of the line (the error lies in [0, step));
    # 10 % more allows for the line's own estimation error.
    if np.ptp(dev) <= 1.1 * step:
        return EncoderAngle(float(step), detected, "straight line", line)
    return EncoderAngle(float(step), detected, "readings", a)


def _quantile_with_noise(delta: np.ndarray, u_fit: float, level: float = 0.95) -> float:
    """Half-width ``x`` with ``P(|delta + n| <= x) = level``, ``delta`` uniform over the samples, ``n ~ N(0, u_fit^2)``."""
    from scipy.special import ndtr

    d = np.abs(np.asarray(delta, dtype=float))
    if u_fit <= 0:
        return float(np.quantile(d, level))
    lo, hi = 0.0, float(d.max()) + 4.0 * u_fit
    for _ in range(3):  # the coverage grows monotonically with x: bracket it on a grid, three times finer each pass
        xs = np.linspace(lo, hi, 65)
        cov = np.mean(ndtr((xs[:, None] - d) / u_fit) - ndtr((-xs[:, None] - d) / u_fit), axis=1)
        i = int(np.searchsorted(cov, level))
        lo, hi = xs[max(i - 1, 0)], xs[min(i, xs.size - 1)]
    return 0.5 * (lo + hi)


@dataclass(frozen=True)
class EncoderEffect(ResultMixin):
    """What a quantised encoder leaves in a fit against the angle (:func:`encoder_effect`).

    Attributes
    ----------
    u_amplitude, u_phase : float
        The component for the record's own budget: combined with the fit's
        u by root sum of squares it gives the 95 % half-width ``U / 2`` of the
        bounded-plus-normal sum (output unit, rad).
    sd_amplitude, sd_phase : float
        The standard deviations of the effect over the grid positions: the
        standard uncertainty to propagate when the record's phase is combined
        with other records' (their bounded errors add up to a nearly normal sum).
    """

    u_amplitude: float
    u_phase: float
    sd_amplitude: float
    sd_phase: float


def encoder_effect(enc: EncoderAngle, t, amplitude: float, phase: float, *, u_amplitude: float, u_phase: float,
                   harmonics: int = 1, drift: bool = False) -> EncoderEffect:
    """Type B standard uncertainties the encoder step leaves in a fit against the angle.

    The error of a quantised angle depends on where the count grid lies
    against the true angle, which no record shows: it is uniform over one
    step.  The fit is repeated, noise-free, on :data:`_GRID_OFFSETS` grid
    positions spread over a step: the true angle is the smooth model of the
    record (the constant-speed line), the output ``A sin(angle + phi)``, the
    readings that angle quantised on the shifted grid (reading the centre of
    each count) and the angle fitted against them processed as the record's
    was (:attr:`EncoderAngle.model`).  The spread of the fitted amplitude and
    phase is the quantisation's effect through this record's own sampling
    (aliased steps included), a Monte-Carlo propagation of a rectangular
    input (JCGM 101).  Its distribution is bounded, not normal, so it is
    combined with the fit's normal ``u`` into the 95 % half-width ``U`` of
    the sum, and the component returned is ``sqrt((U/2)^2 - u_fit^2)``: the
    budget's rule ``U = 2 sqrt(sum u^2)`` then gives that 95 % interval.

    Parameters
    ----------
    enc : EncoderAngle
        From :func:`encoder_angle` (``step_deg`` set).
    t : array_like, shape (N,)
        Time stamps of the cut record, s.
    amplitude, phase : float
        The fitted amplitude (output unit) and phase at angle 0 (rad).
    u_amplitude, u_phase : float
        The fit's own standard uncertainties.
    harmonics, drift :
        As the record's fit.

    Returns
    -------
    EncoderEffect
    """
    if enc.step_deg is None or not amplitude > 0:
        return EncoderEffect(0.0, 0.0, 0.0, 0.0)
    t = np.asarray(t, dtype=float)
    a = np.asarray(enc.angle_deg, dtype=float)
    sign = 1.0 if a[-1] >= a[0] else -1.0
    tc = t - t.mean()
    truth = np.polyval(np.polyfit(tc, sign * a, 1), tc)  # increasing, as fit_against_angle makes it
    step = float(enc.step_deg)
    off = (np.arange(_GRID_OFFSETS) + 0.5) / _GRID_OFFSETS * step
    read = step * (np.floor((truth[None, :] + off[:, None]) / step) + 0.5) - off[:, None]
    if enc.model == "straight line":
        # the same constant-speed line through each set of readings (tc is centred: closed form)
        slope = (read @ tc) / float(tc @ tc)
        read = read.mean(axis=1)[:, None] + slope[:, None] * tc[None, :]
    psi_true = np.radians(truth)
    y = amplitude * np.sin(psi_true + phase)
    psi = np.radians(read)
    cols = []
    for k in range(1, harmonics + 1):
        cols += [np.sin(k * psi), np.cos(k * psi)]
    cols.append(np.ones_like(psi))
    if drift:
        cols.append(np.broadcast_to(psi_true - psi_true.mean(), psi.shape))
    x = np.stack(cols, axis=1)                        # (M, p, N)
    g = np.matmul(x, x.transpose(0, 2, 1))
    b = x @ y
    c = np.linalg.solve(g, b[..., None])[..., 0]
    amp = np.hypot(c[:, 0], c[:, 1])
    ph = np.arctan2(c[:, 1], c[:, 0])
    d_amp = amp - amplitude
    d_ph = np.asarray(wrap_phase(ph - phase))
    out = []
    for d, u in ((d_amp, float(u_amplitude)), (d_ph, float(u_phase))):
        half = _quantile_with_noise(d, u)
        out.append(math.sqrt(max((0.5 * half) ** 2 - u * u, 0.0)))
    return EncoderEffect(out[0], out[1], float(np.sqrt(np.mean(d_amp**2))), float(np.sqrt(np.mean(d_ph**2))))
