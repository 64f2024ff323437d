"""Accelerometer frequency response: known input (double centrifuge) or
back-to-back comparison with a reference accelerometer.

References
----------
.. [1] Qin Chaojun, "Three-parameter cosine fit in double-centrifuge dynamic
   calibration of linear accelerometers" (seed 003; ``shared/METHODS.md``
   section 4).
.. [2] ISO 16063-21:2003, Vibration calibration by comparison to a reference
   transducer (back-to-back: ``S_dut = S_ref * A_dut / A_ref``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from senscal._result import ResultMixin
from senscal.diagnostics import named
from senscal.errors import DataError, FileFormatError, InputError
from senscal.sinefit import fit_sine, wrap_phase
from senscal.vibration.budget import (BudgetComponent, UncertaintyBudget, make_budget, mean_with_budget,
                                     unique_warnings)
from senscal.vibration.fits import (AngleSync, cut_whole_revolutions, encoder_angle, encoder_effect, fit_against_angle,
                                    fit_pair)

__all__ = ["ResponsePoint", "FrequencyResponse", "RepeatedPoint", "PhaseReference", "response_point",
           "frequency_response", "phase_reference_run", "apply_phase_reference", "combine_repeats",
           "save_response", "load_response"]

# Relative tolerance within which two records are at the same frequency.
_SAME_FREQ = 1e-3

FORMAT = "senscal.vibration.FrequencyResponse"
FORMAT_VERSION = 2  # 2: ".h5" files are HDF5 (senscal.persist); 1 wrote JSON into them


@dataclass(frozen=True)
class ResponsePoint(ResultMixin):
    """Accelerometer sensitivity and phase at one frequency point.

    Attributes
    ----------
    source : str
        Label (file name).
    method : str
        ``"known input"``, ``"known input, angle-synchronised"`` or ``"back-to-back"``.
    frequency, u_frequency : float
        Excitation frequency and standard uncertainty, Hz.
    input_amplitude : float
        Peak input acceleration in m/s^2 (given, or ``A_ref / S_ref``).
    output_amplitude, u_output_amplitude : float
        Peak output of the accelerometer (its unit) from the fit.
    sensitivity, u_sensitivity : float
        ``S_i`` in output unit per m/s^2 with combined standard uncertainty.
    normalized_sensitivity, u_normalized_sensitivity : float or None
        ``S_i / S_0`` (None without a static sensitivity).
    phase, u_phase : float
        Output phase in rad: at t = 0 (time fits) or at turntable angle 0
        (angle-synchronised), sine convention.
    phase_delay, u_phase_delay : float or None
        Output phase minus input phase in rad (negative for a lagging
        sensor); None when the input phase is unknown.
    sensitivity_budget, normalized_budget, phase_delay_budget : UncertaintyBudget or None
        GUM budgets (k=1 components, expanded with k=2).
    sync : AngleSync or None
        Where an angle-synchronised record was cut.
    n_samples : int
        Samples used in the fit.
    snr_db : float
        Output fit signal-to-noise ratio.
    angle_step_deg : float or None
        Step of a quantised turntable encoder (declared or detected in the
        angle channel), degrees; its effect is the budget component
        ``"encoder step"`` of the sensitivity and the phase delay.  None when
        the angle is not quantised (or not used).
    angle_model : str or None
        The angle the output was fitted against: ``"readings"`` or
        ``"straight line"`` (constant-speed line through quantised readings);
        None without an angle channel.
    phase_reference : str
        How the input phase ``phi_0`` behind ``phase_delay`` was obtained:
        ``"entered"``, ``"reference run"``, ``"reference channel"``,
        ``"assumed encoder zero"`` (angle fit without either; warned) or
        ``"none"`` (no phase delay).
    warnings : tuple of str
        Named warnings (``phase-reference-unknown``, and any the sine fit
        raised).
    """

    source: str
    method: str
    frequency: float
    u_frequency: float
    input_amplitude: float
    output_amplitude: float
    u_output_amplitude: float
    sensitivity: float
    u_sensitivity: float
    normalized_sensitivity: float | None
    u_normalized_sensitivity: float | None
    phase: float
    u_phase: float
    phase_delay: float | None
    u_phase_delay: float | None
    sensitivity_budget: UncertaintyBudget
    normalized_budget: UncertaintyBudget | None
    phase_delay_budget: UncertaintyBudget | None
    sync: AngleSync | None
    n_samples: int
    snr_db: float
    phase_reference: str = "none"
    warnings: tuple[str, ...] = ()
    angle_step_deg: float | None = None
    angle_model: str | None = None


def _fit_dof(fit) -> float:
    """Degrees of freedom behind a fit's uncertainties (effective ones when the fit reports them)."""
    nu = getattr(fit, "dof_effective", None)
    return float(fit.dof if nu is None else nu)


def _fit_warnings(*fits) -> tuple[str, ...]:
    out: list[str] = []
    for f in fits:
        for w in getattr(f, "warnings", ()) or ():
            if w not in out:
                out.append(str(w))
    return tuple(out)


