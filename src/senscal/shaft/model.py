"""Gravity identification on a rotating shaft: the calibration and its model.

A single-axis accelerometer mounted tangentially at radius ``r`` on a shaft
whose axis is tilted by ``tilt`` from the horizontal reads, in its output
unit (sensitivity ``S``)::

    a(theta) = S * (r * alpha + g cos(tilt) sin(theta + phi_0)) + bias + noise

At (nearly) constant speed ``alpha ~ 0`` and the reading is a sinusoid of
the encoder angle: fitting ``amplitude * sin(theta + phase) + offset``
against the angle (not time) identifies the gravity term whatever the speed
ripple does to the time axis [1]_.

References
----------
.. [1] Yang X., Li C., Mu D., Chen C., "New application of the sinusoidal
   excitation method in sensor calibration", Transducer and Microsystem
   Technologies, 2014 (seed 000, experiment 2, eq. 11 and fig. 4;
   ``shared/METHODS.md`` section 1c).
.. [2] Wooldridge J. M., "Econometric Analysis of Cross Section and Panel
   Data", MIT Press (2010), ch. 5: instrumental variables (the encoder's
   derivatives over a longer window instrument the short-window ones).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import savgol_coeffs
from scipy.signal.windows import tukey

from senscal._result import ResultMixin
from senscal.errors import DataError, FileFormatError, InputError, TooFewSamplesError
from senscal.diagnostics import named
from senscal.shaft.angle import POLYORDER, angle_to_rad, check_radius, check_uniform, encoder_kinematics, savgol, white_noise_std
from senscal.shaft.estimate import iv_fit, synchronous_residual
from senscal.sinefit import fit_sine, wrap_phase

__all__ = ["G", "GravityModel", "calibrate_gravity", "load_model"]

G = 9.80665
ANGLE_FREQ = 1.0 / (2.0 * math.pi)  # fit_sine against an angle in rad: one cycle per revolution
KIND = "senscal.shaft.GravityModel"
FORMAT_VERSION = 2  # 2: tagged "type" like every saved calibration (senscal.persist); 1 said "kind"
# Largest sensor radius (m) assumed when judging whether once-per-turn speed ripple could bias the fit
# and no radius was given: shaft rigs for sensor calibration are well under a metre.
SYNC_RADIUS_BOUND = 1.0
MIN_TURNS = 10  # turns below which the u's noise level is too uncertain for k=2 to mean 95 %
TAPER = 0.1  # Tukey window of the gravity fit: cosine over the first and last 5 % of the samples
ECC_ALPHA = 1e-3  # false-alarm probability of each encoder angle-error test (chi-square, 2 dof)


@dataclass(frozen=True)
class GravityModel(ResultMixin):
    """The identified gravity term of a tangential accelerometer on a shaft.

    ``gravity(theta) = amplitude * sin(theta + phase) + offset`` in the
    accelerometer's output unit, ``theta`` the encoder angle in rad.  The
    model saves and loads itself as JSON (:meth:`save`, :func:`load_model`)
    with its ``kind`` and ``format_version``, and checks the data it is
    applied to (:meth:`check_applicable`).

    Attributes
    ----------
    amplitude, u_amplitude : float
        Peak gravity amplitude, output unit (``S g cos(tilt)``).
    phase, u_phase : float
        Phase at encoder zero, rad, in (-pi, pi].
    offset, u_offset : float
        Constant term, output unit: sensor bias plus the centripetal leakage
        of a misaligned axis at the calibration speed.
    covariance : ndarray, shape (3, 3)
        Covariance of (amplitude, phase, offset): from the residual's noise
        density near the rotation frequency (and near zero for the offset),
        plus what the estimated ripple coefficients contribute.
    residual_rms : float
        RMS of the per-sample residuals, output unit.
    noise : float
        White noise of the accelerometer, output unit, from the output minus
        its Savitzky-Golay smoothing (``residual_rms`` also holds the encoder
        differentiator's noise the ripple correction brings in, almost all of
        it far above the rotation frequency, where it does not reach the fit).
    sensitivity, u_sensitivity : float
        Output unit per m/s^2 (1 when the output is in m/s^2).
    output_unit : str
        Unit of the accelerometer channel at calibration ('' if unknown).
    g : float
        Local gravity, m/s^2.
    tilt, u_tilt : float
        Shaft tilt from horizontal, rad: ``acos(amplitude / (S g))``.
    bias, u_bias : float
        ``offset / S`` in m/s^2.
    revolutions : float
        Turns covered by the calibration run.
    n_samples : int
        Samples used.
    mean_speed : float
        Mean angular velocity, rad/s (sign = direction).
    mean_square_speed : float
        Mean of ``w^2`` over the run, rad^2/s^2 (reference of the centripetal leakage).
    speed_variation : float
        Standard deviation of the speed over its mean (ratio).
    angular_acceleration_rms : float
        RMS angular acceleration from the encoder, rad/s^2.
    ripple_correction : str
        How encoder-measured angular acceleration was kept out of the fit:
        ``"regression"`` (coefficient estimated with the fit), ``"radius"``
        (``S r alpha`` subtracted for a given radius) or ``"none"``.
    ripple_coefficient : float
        Output per unit encoder angular acceleration (``S r cos(d)``),
        output unit / (rad/s^2); NaN when the run has too little speed
        variation to estimate it.  When estimated, a diagnostic (listed in
        ``diagnostic``): see ``u_centripetal_coefficient``.
    u_ripple_coefficient : float or None
        0 with ``"radius"`` (the given ``S r``), otherwise None: the same
        quantisation bursts read this coefficient low and spread it beyond
        its spectral u on long runs (coverage 70 % on 260 turns, 30 seeds)
        while the u is 1.3x too large on 10 turns.
    ripple_leak : float
        Change of the amplitude caused by the correction (what a plain fit
        would have got wrong), output unit.
    radius : float or None
        Radius given for the ``"radius"`` correction, m.
    window : float
        Savitzky-Golay window of the encoder derivatives, s.
    synchronous_ripple : float
        Relative speed ripple locked to the rotation (once per turn), from
        the encoder's angular acceleration (``w = w0 (1 + m sin(theta + p))``
        gives ``m``).
    centripetal_coefficient : float or None
        Output per unit ``w^2`` (``S r sin(d)`` for a sensitive axis turned by
        ``d`` toward the centre), output unit / (rad/s)^2, when regressed out
        (None when the run's speed variation could not separate it).  A
        diagnostic (listed in ``diagnostic``): see ``u_centripetal_coefficient``.
    u_centripetal_coefficient : None
        Not reported: the encoder's quantisation bursts where its count rate
        crosses a multiple of the sample rate (the reading then advances by
        the same whole number of counts per sample and hides the speed
        change) are neither white nor stationary, and the residual's spectrum
        put this coefficient's u 1.3x too high on 10-60 turns and 1.5x too
        low on 260 (coverage 99 % and about 85 %).  ``shaft compensate
        --centripetal`` measures the misalignment with a u that covers.
        Kept as a field so files from earlier versions load.
    u_angle : float
        Standard uncertainty of the encoder angle (once-per-turn error, RMS
        over a turn) given as a type B input, rad: the prior of the angle
        error estimated from the data (0: none).
    once_per_turn_angle, u_once_per_turn_angle : float
        Once-per-turn deviation of the encoder angle from a steady rotation,
        rad (the encoder's once-per-turn angular acceleration over ``w^2``):
        speed ripple locked to the turn or an eccentric disc.
    twice_per_turn, u_twice_per_turn : float
        Amplitude of the accelerometer's twice-per-turn term against the
        angle, output unit (``amplitude e / 2`` for a once-per-turn angle
        error ``e``).
    angle_error, u_angle_error : float
        Amplitude ``e`` of the once-per-turn angle error ``e sin(theta + q)``
        estimated from the twice-per-turn term (with ``u_angle`` as its prior
        when declared), rad, and its standard uncertainty (per component);
        amplitude, phase and offset are corrected for it and their
        covariance holds the estimate's share.
    angle_error_vector : tuple of float
        ``(e_s, e_c)``, rad: the encoder reads ``theta + e_s sin(theta) +
        e_c cos(theta)``.  :meth:`gravity` takes encoder angles and undoes
        it, so a later run read by the same encoder is compensated with
        the error's offset and twice-per-turn term as well.
    encoder_step : float or None
        Step of the encoder angle, rad (``2 pi / encoder_lines`` or detected
        in the readings); None when the angle showed no grid.
    encoder_step_detected : bool
        True when the step came from the readings.
    u_encoder_step : tuple of float
        Type B shares of the step in (amplitude, phase, offset) (output
        unit, rad, output unit), in the covariance.
    diagnostic : tuple of str
        Fields reported as diagnostics, without an uncertainty (not to be
        quoted as measurement results).
    nuisance : tuple of str
        Encoder regressors estimated with the gravity term: ``"alpha"``
        (angular acceleration) and/or ``"speed2"`` (``w^2``).
    warnings : tuple of str
        Named warnings (``name: sentence``): ``speed-not-constant``,
        ``synchronous-ripple`` (once-per-turn ripple the run cannot tell from
        gravity), ``encoder-eccentricity`` (a twice-per-turn term beyond noise and
        ``u_angle``: an angle error, estimated and removed, or a nonlinear sensor), ``ripple-not-removed``, ``few-turns`` (under 10 turns: k=2
        covers less than 95 %), ``amplitude-above-g``, ``sensitivity-missing``.
    source : str or None
        File the calibration came from.
    created : str
        UTC time of the calibration (ISO 8601).
    kind, format_version
        Type tag and file format version of the saved model.
    """

    amplitude: float
    phase: float
    offset: float
    u_amplitude: float
    u_phase: float
    u_offset: float
    covariance: np.ndarray
    residual_rms: float
    noise: float
    sensitivity: float
    u_sensitivity: float
    output_unit: str
    g: float
    tilt: float
    u_tilt: float
    bias: float
    u_bias: float
    revolutions: float
    n_samples: int
    mean_speed: float
    mean_square_speed: float
    speed_variation: float
    angular_acceleration_rms: float
    ripple_correction: str
    ripple_coefficient: float
    u_ripple_coefficient: float | None
    ripple_leak: float
    radius: float | None
    window: float
    synchronous_ripple: float = 0.0
    centripetal_coefficient: float | None = None
    u_centripetal_coefficient: float | None = None
    nuisance: tuple[str, ...] = ()
    u_angle: float = 0.0
    once_per_turn_angle: float = 0.0
    u_once_per_turn_angle: float = 0.0
    twice_per_turn: float = 0.0
    u_twice_per_turn: float = 0.0
    angle_error: float = 0.0
    u_angle_error: float = 0.0
    angle_error_vector: tuple[float, float] = (0.0, 0.0)
    encoder_step: float | None = None
    encoder_step_detected: bool = False
    u_encoder_step: tuple[float, ...] = (0.0, 0.0, 0.0)
    diagnostic: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    source: str | None = None
    created: str = ""
    kind: str = KIND
    format_version: int = FORMAT_VERSION

    # -- the model -------------------------------------------------------------
    def gravity(self, theta) -> np.ndarray:
        """Gravity term (output unit) at encoder angles ``theta`` (rad, unwrapped or not).

        The encoder's estimated once-per-turn error (``angle_error_vector``) is undone first: the
        shaft's angle is ``theta - e_s sin(theta) - e_c cos(theta)`` to first order.
        """
        th = np.asarray(theta, dtype=float)
        e_s, e_c = self.angle_error_vector
        if e_s or e_c:
            th = th - (e_s * np.sin(th) + e_c * np.cos(th))
        return self.amplitude * np.sin(th + self.phase) + self.offset

    def u_gravity(self, theta) -> np.ndarray:
        """Standard uncertainty of :meth:`gravity` from the fit covariance, output unit."""
        x = np.asarray(theta, dtype=float) + self.phase
        jac = np.stack([np.sin(x), self.amplitude * np.cos(x), np.ones_like(x)], axis=-1)
        return np.sqrt(np.einsum("...i,ij,...j->...", jac, np.asarray(self.covariance), jac))

    def check_applicable(self, *, accel_unit: str | None = None) -> None:
        """Check that an accelerometer channel may be compensated with this model.

        Parameters
        ----------
        accel_unit : str, optional
            Unit of the accelerometer channel ('' or None when unknown); must
            be the calibration's (as a unit: ``m/s²`` is ``m/s^2``) when both are known.

        Raises
        ------
        InputError
            The units differ (another sensor or a rescaled channel).

        Notes
        -----
        :func:`senscal.shaft.compensate` also checks the data themselves:
        a gravity term left after compensation (sensor remounted, another
        sensor, wrong angle zero) is reported as a warning.
        """
        from senscal.persist.units import unit_factor

        # The engine takes arrays as they are: another scale is refused here (the shaft-compensate job
        # converts the channel before it gets here), another dimension always.
        scale = unit_factor(accel_unit, self.output_unit, what="the accelerometer channel",
                            fix="convert the channel or recalibrate with this sensor")
        if scale != 1.0:
            raise InputError(f"the accelerometer channel is in {accel_unit!r} but the sensor was calibrated in "
                             f"{self.output_unit!r}; multiply it by {scale:g} first")

    # -- persistence -----------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (phases also in degrees)."""
        d = super().to_dict()
        d["phase_deg"] = math.degrees(self.phase)
        d["u_phase_deg"] = math.degrees(self.u_phase)
        d["tilt_deg"] = math.degrees(self.tilt)
        d["u_tilt_deg"] = math.degrees(self.u_tilt)
        return d

    def save(self, path: str | Path) -> Path:
        """Write the model as JSON, or HDF5 for a ``.h5``/``.hdf5`` path (folders created).

        The file carries ``type`` and ``format_version``
        (:mod:`senscal.persist`); :func:`senscal.load_calibration` and
        :func:`load_model` read it back.
        """
        from senscal.persist import document, write_document

        return write_document(document(KIND, self.to_dict(), drop=("kind",)), path, what="model file")

    def apply(self, accel, angle, *, angle_unit: str = "rad", unit: str | None = None) -> np.ndarray:
        """Remove gravity from accelerometer readings: what the sensor measured besides gravity.

        Parameters
        ----------
        accel : array_like
            Accelerometer output, output unit of the calibration.
        angle : array_like, same shape
            Encoder angle at each reading, in ``angle_unit``.
        angle_unit : {"rad", "deg"}
        unit : str, optional
            Unit of ``accel``; refused when it differs from the calibration's
            (compared as units: ``m/s²`` equals ``m/s^2``).

        Returns
        -------
        ndarray
            ``(accel - gravity(angle)) / sensitivity``: the tangential
            acceleration (plus the centripetal leakage at the calibration
            speed), m/s^2.  :func:`senscal.shaft.compensate` also derives the
            angular acceleration and checks the result.
        """
        self.check_applicable(accel_unit=unit)
        theta = angle_to_rad(np.asarray(angle, dtype=float).ravel(), angle_unit).reshape(np.shape(angle))
        a = np.asarray(accel, dtype=float)
        if a.shape != theta.shape:
            raise InputError(f"accel and angle must have the same shape, got {a.shape} and {theta.shape}")
        return (a - self.gravity(theta)) / self.sensitivity

    @classmethod
    def from_document(cls, d: dict[str, Any], *, source: str = "model") -> "GravityModel":
        """Rebuild a model from a saved document (version 1 tagged ``kind``, version 2 ``type``)."""
        if isinstance(d, dict) and d.get("type") == KIND:
            d = {**{k: v for k, v in d.items() if k != "type"}, "kind": KIND}
        return cls.from_dict(d, source=source)

    @classmethod
    def from_dict(cls, d: dict[str, Any], *, source: str = "model") -> "GravityModel":
        """Rebuild a model from :meth:`to_dict` output, checking its type and version."""
        if not isinstance(d, dict) or d.get("kind") != KIND:
            kind = d.get("kind") if isinstance(d, dict) else type(d).__name__
            raise FileFormatError(f"{source} is not a senscal shaft gravity model (kind={kind!r}); "
                                  "give the MODEL.json written by 'senscal shaft calibrate --out'")
        from senscal.persist import check_version

        check_version(d, source)
        names = {f.name for f in dataclasses.fields(cls)}
        kw = {k: v for k, v in d.items() if k in names}
        missing = [f.name for f in dataclasses.fields(cls)
                   if f.name not in kw and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
        if missing:
            raise FileFormatError(f"{source} lacks the field(s) {', '.join(missing)}; recalibrate to rewrite it")
        for k in ("amplitude", "phase", "offset", "u_amplitude", "u_phase", "u_offset", "sensitivity", "g"):
            if not isinstance(kw[k], (int, float)) or not math.isfinite(kw[k]):
                raise FileFormatError(f"{source} has a non-numeric '{k}' ({kw[k]!r}); recalibrate to rewrite it")
        from senscal.io.sidefiles import array_field

        kw["covariance"] = array_field(kw["covariance"], (3, 3), f"'covariance' in {source}")
        kw["warnings"] = tuple(kw.get("warnings") or ())
        kw["nuisance"] = tuple(kw.get("nuisance") or ())
        if "angle_error_vector" in kw:
            kw["angle_error_vector"] = tuple(float(v) for v in kw["angle_error_vector"])
        if "u_encoder_step" in kw:
            kw["u_encoder_step"] = tuple(float(v) for v in kw["u_encoder_step"])
        kw["format_version"] = FORMAT_VERSION  # the object is today's, whichever layout it was read from
        return cls(**kw)


def load_model(path: str | Path) -> GravityModel:
    """Read a :class:`GravityModel` written by :meth:`GravityModel.save` (JSON or HDF5, any version).

    Same as ``senscal.load_calibration(path)`` but refuses other calibration types.
    """
    from senscal.persist import load_calibration

    return load_calibration(path, expect=KIND)


# ---------------------------------------------------------------------------
# Calibration
# ---------------------------------------------------------------------------

def time_step(n: int, t, fs) -> float:
    if (t is None) == (fs is None):
        raise InputError("give the time stamps t (s) or the sample rate fs (Hz), exactly one of them")
    if t is None:
        fs = float(fs)
        if not (math.isfinite(fs) and fs > 0):
            raise InputError(f"sample rate fs must be a positive number of Hz, got {fs!r}")
        return 1.0 / fs
    t = np.asarray(t, dtype=float)
    if t.shape != (n,):
        raise InputError(f"t must hold one time stamp per sample ({n}), got shape {t.shape}")
    return check_uniform(t)


def check_accel(accel, n: int | None = None) -> np.ndarray:
    a = np.asarray(accel, dtype=np.float64)
    if a.ndim != 1 or (n is not None and a.size != n):
        raise InputError(f"the accelerometer channel must be 1-D with one sample per angle sample ({n}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DataError(f"the accelerometer channel has NaN or inf in data row {int(np.flatnonzero(~np.isfinite(a))[0]) + 1}; "
                        "remove or interpolate bad samples first")
    peak = float(np.max(np.abs(a))) if a.size else 0.0
    if peak > 1e150:
        # Least squares squares the data: beyond 1e154 the squares overflow float64 (same rule as fit_sine).
        raise DataError(f"the accelerometer channel reaches {peak:.3g}, too large for a least-squares fit "
                        "(its squares overflow); check the unit or rescale the data")
    return a


def by_angle(theta: np.ndarray, *ys: np.ndarray):
    """Samples sorted by angle, repeated encoder readings merged (weights = counts).

    The gravity term is a function of the angle only, so the order of the
    samples does not matter; merging equal angles keeps the least-squares
    problem identical while giving the fit a strictly increasing abscissa.
    """
    order = np.argsort(theta, kind="stable")
    x = theta[order]
    ux, inv, cnt = np.unique(x, return_inverse=True, return_counts=True)
    if ux.size == x.size:
        return ux, None, [y[order] for y in ys]
    return ux, cnt.astype(float), [np.bincount(inv, y[order]) / cnt for y in ys]


def fit_angle(y, x, w=None):
    # The white-noise path: the samples are sorted by angle (not time), so the sine engine's noise tests
    # (lag-one whiteness, phase-dependent variance, low-frequency noise) would judge an ordering, not the
    # noise, and the shaft sets its own covariance (senscal.shaft.estimate).
    return fit_sine(y, x, freq=ANGLE_FREQ, weights=w, noise_model="white")


def calibrate_gravity(accel, angle, t=None, *, fs: float | None = None, angle_unit: str = "rad",
                      sensitivity: float = 1.0, u_sensitivity: float = 0.0, output_unit: str = "",
                      radius: float | None = None, ripple_correction: bool = True, g: float = G,
                      window: float = 0.1, max_speed_variation: float = 0.10, u_angle: float = 0.0,
                      encoder_lines: int | None = None, source: str | None = None) -> GravityModel:
    """Identify the gravity term seen by a tangential accelerometer on a shaft.

    Fits ``amplitude * sin(theta + phase) + offset`` to the accelerometer
    against the unwrapped encoder angle (the three-parameter sine fit with
    the angle as abscissa), so speed ripple does not distort the sinusoid.
    The samples are weighted by a Tukey window (5 % cosine ends) and the
    uncertainties come from the residual's noise density near the rotation
    frequency (:func:`senscal.shaft.estimate.spectral_meat`), not from its
    total variance: the encoder differentiator's noise is large per sample
    but lies far above the rotation frequency, and coloured accelerometer
    noise is counted where it matters.

    Parameters
    ----------
    accel : array_like, shape (N,)
        Accelerometer output (output unit: m/s^2 or V, ...).
    angle : array_like, shape (N,)
        Encoder angle in ``angle_unit``; wrapped angles are unwrapped.  Must
        not reverse during the run.
    t : array_like, shape (N,), optional
        Time stamps, s (uniform).  Give ``t`` or ``fs``.
    fs : float, optional
        Sample rate, Hz.
    angle_unit : {"rad", "deg"}
        Unit of ``angle``.
    sensitivity : float
        Output per m/s^2 (1 for an output in m/s^2), used for the tilt and
        the bias in m/s^2.
    u_sensitivity : float
        Standard uncertainty of ``sensitivity``.
    output_unit : str
        Unit of ``accel``, stored so compensation can check it.
    radius : float, optional
        Radius of the sensor, m.  When given, ``sensitivity * radius *
        alpha_encoder`` is subtracted before the fit (works for ripple locked
        to the rotation too); the centripetal term ``w^2`` is still regressed.
    ripple_correction : bool
        Without ``radius``: estimate the response to the encoder's angular
        acceleration and to ``w^2`` (centripetal term of a misaligned axis)
        together with the gravity term (instrumental variables [2]_), so
        speed ripple does not leak into the fit.  The coefficients are learnt
        from speed variation that differs from turn to turn (judged after
        removing the regressors' synchronous part, all harmonics of the
        angle) and then remove the once-per-turn part as well; their
        uncertainty enters the reported covariance.  A run whose only speed
        variation repeats with the angle cannot separate them: the named
        warning ``synchronous-ripple`` says so.  False gives the plain three-parameter fit of the paper [1]_.
    g : float
        Local gravity, m/s^2.
    window : float
        Savitzky-Golay window for the encoder derivatives, s.
    max_speed_variation : float
        Speed standard deviation over mean speed above which a warning says
        the run was not at constant speed.
    u_angle : float
        Standard uncertainty of the encoder angle from a once-per-turn
        error (an eccentric or tilted disc: the RMS over a turn of
        ``e sin(theta + q)``, i.e. ``e / sqrt(2)``), rad: the encoder's
        accuracy specification, a type B input.  The angle error is always
        estimated from the accelerometer's twice-per-turn term (amplitude
        ``amplitude * e / 2``) and removed from the offset (which it moves by
        ``(amplitude e / 2) sin(q - phase)``) and, through the ripple
        regressors, from amplitude and phase (``b w^2 e``), its noise carried
        into u (about 1.9x u(offset) and 1.4x u(amplitude) at 1 rev/s and
        r = 0.1 m); ``u_angle`` is the estimate's normal prior (0: none).
        A twice-per-turn term beyond noise (and beyond ``u_angle``) is named
        ``encoder-eccentricity``: a nonlinear sensor's would be corrected
        as an angle error.
    encoder_lines : int, optional
        Counts per revolution of the encoder: its step ``2 pi / lines`` is an
        error in the fit's abscissa.  Without it the step is detected in the
        angle channel (readings on a grid, :func:`senscal.vibration.fits.angle_grid`);
        either way its effect on amplitude, phase and offset, propagated
        through this record's own sampling and smoothing over the grid's
        position (:func:`_encoder_step_effect`), is a type B share of the
        covariance.  Readings that advance a whole number of grid steps per
        sample do not show the step (every reading may lie up to half a count
        from the angle, the same for all, which moves the phase by up to that):
        named ``encoder-step-unknown`` unless ``encoder_lines`` is given.
    source : str, optional
        Where the data came from (stored in the model).

    Returns
    -------
    GravityModel

    Raises
    ------
    TooFewSamplesError
        Less than one full revolution.
    DataError
        NaN/inf, a reversing angle, irregular time stamps.
    InputError
        Bad arguments (sensitivity <= 0, radius <= 0, ...).

    References
    ----------
    .. [1] Yang X., Li C., Mu D., Chen C., Transducer and Microsystem
       Technologies, 2014 (seed 000, experiment 2; METHODS.md 1c).
    .. [2] Wooldridge J. M., Econometric Analysis of Cross Section and Panel
       Data (2010), ch. 5.
    """
    theta = angle_to_rad(angle, angle_unit, monotonic=True)
    n = theta.size
    a = check_accel(accel, n)
    if not (math.isfinite(sensitivity) and sensitivity > 0):
        raise InputError(f"sensitivity must be a positive number (output per m/s^2), got {sensitivity!r}")
    if not (math.isfinite(u_sensitivity) and u_sensitivity >= 0):
        raise InputError(f"u_sensitivity must be >= 0, got {u_sensitivity!r}")
    if not (math.isfinite(g) and g > 0):
        raise InputError(f"g must be a positive acceleration in m/s^2, got {g!r}")
    if radius is not None:
        radius = check_radius(radius)
    if not (math.isfinite(u_angle) and 0.0 <= u_angle < math.pi):
        raise InputError(f"u_angle (--u-angle-deg) must be a standard uncertainty >= 0 of the angle, got {u_angle!r}")
    if encoder_lines is not None and not (isinstance(encoder_lines, (int, np.integer, float))
                                          and float(encoder_lines).is_integer() and encoder_lines >= 4):
        raise InputError(f"encoder lines (--encoder-lines) must be a whole number of counts per revolution (>= 4), "
                         f"got {encoder_lines!r}")
    revs = abs(float(theta[-1] - theta[0])) / (2.0 * math.pi)
    if revs < 1.0:
        raise TooFewSamplesError(
            f"the calibration run covers only {revs:.3g} revolutions ({math.degrees(abs(theta[-1] - theta[0])):.4g} deg); "
            "record at least one full revolution (several are better), or check --angle-unit"
        )
    dt = time_step(n, t, fs)
    kin = encoder_kinematics(theta, dt, window=window)
    e = kin.edge
    w_in = kin.angular_velocity[e:n - e] if n > 2 * e + 2 else kin.angular_velocity
    al_in = kin.angular_acceleration[e:n - e] if n > 2 * e + 2 else kin.angular_acceleration
    mean_speed = float(np.mean(w_in))
    speed_var = float(np.std(w_in) / abs(mean_speed)) if mean_speed != 0 else math.inf
    m = kin.window_samples
    # Regressors: quintic Savitzky-Golay derivatives, flat to 0.1 % up to about 1/(4 window) (the cubic ones
    # lose 5 % at 2.7 Hz for 0.1 s): one coefficient must serve the once-per-turn ripple and the rest alike.
    m5 = max(m, 7) if n >= 7 else m
    p5 = 5 if m5 >= 7 else POLYORDER
    # The angular acceleration's coefficient (S r) is quoted with a u, so its regressor must be flatter
    # still: the quintic second derivative droops 0.07 % at 2.7 Hz for 0.1 s, which read the coefficient
    # high by 1.2 u on a 60-turn run (81 % coverage); a septic one over 1.3 windows droops 1e-5 there,
    # for 18 % more quantisation noise.
    m7 = int(round(1.3 * m)) | 1
    m7, p7 = (m7, 7) if 9 <= m7 <= n else (m5, p5)
    x_al = savgol(theta, m7, 2, dt, polyorder=p7)
    x_w = savgol(theta, m5, 1, dt, polyorder=p5)
    # Instruments: the same derivatives over a window three times longer.  Their quantisation noise is far
    # smaller, so the coefficients are not pulled toward zero by the noise in the regressors (errors in
    # variables), as least squares would be.
    ml = min(n - 1 + n % 2, 3 * m)
    z_al = savgol(theta, ml, 2, dt)
    z_w = savgol(theta, ml, 1, dt)
    # The filters extrapolate over their first and last half window: keep those samples out of the
    # fit when the encoder's derivatives are used, unless that would leave < 1 revolution.
    mode = "radius" if radius is not None else ("regression" if ripple_correction else "none")
    ei = max(ml, m5, m7) // 2
    keep = slice(ei, n - ei) if n > 2 * ei + 2 and abs(theta[n - ei - 1] - theta[ei]) >= 2.0 * math.pi \
        else slice(0, n)
    # The abscissa is the smoothed angle: the encoder's quantisation would otherwise be an error in
    # the variable (amplitude * step / sqrt(12) of extra residual and a small sinc bias of the amplitude).
    # Quintic, like the regressors: a cubic window rounds off the speed ripple's angle excursions and puts
    # sidebands of the gravity sinusoid next to the rotation frequency.
    th_fit = savgol(theta, m5, 0, dt, polyorder=p5)
    tk = th_fit[keep]
    d = np.column_stack([np.sin(tk), np.cos(tk), np.ones_like(tk)])
    yk = a[keep] - (sensitivity * radius * x_al[keep] if radius is not None else 0.0)
    # The residual's periodogram smoothed over +/- the rotation frequency (one bin per turn each side):
    # the noise density near the rotation frequency (and near each regressor's own frequencies), not the
    # residual's total variance, which the differentiator's noise far above the rotation frequency dominates.
    hw = max(1, int(round(abs(float(theta[keep][-1] - theta[keep][0])) / (2.0 * math.pi))))
    # Samples weighted by a Tukey window (5 % cosine ends): an abruptly truncated sinusoid has spectral
    # sidelobes that would pick up the differentiator's noise tens of hertz away; the taper costs 2 % in u.
    taper = tukey(tk.size + 2, TAPER)[1:-1]
    # Bins the fit empties (zero, and the rotation frequency with the taper's main lobe) stay out of the
    # density averages: they would bias it low.
    empty = [0, 1, 2, hw - 2, hw - 1, hw, hw + 1, hw + 2]
    s2 = kin.angle_noise ** 2
    w2 = x_w[keep] ** 2
    w2z = z_w[keep] ** 2
    cands = {
        "alpha": (x_al[keep], z_al[keep], s2 * _kernel_dot(m7, p7, ml, 2, dt)),
        # Centripetal term of a misaligned axis, S sin(d) r w^2: w^2 noise is 2 w dw.
        "speed2": (w2 - w2.mean(), w2z - w2z.mean(), 4.0 * float(np.mean(w2)) * s2 * _kernel_dot(m5, p5, ml, 1, dt)),
    }
    # The coefficients may be learnt only from speed variation that differs from turn to turn: whatever
    # repeats with the angle (ripple locked to the rotation with all its harmonics, an encoder's
    # once-per-turn error, the quantisation pattern of a speed that is itself a function of the angle)
    # is collinear with the gravity sinusoid or shares the encoder's angle-locked error, and a coefficient
    # fixed by a few per cent of second harmonic carries that error, amplified by the regressor's variance
    # inflation against the angle, into the gravity term.  So the identifying variation is measured after
    # removing the synchronous part: the harmonics within the instrument's main lobe (three cycles per
    # long window, where its response is down to 0.6 % of a derivative's) exactly, the rest by the
    # synchronous average (one bin per sample of a turn: every harmonic the sampling resolves).
    per_turn = tk.size / max(abs(float(tk[-1] - tk[0])) / (2.0 * math.pi), 1.0)
    sync_bins = max(1, int(round(per_turn)))
    # At most 16 by least squares (a slow shaft's main lobe holds hundreds, and N x (2K + 1) columns would
    # not fit): the synchronous average leaves about pi k / (sqrt(3) bins) of harmonic k inside its bins,
    # which for k = 17 and bins = per_turn > 16 ml / 3 is below 3.2 / ml (1 % for the default 0.3 s
    # instrument at 1 kHz) of a harmonic that the smooth regressors hardly hold.
    sync_harm = min(int(math.ceil(3.0 * per_turn / ml)) + 1, 16)
    info = {}
    for name, (xv, zv, cvv) in cands.items():
        xt, zt = synchronous_residual(tk, np.column_stack([xv, zv]), sync_bins, sync_harm).T
        cross = float(np.mean(xt * zt))
        # Fraction by which the noise the two derivatives share could pull the coefficient (x2 for
        # quantisation that is not white): the instrument must see real, non-synchronous variation.
        eps = 2.0 * abs(cvv) / abs(cross) if cross != 0 else math.inf
        if not math.sqrt(float(np.mean(xt * xt))) > 1e-6 * float(np.mean(w2)):
            # No speed variation beyond rounding (a steady drive read by an encoder whose readings advance a
            # whole number of counts per sample): nothing to learn a coefficient from.
            eps = math.inf
        sc, cvx, _ = iv_fit(xv, d, d, hw, empty, taper=taper)
        amp_x = math.hypot(sc[0], sc[1])
        gx = np.array([sc[0], sc[1]]) / amp_x if amp_x > 0 else np.zeros(2)
        u_amp_x = math.sqrt(max(float(gx @ cvx[:2, :2] @ gx), 0.0))
        info[name] = {"eps": eps, "sync": amp_x, "u_sync": u_amp_x, "x": xv, "z": zv}
    wanted = {"regression": ["alpha", "speed2"], "radius": ["speed2"], "none": []}[mode]

    # The twice-per-turn term (an angle error's trace, estimated below) is fitted with the gravity term so
    # that its line, at the edge of the density's band around the rotation frequency, does not lift the
    # density behind u (0.05 deg: u(amplitude) 1.3x too large); over whole turns it is orthogonal to gravity.
    d2 = np.column_stack([np.sin(2.0 * tk), np.cos(2.0 * tk)])
    empty2 = sorted(set(empty) | {2 * hw + j for j in range(-2, 3)})

    def solve(names, y):
        mm = np.column_stack([d] + [info[k]["x"] for k in names] + [d2])
        ww = np.column_stack([d] + [info[k]["z"] for k in names] + [d2])
        coef, cov, res = iv_fit(y, mm, ww, hw, empty2, taper=taper)
        return coef[:-2], cov[:-2, :-2], res

    def gravity_cov(coef, cov):
        s_, c_ = coef[0], coef[1]
        amp_ = math.hypot(s_, c_)
        jac = np.array([[s_ / amp_, c_ / amp_, 0.0], [-c_ / amp_**2, s_ / amp_**2, 0.0], [0.0, 0.0, 1.0]])
        return jac @ cov[:3, :3] @ jac.T

    used = [k for k in wanted if info[k]["eps"] < 0.5]
    coef, cov, res = solve(used, yk)
    # A coefficient biased by eps moves the gravity term by up to eps |b| times its regressor's
    # once-per-turn amplitude; kept only while that stays below 0.3 u (k=2 coverage >= 94.5 %).
    u_amp0 = math.sqrt(gravity_cov(coef, cov)[0, 0])
    drop = [k for i, k in enumerate(used) if info[k]["eps"] * abs(coef[3 + i]) * info[k]["sync"] > 0.3 * u_amp0]
    if drop:
        used = [k for k in used if k not in drop]
        coef, cov, res = solve(used, yk)
    b_of = {k: float(coef[3 + i]) for i, k in enumerate(used)}
    removed = np.column_stack([info[k]["x"] for k in used]) @ coef[3:] if used else 0.0
    x, cnt, (ya, tw) = by_angle(tk, (yk - removed) * taper, taper)
    wts = tw if cnt is None else tw * cnt
    ya = ya / tw
    fit = fit_angle(ya, x, wts)
    cov_g = gravity_cov(coef, cov)
    amp, ph, off = float(fit.amplitude), float(fit.phase), float(fit.offset)
    w_mean2 = float(np.mean(w2)) if w2.size else 0.0
    # A once-per-turn angle error e sin(theta + q) (eccentric or tilted encoder disc) moves the fit against
    # the angle by (amplitude e / 2) sin(q - phase) in the offset, with a twice-per-turn term of the same
    # size, and puts a once-per-turn e w^2 into the encoder's angular acceleration that no speed ripple made:
    # the regressors remove b e w^2 of gravity (b: their coefficients, S r for the radius correction).
    # The twice-per-turn term of the accelerometer against the angle: an angle error's signature (or a
    # sensor's own nonlinearity, which the fit does not model either), tested against its noise density.
    res_g = (yk - removed) - fit.amplitude * np.sin(tk + fit.phase) - fit.offset
    c2, cov2, _ = iv_fit(res_g, d2, d2, hw, empty2, taper=taper)
    twice = float(math.hypot(c2[0], c2[1]))
    u_twice = math.sqrt(max(float(np.trace(cov2)) / 2.0, 0.0))
    # Ripple locked to the rotation is a sinusoid of the angle like gravity: only speed variation at
    # other frequencies (or a known radius) tells its effect apart.  A regressor left out matters when
    # its once-per-turn part is real (5 sigma: false alarm < 4e-6) and could move the amplitude by more
    # than 0.3 u for a plausible coefficient: S r with r <= SYNC_RADIUS_BOUND for the tangential term,
    # S r sin(1 deg) for the centripetal term of a misaligned axis (u before the angle-error correction).
    r_bound = radius if radius is not None else SYNC_RADIUS_BOUND
    coef_bound = {"alpha": sensitivity * r_bound, "speed2": sensitivity * r_bound * math.sin(math.radians(1.0))}
    u_amp0 = math.sqrt(max(float(cov_g[0, 0]), 0.0))
    lost = [k for k in (("alpha", "speed2") if mode == "none" else wanted) if k not in used
            and info[k]["sync"] > 5.0 * info[k]["u_sync"] and coef_bound[k] * info[k]["sync"] > 0.3 * u_amp0]
    ecc_est = None
    # Unmodelled once-per-turn ripple has harmonics of its own (S r alpha holds m^2 / 2 of the second):
    # its twice-per-turn term is not an angle error's, and the run is named synchronous-ripple instead.
    if amp > 0 and not lost:
        # The angle error is estimated from its twice-per-turn trace, as nuisance parameters, and its
        # effects removed, with the estimate's noise carried into u; a declared accuracy (u_angle) is its
        # prior.  Naming it instead would not do: the twice-per-turn term's noise per component is about
        # sqrt 2 u(offset), so an offset error of 2 u(offset) has only 1.4 sigma of signature.
        amp, ph, off, cov_g, ecc_est = _correct_angle_error(
            amp, ph, off, cov_g, c2, cov2, theta, keep, tk, taper, dt, (m7, p7), (m5, p5), x_w[keep],
            b_of.get("alpha", sensitivity * radius if mode == "radius" else 0.0), b_of.get("speed2", 0.0),
            u_angle)
    # The encoder's step: declared, or the grid the readings lie on; its effect through this record's own
    # sampling is a type B share, and a grid the readings cannot resolve is named unless declared.
    from senscal.vibration.fits import angle_grid

    grid_deg, through_zero, on_line = angle_grid(np.degrees(theta), np.arange(n) * dt)
    step = None if encoder_lines is None else 2.0 * math.pi / float(encoder_lines)
    step_detected = False
    if grid_deg is not None and not on_line and (step is None or math.radians(grid_deg) > step * (1 + 1e-6)):
        step, step_detected = math.radians(grid_deg), True
    unresolved_deg = grid_deg if (step is None and on_line and through_zero) else None
    step_u = np.zeros(3)
    # Only readings on a constant-speed line hide the step (one error, the same for all samples): with any
    # other sampling the step's error varies along the record and the residual's spectrum carries it.
    if step is not None and on_line and amp > 0:
        step_u = _encoder_step_effect(tk, taper, (m5, p5), step, amp, ph, off,
                                      np.sqrt(np.maximum(np.diag(cov_g), 0.0)))
        cov_g = cov_g + np.diag(step_u**2)
    u = np.sqrt(np.maximum(np.diag(cov_g), 0.0))
    rms = float(np.sqrt(np.mean(res**2)))
    noise = white_noise_std(a, kin.window_samples)
    # What removing the ripple changed (or, without the correction, what it would have changed).
    plain_coef = solve([], a[keep])[0]
    amp_plain = math.hypot(plain_coef[0], plain_coef[1])
    if mode == "none":
        diag = [k for k in ("alpha", "speed2") if info[k]["eps"] < 0.5]
        dcoef = solve(diag, yk)[0] if diag else plain_coef
        leak = amp_plain - math.hypot(dcoef[0], dcoef[1])
        b_al = float(dcoef[3]) if "alpha" in diag else math.nan
    else:
        leak = amp_plain - amp
        b_al = b_of.get("alpha", math.nan)
    # Relative speed ripple at the rotation frequency: alpha = w0^2 m cos(theta + p) for w = w0 (1 + m sin).
    sync_rel = info["alpha"]["sync"] / w_mean2 if w_mean2 > 0 else 0.0

    # Tilt from horizontal: cos(tilt) = amplitude / (S g).
    ratio = amp / (sensitivity * g)
    u_ratio = math.hypot(u[0] / (sensitivity * g), ratio * u_sensitivity / sensitivity)
    tilt = math.acos(min(max(ratio, -1.0), 1.0))
    # Near a horizontal shaft acos is not linear: tilt ~ sqrt(2 (1 - ratio)) has spread ~ sqrt(2 u).
    u_tilt = u_ratio / math.sqrt(max(1.0 - min(ratio, 1.0) ** 2, 2.0 * u_ratio))
    bias = off / sensitivity
    u_bias = math.hypot(u[2] / sensitivity, bias * u_sensitivity / sensitivity)

    warnings = []
    if speed_var > max_speed_variation:
        warnings.append(named("speed-not-constant", (
            f"the speed varied by {100 * speed_var:.3g}% (std/mean, limit {100 * max_speed_variation:.3g}%); "
            "angular acceleration leaks into the gravity fit, calibrate at a steadier speed")))
    # Once-per-turn ripple a regressor left out (lost, above) is named.
    if mode == "radius" and "speed2" in lost:
        per_deg = coef_bound["speed2"] * info["speed2"]["sync"]
        warnings.append(named("synchronous-ripple", (
            f"the speed varies once per turn ({100 * sync_rel:.3g}% ripple locked to the rotation) and the run "
            "holds too little other speed variation to tell the centripetal term of a misaligned sensitive axis "
            f"from gravity: amplitude and phase may be off by {per_deg:.3g} per degree of misalignment "
            f"({per_deg / u[0]:.3g} u); calibrate with speed variation that is not once per turn")))
    elif lost:
        warnings.append(named("synchronous-ripple", (
            f"the speed varies once per turn ({100 * sync_rel:.3g}% ripple, angular acceleration "
            f"{info['alpha']['sync']:.3g} rad/s^2 locked to the rotation) and the run holds too little other speed "
            "variation to tell its effect from gravity: amplitude, phase and tilt are off by S r times that, "
            "beyond their u (and the offset is not corrected for an angle error, whose twice-per-turn trace the ripple's "
            "harmonics would mimic); give the sensor radius (--radius) or calibrate at a steadier speed")))
    if mode == "none" and "alpha" not in lost and abs(leak) > 2.0 * u[0] and math.isfinite(leak):
        warnings.append(named("ripple-not-removed", (
            f"angular acceleration during the run moved the gravity amplitude by about {leak:.3g} "
            f"({abs(leak) / u[0]:.3g} standard uncertainties) and was NOT removed: enable the ripple correction "
            "or give the radius")))
    # The encoder's angle error.  Its once-per-turn part reads like speed ripple locked to the turn, which
    # one run at one speed cannot tell apart (both put e w^2 into the encoder's angular acceleration, and
    # gravity absorbs what they do to the accelerometer); its twice-per-turn trace in the accelerometer is
    # amplitude e / 2.  Both are tested against their noise (chi-square, 2 dof, false alarm ECC_ALPHA), beyond
    # what the declared accuracy u_angle explains (a once-per-turn error of RMS u_angle has amplitude
    # sqrt(2) u_angle; k=2: 2 sqrt(2) u_angle).
    crit = math.sqrt(-2.0 * math.log(ECC_ALPHA))  # chi-square with 2 dof: P(> c) = exp(-c / 2)
    e_max = 2.0 * math.sqrt(2.0) * u_angle
    e_once = info["alpha"]["sync"] / w_mean2 if w_mean2 > 0 else 0.0
    u_e_once = info["alpha"]["u_sync"] / w_mean2 if w_mean2 > 0 else math.inf
    e_twice = 2.0 * twice / abs(amp) if amp else 0.0
    # The estimate and its removal assume the twice-per-turn term is an angle error's; a nonlinear sensor's
    # would be corrected wrongly, so a term beyond noise is named (chi-square, 2 dof, false alarm ECC_ALPHA),
    # beyond what a declared accuracy explains (a once-per-turn error of RMS u_angle has amplitude sqrt(2)
    # u_angle; k=2: 2 sqrt(2) u_angle), where the prior would pull the estimate short of it.
    twice_seen = twice - abs(amp) * e_max / 2.0 > crit * u_twice
    # Ripple locked to the turn that the run could not model is named by synchronous-ripple already, and its
    # unmodelled harmonics (S r alpha has m^2 / 2 of second harmonic) are twice-per-turn too: one warning a cause.
    if twice_seen and not lost:
        if u_angle > 0.0:
            how = (f"beyond the declared accuracy ({math.degrees(u_angle):.2g} deg), which pulls the estimate short "
                   "of it: offset, amplitude and phase may be off beyond their u; give --u-angle-deg 0 to estimate "
                   "it from the data alone, or check the disc's centring")
        else:
            how = ("estimated from that term and removed from offset, amplitude and phase (their u include the "
                   "estimate's noise); a nonlinear sensor's twice-per-turn term would be removed wrongly: check the "
                   "disc's centring")
        warnings.append(named("encoder-eccentricity", (
            f"the accelerometer has a twice-per-turn term of {twice:.3g} ({twice / u_twice:.3g} u), the trace of "
            f"a {math.degrees(e_twice):.2g} deg once-per-turn angle error (or of a nonlinear sensor); {how}")))
    if unresolved_deg is not None:
        warnings.append(named("encoder-step-unknown", (
            f"the angle readings are whole multiples of {unresolved_deg:.4g} deg and advance a whole number of them "
            "per sample, so the encoder's count step cannot be told from this record: every reading may lie up to "
            "half a count from the angle, the same for all, which moves the phase by up to that and is not in its "
            "u; give --encoder-lines N (counts per revolution) or sample at a rate that is not a whole number of "
            "counts per sample")))
    if hw < MIN_TURNS:
        # The density behind u rests on about four degrees of freedom per turn: below 10 turns (40) k=2
        # covers less than 94.8 % (Student's t), 88 % for one turn.
        warnings.append(named("few-turns", (
            f"the fit covers only {hw} turns, so the noise level behind the uncertainties rests on about "
            f"{4 * hw} degrees of freedom and k=2 covers less than 95 %; record at least {MIN_TURNS} turns")))
    unit = str(output_unit or "").strip()
    if unit and sensitivity == 1.0 and unit.replace(" ", "").replace("²", "^2") not in ("m/s^2", "m/s2", "ms^-2", "m*s^-2"):
        warnings.append(named("sensitivity-missing", (
            f"the accelerometer output is in '{unit}' but no sensitivity was given: tilt and bias assume m/s^2; "
            "give the sensitivity (output per m/s^2)")))
    if ratio - 1.0 > 3.0 * u_ratio:
        warnings.append(named("amplitude-above-g", (
            f"gravity amplitude {amp:.6g} exceeds sensitivity * g = {sensitivity * g:.6g}; check --sensitivity "
            "(the output may not be in m/s^2)")))
    kc = b_of.get("speed2")
    return GravityModel(
        amplitude=amp, phase=float(wrap_phase(ph)), offset=off, u_amplitude=float(u[0]), u_phase=float(u[1]),
        u_offset=float(u[2]), covariance=cov_g, residual_rms=rms, noise=noise, sensitivity=float(sensitivity),
        u_sensitivity=float(u_sensitivity), output_unit=str(output_unit or ""), g=float(g), tilt=tilt,
        u_tilt=u_tilt, bias=bias, u_bias=u_bias, revolutions=revs, n_samples=int(res.size), mean_speed=mean_speed,
        mean_square_speed=w_mean2, speed_variation=speed_var,
        angular_acceleration_rms=float(np.sqrt(np.mean(al_in**2))), ripple_correction=mode,
        ripple_coefficient=float(sensitivity * radius if mode == "radius" else b_al),
        u_ripple_coefficient=0.0 if mode == "radius" else None,
        ripple_leak=float(leak), radius=radius, window=kin.window, synchronous_ripple=float(sync_rel),
        centripetal_coefficient=kc, u_centripetal_coefficient=None,
        diagnostic=tuple(k for k, v in (("ripple_coefficient", mode != "radius" and math.isfinite(b_al)),
                                        ("centripetal_coefficient", kc is not None)) if v),
        nuisance=tuple(used), u_angle=float(u_angle), once_per_turn_angle=float(e_once),
        u_once_per_turn_angle=float(u_e_once), twice_per_turn=twice, u_twice_per_turn=float(u_twice),
        encoder_step=None if step is None else float(step), encoder_step_detected=step_detected,
        u_encoder_step=tuple(float(v) for v in step_u),
        angle_error=0.0 if ecc_est is None else float(math.hypot(ecc_est[0], ecc_est[1])),
        angle_error_vector=(0.0, 0.0) if ecc_est is None else (float(ecc_est[0]), float(ecc_est[1])),
        u_angle_error=0.0 if ecc_est is None else float(math.sqrt(max(np.trace(ecc_est[2]) / 2.0, 0.0))),
        warnings=tuple(warnings), source=source,
        created=_dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat(),
    )


# Positions of the count grid against the angle over which the step's effect is spread (stratified: the
# 95 % quantile of a bounded error to about 1/32 of its range, as senscal.vibration.fits.encoder_effect).
_GRID_OFFSETS = 32


def _half_width_with_noise(d: np.ndarray, u: float, level: float = 0.95) -> float:
    """``x`` with ``P(|d + n| <= x) = level``, ``d`` uniform over its values, ``n ~ N(0, u^2)`` (bisection)."""
    from scipy.special import ndtr

    d = np.abs(np.asarray(d, dtype=float))
    if u <= 0:
        return float(np.quantile(d, level))
    lo, hi = 0.0, float(d.max()) + 4.0 * u
    for _ in range(60):
        x = 0.5 * (lo + hi)
        cov = float(np.mean(ndtr((x - d) / u) - ndtr((-x - d) / u)))
        lo, hi = (x, hi) if cov < level else (lo, x)
    return 0.5 * (lo + hi)


def _encoder_step_effect(tk, taper, w_filter, step, amp, ph, off, u_fit) -> np.ndarray:
    """Type B standard uncertainties of (amplitude, phase, offset) from an encoder step ``step`` (rad).

    Where the count grid lies against the true angle no record shows: uniform over one step.  For
    :data:`_GRID_OFFSETS` grid positions the smoothed angle (the fit's abscissa, standing in for the
    true angle) is read on the shifted grid (nearest count), smoothed as the record was, and the
    noise-free gravity term refitted against it with the record's taper: the spread of the fitted
    values is the step's effect through this record's sampling (a Monte-Carlo propagation of a
    rectangular input, JCGM 101).  It is bounded, so it is combined with the fit's normal u into the
    95 % half-width U of the sum, and the share returned is ``sqrt((U / 2)^2 - u_fit^2)``.
    """
    from scipy.signal import savgol_filter

    m5, p5 = w_filter
    truth = np.asarray(tk, dtype=float)
    line = truth[0] + (truth[-1] - truth[0]) * np.arange(truth.size) / max(truth.size - 1, 1)
    offs = (np.arange(_GRID_OFFSETS) + 0.5) / _GRID_OFFSETS * step
    read = step * np.round((truth[None, :] + offs[:, None]) / step) - offs[:, None]
    if m5 < truth.size:
        read = savgol_filter(read - line, m5, p5, axis=-1, mode="interp") + line
    sw = np.sqrt(taper)
    y = (amp * np.sin(truth + ph) + off) * sw
    vals = []
    for r in read:
        dd = np.column_stack([np.sin(r), np.cos(r), np.ones_like(r)]) * sw[:, None]
        c = np.linalg.lstsq(dd, y, rcond=None)[0]
        vals.append([math.hypot(c[0], c[1]), math.atan2(c[1], c[0]), c[2]])
    vals = np.array(vals)
    dv = vals - np.array([amp, ph, off])
    dv[:, 1] = (dv[:, 1] + math.pi) % (2.0 * math.pi) - math.pi
    out = []
    for j in range(3):
        half = _half_width_with_noise(dv[:, j], float(u_fit[j]))
        out.append(math.sqrt(max((0.5 * half) ** 2 - float(u_fit[j]) ** 2, 0.0)))
    return np.array(out)


def _correct_angle_error(amp, ph, off, cov_g, c2, cov2, theta, keep, tk, taper, dt, al_filter, w_filter, w_keep,
                         b_alpha, b_speed2, u_angle=0.0):
    """Gravity term and offset corrected for a once-per-turn angle error estimated from its twice-per-turn trace.

    The encoder reads ``phi = theta + e_s sin(theta) + e_c cos(theta)``.  Against ``phi`` the gravity
    sinusoid ``A sin(theta + ph)`` becomes ``A sin(phi + ph) - A eps cos(phi + ph)``: an offset
    ``(A / 2)(e_s sin ph - e_c cos ph)`` and a twice-per-turn term ``T = -(A / 2) R(ph) e`` (``R`` the
    rotation by ``ph``), so ``e = -(2 / A) R(ph)^T T``.  The regressors see ``eps`` too: the angular
    acceleration ``eps''`` (about ``-w^2 eps``) and ``w^2`` (``2 w eps'``), whose coefficients move their
    once-per-turn part into the gravity term; that part is computed through the regressors' own filters.
    All is linear in ``T``: the corrections and their covariance ``J cov(T) J^T`` (``T`` is estimated
    at twice the rotation frequency, independent of the gravity fit's noise) are applied to
    (amplitude, phase, offset).  A declared accuracy ``u_angle`` (rad, per component of ``e``) is a
    normal prior: the estimate is then the posterior mean ``(C^-1 + I / u_angle^2)^-1 C^-1 e_T``
    with ``C`` the covariance of ``e_T`` from ``T``, and its covariance the posterior's.

    Returns
    -------
    amp, ph, off, cov_g, (e_s, e_c, cov_e)
    """
    rot = np.array([[math.cos(ph), -math.sin(ph)], [math.sin(ph), math.cos(ph)]])
    to_e = -(2.0 / amp) * rot.T  # e = to_e @ T
    # Gravity (sin, cos coefficients): minus the once-per-turn projection of b d(alpha) + k d(w^2) per unit e.
    sw = np.sqrt(taper)
    dd = np.column_stack([np.sin(tk), np.cos(tk), np.ones_like(tk)]) * sw[:, None]
    m7, p7 = al_filter
    m5, p5 = w_filter
    cols = []
    for unit in (np.sin(theta), np.cos(theta)):
        d_al = savgol(unit, m7, 2, dt, polyorder=p7)[keep] if b_alpha else 0.0
        d_w2 = 2.0 * w_keep * savgol(unit, m5, 1, dt, polyorder=p5)[keep] if b_speed2 else 0.0
        pert = -(b_alpha * d_al + b_speed2 * d_w2) * np.ones_like(tk)
        cols.append(np.linalg.lstsq(dd, pert * sw, rcond=None)[0][:2])
    jac_e = np.vstack([np.column_stack(cols), (amp / 2.0) * np.array([[math.sin(ph), -math.cos(ph)]])])
    e_t = to_e @ np.asarray(c2, dtype=float)
    cov_e = to_e @ np.asarray(cov2, dtype=float) @ to_e.T
    if u_angle > 0.0:
        prec = np.linalg.inv(cov_e)
        cov_e = np.linalg.inv(prec + np.eye(2) / u_angle**2)
        e_t = cov_e @ prec @ e_t
    dv = jac_e @ e_t
    gs, gc = amp * math.cos(ph) - dv[0], amp * math.sin(ph) - dv[1]
    amp2 = math.hypot(gs, gc)
    ph2 = math.atan2(gc, gs)
    off2 = off - dv[2]
    # (G_s, G_c, offset) -> (amplitude, phase, offset)
    jg = np.array([[gs / amp2, gc / amp2, 0.0], [-gc / amp2**2, gs / amp2**2, 0.0], [0.0, 0.0, 1.0]])
    cov_add = jg @ jac_e @ cov_e @ jac_e.T @ jg.T
    return amp2, ph2, off2, cov_g + cov_add, (float(e_t[0]), float(e_t[1]), cov_e)


def _kernel_dot(m_short: int, p_short: int, m_long: int, deriv: int, dt: float) -> float:
    """``sum h_short h_long`` of two centred Savitzky-Golay derivative kernels (their shared white-noise gain)."""
    hs = savgol_coeffs(m_short, p_short, deriv=deriv, delta=dt)
    hl = savgol_coeffs(m_long, POLYORDER, deriv=deriv, delta=dt)
    if hs.size > hl.size:
        hs, hl = hl, hs
    pad = (hl.size - hs.size) // 2
    return float(np.dot(np.pad(hs, (pad, hl.size - hs.size - pad)), hl))