def _angle_fit_warnings(fit, enc) -> tuple[str, ...]:
    """The angle fit's warnings, with a ``coloured-noise`` sentence that says what its u really assumes.

    The sine fit's own sentence speaks of a time base; against the turntable
    angle the abscissa is the angle, and with a quantised encoder the
    readings' steps are one cause of a correlated residual.
    """
    out = []
    for w in _fit_warnings(fit):
        if not w.startswith("coloured-noise:"):
            out.append(w)
            continue
        r1 = float(getattr(fit, "residual_lag1", float("nan")))
        if str(getattr(fit, "noise_model", "white")) == "coloured":
            said = ("u of the fit uses the residual's noise spectrum at the turntable frequency (the angle steps are "
                    "uniform)")
        else:
            said = ("u of the fit assumes white noise: the angle steps are not uniform, so no noise spectrum was "
                    "fitted, and u can be too small")
        cause = ("check the output for interference or drift, and the angle channel for speed ripple"
                 if enc.step_deg is None else
                 f"the encoder's {enc.step_deg:.3g} deg steps are in u as the type B component 'encoder step', so a "
                 "residual correlated by them alone is covered; otherwise check the output for interference or drift")
        out.append(named("coloured-noise", (
            f"the output's residual against the turntable angle is correlated (lag-1 autocorrelation {r1:.2f}); "
            f"{said}; {cause}")))
    return tuple(out)


def _check_rel(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value) or value < 0:
        raise InputError(f"{name} must be a non-negative relative standard uncertainty, got {value!r}")
    return value


def response_point(output, t, *, input_amplitude: float | None = None, reference=None,
                   reference_sensitivity: float | None = None, angle_deg=None, freq: float | None = None,
                   static_sensitivity: float | None = None, initial_phase: float | None = None,
                   u_input: float = 0.0, u_reference_sensitivity: float = 0.0,
                   u_static_sensitivity: float = 0.0, u_input_phase: float = 0.0, drift: bool = False,
                   harmonics: int = 1, encoder_lines: int | None = None, u_angle: float = 0.0, source: str = "",
                   unit: str = "V/(m/s^2)") -> ResponsePoint:
    """Sensitivity, normalised sensitivity, phase and phase delay at one frequency.

    Three ways to know the input:

    * ``input_amplitude`` with ``angle_deg`` (double centrifuge): the record
      is cut to whole turntable revolutions starting at a 360 deg crossing and
      the output is fitted against the angle.  The phase delay is the output
      phase at encoder angle 0 minus the input phase ``phi_0`` there:
      ``initial_phase`` when entered (``u_input_phase`` in the budget), or
      from a start-up / lowest-frequency run (:func:`apply_phase_reference`).
      Without either, ``phi_0 = pi/2`` is assumed (the axis sees
      ``a0 cos(angle)``: encoder zero exactly along the field), which an
      encoder zero offset shifts one for one, so the point carries the named
      warning ``phase-reference-unknown``.
    * ``input_amplitude`` alone: the output is fitted against time; the
      phase delay is ``phase - initial_phase`` when ``initial_phase`` is given.
    * ``reference`` with ``reference_sensitivity`` (back-to-back, ISO
      16063-21): both fitted at one frequency, ``S = S_ref A_out / A_ref``,
      phase delay ``phase_out - phase_ref``.

    Parameters
    ----------
    output : array_like, shape (N,)
        Accelerometer output (its unit, e.g. V).
    t : array_like, shape (N,)
        Time stamps in s.
    input_amplitude : float, optional
        Peak input acceleration in m/s^2.
    reference : array_like, shape (N,), optional
        Reference accelerometer output.
    reference_sensitivity : float, optional
        Reference sensitivity, reference unit per m/s^2.
    angle_deg : array_like, shape (N,), optional
        Secondary turntable angle in degrees.
    freq : float, optional
        Known frequency in Hz (ignored with ``angle_deg``: the angle gives it).
    static_sensitivity : float, optional
        ``S_0`` (output unit per m/s^2) for the normalised sensitivity.
    initial_phase : float, optional
        Input phase ``phi_0`` in rad (sine convention) from a start-up test:
        at t = 0 for a time fit, at encoder angle 0 with ``angle_deg``
        (pi/2 when encoder zero lies exactly along the field).
    u_input, u_reference_sensitivity, u_static_sensitivity : float
        Type B relative standard uncertainties (fractions) of the input
        amplitude, the reference sensitivity and ``S_0``.
    u_input_phase : float
        Type B standard uncertainty of the entered input phase in rad.
    drift : bool
        Also fit a linear offset drift.
    harmonics : int
        Harmonics fitted with the fundamental (1 = fundamental only).  A nonlinear sensor puts harmonics in its output;
        fitting them keeps them out of the residual, so the fundamental's
        uncertainty stays the noise's (the fundamental itself is orthogonal to
        them over whole revolutions).
    encoder_lines : int, optional
        Counts per revolution of the turntable encoder (with ``angle_deg``):
        its step ``360 / lines`` deg is an error in the regressor.  Without it
        the step is detected in the angle channel (:func:`~senscal.vibration.fits.angle_step`);
        either way the fit uses a constant-speed line through the readings when
        they allow it, and the step's remaining effect on the amplitude and
        phase (:func:`~senscal.vibration.fits.encoder_effect`) is the type B
        component ``"encoder step"`` of the sensitivity and phase-delay budgets.
    u_angle : float
        Type B standard uncertainty of the encoder's angle reading in rad
        (its accuracy specification: an angle error constant over the record
        moves the phase one for one); a once-per-turn error (eccentric disc)
        leaves the fundamental's amplitude and phase unchanged to first order.
    source : str
        Label stored with the result.
    unit : str
        Sensitivity unit.

    Returns
    -------
    ResponsePoint

    References
    ----------
    .. [1] Qin Chaojun (seed 003), METHODS.md section 4.
    .. [2] ISO 16063-21:2003.
    """
    u_input = _check_rel("u_input", u_input)
    u_reference_sensitivity = _check_rel("u_reference_sensitivity", u_reference_sensitivity)
    u_static_sensitivity = _check_rel("u_static_sensitivity", u_static_sensitivity)
    u_input_phase = _check_rel("u_input_phase", u_input_phase)
    u_angle = _check_rel("u_angle", u_angle)
    if encoder_lines is not None and not (int(encoder_lines) == encoder_lines and encoder_lines >= 4):
        raise InputError(f"encoder lines must be a whole number of counts per revolution (>= 4), got {encoder_lines!r}")
    if (encoder_lines is not None or u_angle) and angle_deg is None:
        raise InputError("encoder lines and the angle's u describe a turntable angle channel: give the angle too")
    y = np.asarray(output, dtype=float)
    enc = None
    u_amp_q = u_ph_q = sd_ph_q = 0.0
    t = np.asarray(t, dtype=float)
    sync = None
    if reference is not None:
        if input_amplitude is not None or angle_deg is not None:
            raise InputError("give either a reference channel (back-to-back) or a known input amplitude, not both")
        if reference_sensitivity is None or not 0 < reference_sensitivity < math.inf:
            raise InputError("back-to-back comparison needs the reference sensitivity (> 0, reference unit per m/s^2)")
        pf = fit_pair(reference, y, t, freq=freq, drift=drift, harmonics=harmonics)
        a_ref, a_out = pf.reference_amplitude, pf.output_amplitude
        if a_ref <= 0:
            raise InputError("the reference channel carries no sinusoid; check --reference")
        a_in = a_ref / reference_sensitivity
        s = reference_sensitivity * a_out / a_ref
        jac = np.array([-s / a_ref, reference_sensitivity / a_ref, 0.0, 0.0])
        u_fit = math.sqrt(max(float(jac @ pf.covariance @ jac), 0.0))
        comps_b = [("reference sensitivity", "B", u_reference_sensitivity * s)]
        f, u_f = pf.frequency, pf.u_frequency
        u_amp = math.sqrt(pf.covariance[1, 1])
        phase, u_phase = float(pf.output.phase), pf.u_output_phase
        delay, u_delay_fit = pf.phase_difference, math.sqrt(pf.covariance[2, 2])
        method, n, snr = "back-to-back", pf.output.n_samples, float(pf.output.snr_db)
        dof = min(_fit_dof(pf.reference), _fit_dof(pf.output))
        phase_ref, warns = "reference channel", _fit_warnings(pf.reference, pf.output)
    else:
        if input_amplitude is None or not 0 < input_amplitude < math.inf:
            raise InputError("give the known peak input acceleration (> 0, m/s^2) or a reference channel")
        a_in = float(input_amplitude)
        if angle_deg is not None:
            sync = cut_whole_revolutions(angle_deg, t)
            sl = slice(sync.start, sync.stop)
            enc = encoder_angle(np.asarray(angle_deg, dtype=float)[sl], t[sl],
                                step_deg=None if encoder_lines is None else 360.0 / encoder_lines)
            fit = fit_against_angle(y[sl], enc.angle_deg, harmonics=harmonics, drift=drift)
            eff = encoder_effect(enc, t[sl], float(fit.amplitude), float(fit.phase),
                                 u_amplitude=float(fit.u_amplitude), u_phase=float(fit.u_phase),
                                 harmonics=harmonics, drift=drift)
            u_amp_q, u_ph_q, sd_ph_q = eff.u_amplitude, eff.u_phase, eff.sd_phase
            f, u_f = sync.frequency, sync.u_frequency
            warns = _angle_fit_warnings(fit, enc)
            if enc.unresolved_grid_deg is not None:
                warns += (named("encoder-step-unknown", (
                    f"the angle readings are whole multiples of {enc.unresolved_grid_deg:.4g} deg and advance a whole "
                    "number of them per sample, so the encoder's count step cannot be told from this record: every "
                    "reading may lie up to one count behind the angle, the same for all, which moves the phase "
                    "(delay) by up to that and is not in its U; give --encoder-lines N (counts per revolution) or "
                    "sample at a rate that is not a whole number of counts per sample")),)
            if initial_phase is None:
                # The axis sees a0 cos(angle) = a0 sin(angle + pi/2) only if
                # encoder zero lies along the field: an assumption, said aloud.
                delay = float(wrap_phase(fit.phase - 0.5 * math.pi))
                phase_ref = "assumed encoder zero"
                warns += (named("phase-reference-unknown", (
                    "the input phase phi_0 at encoder zero was neither entered nor measured, so the phase delay "
                    "assumes encoder zero lies exactly along the field; an encoder offset shifts every phase delay "
                    "by the offset, which its U does not contain; give --phase-reference FILE (start-up or "
                    "lowest-frequency run) or --initial-phase-deg with --u-initial-phase-deg")),)
            else:
                delay = float(wrap_phase(fit.phase - initial_phase))
                phase_ref = "entered"
            u_delay_fit = float(fit.u_phase)
            method = "known input, angle-synchronised"
        else:
            fit = fit_sine(y, t, freq=freq, drift=drift, harmonics=harmonics)
            f, u_f = float(fit.frequency), float(fit.u_frequency)
            delay = None if initial_phase is None else float(wrap_phase(fit.phase - initial_phase))
            u_delay_fit = float(fit.u_phase)
            method = "known input"
            phase_ref, warns = ("none" if initial_phase is None else "entered"), _fit_warnings(fit)
        a_out, u_amp = float(fit.amplitude), float(fit.u_amplitude)
        s = a_out / a_in
        u_fit = u_amp / a_in
        comps_b = [("input amplitude", "B", u_input * s)]
        if enc is not None and enc.step_deg is not None:
            comps_b.append(("encoder step", "B", u_amp_q / a_in))
        # The output phase at angle 0 carries the encoder's steps too.  apply_phase_reference combines it with other
        # records' phases, whose bounded errors add up to a nearly normal sum: their standard deviation, not the
        # single record's 95 % equivalent, is the u to combine.
        phase, u_phase = float(fit.phase), math.hypot(float(fit.u_phase), sd_ph_q)
        n, snr = fit.n_samples, float(fit.snr_db)
        dof = _fit_dof(fit)
    if not a_out > 0:
        # A dead (constant) output has no phase and no relative uncertainty.
        raise DataError(f"the output channel of {source} carries no sinusoid at {float(f):g} Hz (amplitude 0); "
                        "check --output and the sensor")
    s_budget = make_budget("sensitivity", s, unit, [("output fit (type A)", "A", u_fit, dof)] + comps_b)
    n_budget = None
    if static_sensitivity is not None:
        if not 0 < static_sensitivity < math.inf:
            raise InputError(f"static sensitivity S0 must be > 0, got {static_sensitivity!r}")
        r = s / static_sensitivity
        n_budget = make_budget("normalized sensitivity", r, "1",
                               [(c.source, c.kind, c.standard_uncertainty / static_sensitivity, c.dof)
                                for c in s_budget.components] + [("static sensitivity S0", "B", u_static_sensitivity * r)])
    d_budget = None
    if delay is not None:
        d_comps = [("phase fits (type A)", "A", u_delay_fit, dof), ("input phase", "B", u_input_phase)]
        if enc is not None and enc.step_deg is not None:
            d_comps.append(("encoder step", "B", u_ph_q))
        if u_angle:
            d_comps.append(("angle reading", "B", u_angle))
        d_budget = make_budget("phase delay", delay, "rad", d_comps)
    return ResponsePoint(
        source=source, method=method, frequency=float(f), u_frequency=float(u_f), input_amplitude=a_in,
        output_amplitude=a_out, u_output_amplitude=u_amp, sensitivity=s, u_sensitivity=s_budget.combined,
        normalized_sensitivity=None if n_budget is None else n_budget.value,
        u_normalized_sensitivity=None if n_budget is None else n_budget.combined,
        phase=phase, u_phase=u_phase,
        phase_delay=delay, u_phase_delay=None if d_budget is None else d_budget.combined,
        sensitivity_budget=s_budget, normalized_budget=n_budget, phase_delay_budget=d_budget,
        sync=sync, n_samples=int(n), snr_db=snr, phase_reference=phase_ref, warnings=warns,
        angle_step_deg=None if enc is None else enc.step_deg, angle_model=None if enc is None else enc.model,
    )


@dataclass(frozen=True)
class PhaseReference(ResultMixin):
    """Output phase of a start-up / lowest-frequency double-centrifuge run.

    Attributes
    ----------
    source : str
        Label (file name).
    frequency : float
        Turntable frequency of the run, Hz.
    phase, u_phase : float
        Output phase at encoder angle 0 (sine convention) and its standard
        uncertainty, rad: the input phase ``phi_0`` plus the sensor's own
        phase at this frequency.
    dof : float
        Degrees of freedom of ``u_phase``.
    """

    source: str
    frequency: float
    phase: float
    u_phase: float
    dof: float


def phase_reference_run(output, t, angle_deg, *, harmonics: int = 1, drift: bool = False,
                        encoder_lines: int | None = None, source: str = "") -> PhaseReference:
    """Fit a start-up / lowest-frequency run against the turntable angle.

    Parameters
    ----------
    output : array_like, shape (N,)
        Accelerometer output of the run.
    t : array_like, shape (N,)
        Time stamps in s.
    angle_deg : array_like, shape (N,)
        Turntable angle in degrees (same encoder as the response records).
    harmonics, drift, encoder_lines :
        As in :func:`response_point` (a quantised encoder's step is in ``u_phase``).
    source : str
        Label stored with the result.

    Returns
    -------
    PhaseReference

    References
    ----------
    .. [1] Qin Chaojun (seed 003), METHODS.md section 4: "a start-up test
       gives the initial phase phi_0; dphi_i = phi_i - phi_0".
    """
    y = np.asarray(output, dtype=float)
    sync = cut_whole_revolutions(angle_deg, t)
    sl = slice(sync.start, sync.stop)
    t = np.asarray(t, dtype=float)
    enc = encoder_angle(np.asarray(angle_deg, dtype=float)[sl], t[sl],
                        step_deg=None if encoder_lines is None else 360.0 / encoder_lines)
    fit = fit_against_angle(y[sl], enc.angle_deg, harmonics=harmonics, drift=drift)
    if not float(fit.amplitude) > 0:
        raise DataError(f"the phase-reference run {source} carries no sinusoid; check the file and --output")
    u_q = encoder_effect(enc, t[sl], float(fit.amplitude), float(fit.phase), u_amplitude=float(fit.u_amplitude),
                         u_phase=float(fit.u_phase), harmonics=harmonics, drift=drift).sd_phase
    return PhaseReference(source, float(sync.frequency), float(fit.phase), math.hypot(float(fit.u_phase), u_q),
                          _fit_dof(fit))


def apply_phase_reference(points: Sequence[ResponsePoint], ref: PhaseReference) -> tuple[ResponsePoint, ...]:
    """Phase delays of angle-synchronised points relative to a start-up run (the paper's phi_0).

    The reference run's output phase is ``phi_ref = phi_0 + d(f_ref)``, with
    ``d`` the sensor's own phase delay, which is not zero at any turning
    frequency.  It is extrapolated from the points above ``f_ref``: a
    sensor's phase is an odd function of frequency, ``d(f) = -tau f + beta
    f^3 + O(f^5)``, and the measured ``m_j = phi_j - phi_ref = d(f_j) -
    d(f_ref)`` of the two lowest points above ``f_ref`` fix ``tau`` and
    ``beta``, so ``d(f_ref) = sum_j a_j m_j`` (linear in the measured phases).
    The difference from the linear-only extrapolation (``beta = 0``, lowest
    point) is a type B component ``"start-up run's own delay (model)"``:
    it is the size of the curvature the extrapolation had to correct.  Then
    ``phi_0 = phi_ref - d(f_ref)`` and ``dphi_i = phi_i - phi_0``.

    The uncertainty follows from the independent phase fits of the
    reference run and of the points used (a point whose ``source`` equals
    the reference's shares its fit).  Everything except the point's own fit
    is common to all points and goes into the budget as ``"phi_0 from
    reference run"`` (type B for the averaging of repeats, which cannot
    reduce it).

    Parameters
    ----------
    points : sequence of ResponsePoint
        Angle-synchronised points (``sync`` set).
    ref : PhaseReference
        From :func:`phase_reference_run` with the same encoder.

    Returns
    -------
    tuple of ResponsePoint
        The points with ``phase_delay``, its budget and ``phase_reference =
        "reference run"``.  With one point above ``f_ref`` only the linear
        term is extrapolated and the warning ``phase-reference-uncorrected``
        says the curvature is not checked; with none, nothing is
        extrapolated (delays relative to the sensor's own at ``f_ref``) and
        the same warning says so.
    """
    import dataclasses

    if any(p.sync is None for p in points):
        raise InputError("a phase-reference run applies to double-centrifuge records fitted against the turntable angle "
                         "(--angle)")
    key_ref = ref.source or "reference run"
    u_of: dict = {key_ref: (ref.u_phase, ref.dof)}
    above = sorted((p for p in points if p.frequency > ref.frequency * (1 + _SAME_FREQ)), key=lambda p: p.frequency)
    # distinct frequencies: repeats at f_1 would make the 2 x 2 system singular
    use: list[ResponsePoint] = []
    for p in above:
        if not use or p.frequency > use[-1].frequency * (1 + _SAME_FREQ):
            use.append(p)
        if len(use) == 2:
            break
    fr = ref.frequency
    warns: tuple[str, ...] = ()
    a: list[float] = []
    u_model = 0.0
    if use:
        f1 = use[0].frequency
        a_lin = [fr / (f1 - fr)]
        if len(use) == 2:
            f2 = use[1].frequency
            m = np.array([[-(f1 - fr), f1**3 - fr**3], [-(f2 - fr), f2**3 - fr**3]])
            a = list(np.linalg.solve(m.T, np.array([-fr, fr**3])))
        else:
            a = a_lin
    m_meas = [float(wrap_phase(p.phase - ref.phase)) for p in use]
    d_ref = float(sum(aj * mj for aj, mj in zip(a, m_meas)))
    if len(use) == 2:
        u_model = abs(d_ref - a_lin[0] * m_meas[0])
    else:
        what = ("only one point lies above" if use else "no response point lies above")
        warns = (named("phase-reference-uncorrected", (
            f"{what} the start-up run's {fr:.4g} Hz, so its own phase delay is "
            + ("extrapolated linearly without a check of the curvature" if use else "not corrected: the phase delays "
               "are relative to the sensor's delay at that frequency")
            + "; record the start-up run below at least two response frequencies")),)
    keys = []
    for p in use:
        k = p.source or id(p)
        keys.append(k)
        u_of.setdefault(k, (p.u_phase, _dof_of(p)))
    phi0 = ref.phase - d_ref
    out = []
    for p in points:
        key = p.source or id(p)
        u_of.setdefault(key, (p.u_phase, _dof_of(p)))
        coef = {key: 1.0}
        coef[key_ref] = coef.get(key_ref, 0.0) - (1.0 + sum(a))
        for k, aj in zip(keys, a):
            coef[k] = coef.get(k, 0.0) + aj
        delay = float(wrap_phase(p.phase - phi0))
        own = abs(coef.get(key, 0.0)) * u_of[key][0]
        rest = math.sqrt(sum((cf * u_of[k][0]) ** 2 for k, cf in coef.items() if k != key))
        comps = [("phase fits (type A)", "A", own, u_of[key][1]), ("phi_0 from reference run", "B", rest),
                 ("start-up run's own delay (model)", "B", u_model)]
        budget = make_budget("phase delay", delay, "rad", comps)
        pw = tuple(w for w in p.warnings if not w.startswith("phase-reference-unknown:")) + warns
        out.append(dataclasses.replace(p, phase_delay=delay, u_phase_delay=budget.combined, phase_delay_budget=budget,
                                       phase_reference="reference run", warnings=pw))
    return tuple(out)


def _dof_of(p: ResponsePoint) -> float:
    c = [c for c in p.sensitivity_budget.components if c.kind == "A"]
    return math.inf if not c or c[0].dof is None else float(c[0].dof)


@dataclass(frozen=True)
class FrequencyResponse(ResultMixin):
    """An accelerometer's frequency response: points sorted by frequency.

    Attributes
    ----------
    points : tuple of ResponsePoint
    unit : str
        Sensitivity unit.
    static_sensitivity : float or None
        ``S_0`` used for the normalisation.
    phase_reference : str
        How the input phase behind the phase delays was obtained, in words
        (for the certificate).
    warnings : tuple of str
        Named warnings of the points, one per name.
    """

    points: tuple[ResponsePoint, ...]
    unit: str
    static_sensitivity: float | None
    phase_reference: str = ""
    warnings: tuple[str, ...] = ()

    @property
    def frequency(self) -> np.ndarray:
        """Frequencies in Hz."""
        return np.array([p.frequency for p in self.points])

    @property
    def sensitivity(self) -> np.ndarray:
        return np.array([p.sensitivity for p in self.points])

    @property
    def u_sensitivity(self) -> np.ndarray:
        return np.array([p.u_sensitivity for p in self.points])

    def sensitivity_at(self, frequency: float) -> tuple[float, float]:
        """Sensitivity and its standard uncertainty at ``frequency`` (Hz), sensitivity unit.

        At a calibrated point its own values.  Between two points the
        sensitivity is interpolated linearly in log frequency (the response of
        an accelerometer well below resonance is smooth there), with weights
        ``w`` and ``1 - w``; its uncertainty propagates the two points'
        budgets: type A components are independent between points
        (``sum w_i^2 u_i^2``), type B components of the same source (the
        input amplitude, the reference) are fully correlated
        (``(sum w_i u_i)^2``).  Points without budgets count as independent.
        Outside the calibrated range it refuses: a calibration says nothing
        about frequencies it did not visit.
        """
        f = float(frequency)
        fr = self.frequency
        if not (math.isfinite(f) and f > 0):
            raise InputError(f"frequency must be a positive number of Hz, got {frequency!r}")
        tol = 1e-9 * fr.max()
        if f < fr.min() - tol or f > fr.max() + tol:
            raise InputError(f"{f:g} Hz lies outside the calibrated range {fr.min():g} to {fr.max():g} Hz; "
                             "calibrate at that frequency")
        j = int(np.clip(np.searchsorted(fr, f), 1, max(len(fr) - 1, 1)))
        if len(fr) == 1 or abs(f - fr[j - 1]) <= tol:
            return float(self.points[max(j - 1, 0)].sensitivity), float(self.points[max(j - 1, 0)].u_sensitivity)
        if abs(f - fr[j]) <= tol:
            return float(self.points[j].sensitivity), float(self.points[j].u_sensitivity)
        w = math.log(fr[j] / f) / math.log(fr[j] / fr[j - 1])  # weight of the lower point
        pair = ((w, self.points[j - 1]), (1.0 - w, self.points[j]))
        value = sum(wi * p.sensitivity for wi, p in pair)
        var_a, b_sum = 0.0, {}
        for wi, p in pair:
            comps = p.sensitivity_budget.components if p.sensitivity_budget is not None else ()
            if not comps:
                var_a += (wi * p.u_sensitivity) ** 2
            for c in comps:
                if c.kind == "B":
                    b_sum[c.source] = b_sum.get(c.source, 0.0) + wi * c.standard_uncertainty
                else:
                    var_a += (wi * c.standard_uncertainty) ** 2
        return float(value), float(math.sqrt(var_a + sum(v * v for v in b_sum.values())))

    def apply(self, output_amplitude, frequency: float, *, unit: str | None = None) -> np.ndarray:
        """Correct output amplitudes at one frequency: the input amplitude that caused them.

        Parameters
        ----------
        output_amplitude : array_like
            Peak output amplitude(s) of the sensor, in the output unit (the
            sensitivity unit's numerator: ``V`` for ``V/(m/s^2)``).
        frequency : float
            Hz, within the calibrated range.
        unit : str, optional
            Unit of ``output_amplitude``; converted to the output unit
            (``mV`` amplitudes, ``V/(m/s^2)`` calibration), refused when of
            another dimension.

        Returns
        -------
        ndarray
            ``output_amplitude / S(frequency)``, input unit (``m/s^2`` for a
            sensitivity in ``V/(m/s^2)``); :meth:`sensitivity_at` gives ``S``
            and its ``u``.
        """
        from senscal.persist.units import numerator, unit_factor

        scale = unit_factor(unit, numerator(self.unit), what="the output amplitude",
                            fix="give amplitudes in the calibration's output unit")
        s, _ = self.sensitivity_at(frequency)
        return np.asarray(output_amplitude, dtype=float) * scale / s

    def compare(self, sensitivity: float, frequency: float) -> tuple[float, float]:
        """Relative deviation of a sensitivity measured at ``frequency`` from this calibration.

        Returns
        -------
        deviation, u_deviation : float
            ``sensitivity / S(f) - 1`` and the standard uncertainty this
            calibration contributes to it (``u(S) / S``), ratio.
        """
        s, u = self.sensitivity_at(frequency)
        return float(sensitivity) / s - 1.0, u / s

    @classmethod
    def from_document(cls, doc, *, source: str = "response file") -> "FrequencyResponse":
        """Rebuild from a saved document; see :func:`response_from_document`."""
        return response_from_document(doc, source=source)


def frequency_response(points: Sequence[ResponsePoint], *, unit: str = "V/(m/s^2)",
                       static_sensitivity: float | None = None, phase_reference: str | None = None,
                       ) -> FrequencyResponse:
    """Collect response points into a :class:`FrequencyResponse` (sorted by frequency).

    Parameters
    ----------
    points : sequence of ResponsePoint
    unit : str
        Sensitivity unit.
    static_sensitivity : float, optional
        ``S_0`` used for the normalisation.
    phase_reference : str, optional
        How phi_0 was obtained, in words (default: from the points).
    """
    if not points:
        raise InputError("give at least one frequency point")
    pts = tuple(sorted(points, key=lambda p: p.frequency))
    if phase_reference is None:
        phase_reference = _PHASE_REF_TEXT.get(pts[0].phase_reference, pts[0].phase_reference)
    return FrequencyResponse(pts, unit, static_sensitivity, phase_reference,
                             unique_warnings(*(p.warnings for p in pts)))


_PHASE_REF_TEXT = {
    "none": "no input phase: phase delay not determined",
    "entered": "input phase phi_0 entered (start-up test), its u in the budget",
    "reference run": "input phase phi_0 from a start-up / lowest-frequency run",
    "reference channel": "phase of the reference accelerometer",
    "assumed encoder zero": "NOT DETERMINED: encoder zero assumed along the field (warning phase-reference-unknown)",
}


@dataclass(frozen=True)
class RepeatedPoint(ResultMixin):
    """Repeated records at one frequency combined (GUM type A from their spread).

    Attributes
    ----------
    frequency : float
        Mean frequency of the repeats, Hz.
    n_repeats : int
    sources : tuple of str
    sensitivity, u_sensitivity, sensitivity_std : float
        Mean, combined standard uncertainty of the mean, experimental standard
        deviation of the repeats.
    normalized_sensitivity, u_normalized_sensitivity : float or None
    phase_delay, u_phase_delay : float or None
        rad.
    sensitivity_budget, normalized_budget, phase_delay_budget : UncertaintyBudget or None
    warnings : tuple of str
        ``excess-scatter`` when the repeats scatter more than their fits
        explain (type A then from the spread, Student k), and the points' own.
    """

    frequency: float
    n_repeats: int
    sources: tuple[str, ...]
    sensitivity: float
    u_sensitivity: float
    sensitivity_std: float
    normalized_sensitivity: float | None
    u_normalized_sensitivity: float | None
    phase_delay: float | None
    u_phase_delay: float | None
    sensitivity_budget: UncertaintyBudget
    normalized_budget: UncertaintyBudget | None
    phase_delay_budget: UncertaintyBudget | None
    warnings: tuple[str, ...] = ()


def _mean_of(budgets: Sequence[UncertaintyBudget], quantity: str, relative: bool):
    """Combine per-repeat budgets: type A by :func:`mean_with_budget`'s rule, type B carried over."""
    first = budgets[0]
    a_src = [c for c in first.components if c.kind == "A"][0].source
    u_fit = [b.component(a_src).standard_uncertainty for b in budgets]
    dof = [b.component(a_src).dof for b in budgets]
    vals = [b.value for b in budgets]
    bs = [(c.source, c.standard_uncertainty / abs(first.value) if relative else c.standard_uncertainty)
          for c in first.components if c.kind == "B"]
    m = mean_with_budget(vals, u_fit, bs if relative else [], quantity, first.unit,
                         absolute_b=[] if relative else bs, fit_dof=dof)
    return m.budget, m.std, m.warnings


def combine_repeats(points: Sequence[ResponsePoint], *, rel_tol: float = 1e-3) -> tuple[RepeatedPoint, ...]:
    """Group records at the same frequency and combine them (mean, spread, budget).

    Parameters
    ----------
    points : sequence of ResponsePoint
    rel_tol : float
        Frequencies within this relative tolerance are repeats of one point.

    Returns
    -------
    tuple of RepeatedPoint
        One per distinct frequency, sorted by frequency.  Type A of each mean
        is the fits' own uncertainty of the mean when a chi-square test finds
        the repeats consistent with it, else ``s / sqrt(n)`` with Student k
        and the warning ``excess-scatter`` (see
        :func:`~senscal.vibration.budget.mean_with_budget`).

    References
    ----------
    .. [1] JCGM 100:2008 (GUM) 4.2 (type A evaluation from repeated observations).
    """
    groups: list[list[ResponsePoint]] = []
    for p in sorted(points, key=lambda q: q.frequency):
        if groups and abs(p.frequency - groups[-1][0].frequency) <= rel_tol * groups[-1][0].frequency:
            groups[-1].append(p)
        else:
            groups.append([p])
    out = []
    for g in groups:
        sb, s_std, warns = _mean_of([p.sensitivity_budget for p in g], "sensitivity", True)
        nb = None
        if all(p.normalized_budget is not None for p in g):
            nb, _, _ = _mean_of([p.normalized_budget for p in g], "normalized sensitivity", True)
        db = None
        if all(p.phase_delay_budget is not None for p in g):
            # average phases around the first one so a +/-pi wrap cannot split the mean
            ref = g[0].phase_delay
            wrapped = [make_budget("phase delay", ref + float(wrap_phase(p.phase_delay - ref)), "rad",
                                   [(c.source, c.kind, c.standard_uncertainty, c.dof)
                                    for c in p.phase_delay_budget.components])
                       for p in g]
            db, _, dw = _mean_of(wrapped, "phase delay", False)
            warns += dw
        out.append(RepeatedPoint(
            frequency=float(np.mean([p.frequency for p in g])), n_repeats=len(g), sources=tuple(p.source for p in g),
            sensitivity=sb.value, u_sensitivity=sb.combined, sensitivity_std=s_std,
            normalized_sensitivity=None if nb is None else nb.value,
            u_normalized_sensitivity=None if nb is None else nb.combined,
            phase_delay=None if db is None else db.value, u_phase_delay=None if db is None else db.combined,
            sensitivity_budget=sb, normalized_budget=nb, phase_delay_budget=db,
            warnings=unique_warnings(warns, *(p.warnings for p in g))))
    return tuple(out)


def save_response(resp: FrequencyResponse, path) -> "Path":
    """Save a frequency response with its type and format version: JSON, or HDF5 for ``.h5``/``.hdf5``.

    :func:`senscal.load_calibration` and :func:`load_response` read it back.
    """
    from senscal.persist import document, write_document

    return write_document(document(FORMAT, resp.to_dict()), path, what="response file")


def _budget_from(d):
    if d is None:
        return None
    comps = tuple(BudgetComponent(**c) for c in d["components"])
    return UncertaintyBudget(d["quantity"], d["value"], d["unit"], comps, d["combined"], d["coverage_factor"],
                             d["expanded"], d.get("effective_dof"))


def load_response(path) -> FrequencyResponse:
    """Load a response written by :func:`save_response` (JSON or HDF5, any version; type checked).

    Same as ``senscal.load_calibration(path)`` but refuses other calibration types.
    """
    from senscal.persist import load_calibration

    return load_calibration(path, expect=FORMAT)


def response_from_document(doc, *, source: str = "response file") -> FrequencyResponse:
    """Rebuild a :class:`FrequencyResponse` from a saved document (see :func:`save_response`)."""
    if not isinstance(doc, dict) or doc.get("type") != FORMAT:
        raise FileFormatError(f"{source} is not a senscal frequency response "
                              f"(type {doc.get('type') if isinstance(doc, dict) else None!r})")
    from senscal.persist import check_version

    check_version(doc, source)
    try:
        pts = []
        for d in doc["points"]:
            kw = dict(d)
            for k in ("sensitivity_budget", "normalized_budget", "phase_delay_budget"):
                kw[k] = _budget_from(d.get(k))
            kw["sync"] = None if d.get("sync") is None else AngleSync(**d["sync"])
            kw["warnings"] = tuple(d.get("warnings") or ())
            pts.append(ResponsePoint(**kw))
        resp = FrequencyResponse(tuple(pts), doc["unit"], doc["static_sensitivity"], doc.get("phase_reference", ""),
                                 tuple(doc.get("warnings") or ()))
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise FileFormatError(f"{source} is a damaged frequency response (missing or bad {exc}); "
                              "save the response again") from None
    if not pts or not all(isinstance(p.frequency, (int, float)) and isinstance(p.sensitivity, (int, float))
                          for p in pts):
        raise FileFormatError(f"{source} holds no usable frequency points; save the response again")
    return resp
