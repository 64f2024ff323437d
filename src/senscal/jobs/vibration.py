"""Vibration jobs: velocity-sensor sensitivity, accelerometer frequency response, amplitude linearity.

Each job takes recordings (paths or :class:`~senscal.io.Recording`, one per
frequency point / input level) and a frozen options dataclass, and returns a
frozen :class:`~senscal.jobs.JobResult` holding the engine results
(:class:`~senscal.vibration.VelocityCalibration`,
:class:`~senscal.vibration.FrequencyResponse`,
:class:`~senscal.vibration.AmplitudeLinearity`). ``to_dict()`` is the
document ``senscal velocity|response|linearity --json`` prints, and
``quantities()`` what ``--save`` stores in the registry.

Examples
--------
>>> from senscal.jobs.vibration import velocity, VelocityOptions        # doctest: +SKIP
>>> res = velocity(["hyd/hydraulic_01.csv", "hyd/hydraulic_02.csv"],
...                VelocityOptions(position="position", velocity="velocity"))  # doctest: +SKIP
>>> res.calibration.sensitivity, res.calibration.u_sensitivity          # doctest: +SKIP
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar, Iterable, Optional, Sequence, Tuple, Union

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.io import Recording
from senscal.io.plausibility import with_time_warnings
from senscal.jobs._base import JobResult, ReadOptions
from senscal.quantity import Quantity

__all__ = ["VelocityOptions", "VelocityResult", "velocity", "ResponseOptions", "ResponseResult", "response",
           "LinearityOptions", "LinearityResult", "linearity"]

Source = Union[str, Path, Recording]
Sources = Union[Source, Sequence[Source]]
# A progress wrapper: ``progress(items, "fitting")`` yields the items (the CLI passes a progress bar).
Progress = Callable[[Sequence[Any], str], Iterable[Any]]


def _no_progress(items, _description):
    return items


# ---------------------------------------------------------------------------
# reading and checks shared by the three jobs
# ---------------------------------------------------------------------------

def _as_list(sources: Sources) -> list:
    if isinstance(sources, (str, Path, Recording)):
        return [sources]
    out = list(sources)
    if not out:
        raise InputError("give at least one recording (one per frequency point / input level)")
    return out


def _distinct(sources: Sequence[Source]) -> None:
    """Refuse a recording given twice: it would count as two independent points."""
    seen: dict[str, Any] = {}
    for s in sources:
        if isinstance(s, Recording):
            continue
        key = os.path.normcase(os.path.realpath(s))
        if key in seen:
            raise InputError(f"{s} is given more than once (also as {seen[key]}); each recording is one point")
        seen[key] = s


def _read(source: Source, opts, channels: Sequence[str], index: int) -> tuple[Recording, str]:
    """The recording and the label its point carries (the path as given, or the recording's source)."""
    if isinstance(source, Recording):
        for ch in channels:
            source[ch]  # an unknown channel is one clean InputError naming the channels there are
        return source, source.source or f"recording {index + 1}"
    rec = opts.read(source, channels=channels)
    return rec, str(source)


class _Units:
    """The units one run works in, fixed by its first recording; every later recording is converted to them.

    A voltage output is worked in V (``mV`` data are multiplied by 1e-3), so a bare ``--static-sensitivity
    0.05`` is 0.05 V/(m/s^2) whatever the file's scale; another output (``pC``, counts) is worked in the
    first recording's unit.  A position reference is worked in m, an angle in deg.  Data of another
    dimension (``V`` for a position, ``m/s^2`` for an output) are refused with one line.
    """

    def __init__(self, given_output: str | None):
        from senscal.units import parse_unit

        self.given = (given_output or "").strip() or None
        if self.given:
            parse_unit(self.given, what="--output-unit")
        self.work: dict[str, str] = {}

    def scale(self, rec: Recording, name: str, role: str, label: str) -> float:
        """The factor that takes channel ``name`` of ``rec`` into the run's unit for ``role``.

        ``role`` is ``"output"`` (sensor output; --output-unit applies), ``"reference"`` (a reference
        sensor's output), ``"position"`` (m) or ``"angle"`` (deg).
        """
        from senscal.units import factor, is_voltage, parse_unit, same_unit, unit_text

        in_file = unit_text(rec.units.get(name))
        what = f"channel '{name}' of {label}"
        if in_file:
            parse_unit(in_file, what=f"the unit of {what}")
        if role == "output" and self.given and in_file and not same_unit(self.given, in_file):
            raise InputError(f"--output-unit {self.given} contradicts {label}, whose header gives '{name}' in "
                             f"{in_file}; drop --output-unit (it is for files that give no unit) or fix the header")
        fixed = {"position": "m", "angle": "deg"}.get(role)
        have = in_file or (self.given if role == "output" else None) or fixed or "V"
        if role not in self.work:
            self.work[role] = fixed or ("V" if is_voltage(have) else have)
        want = self.work[role]
        fix = {"position": "--position must name the displacement reference (m, mm, um ...); check that "
                           "--position and --velocity are not swapped",
               "angle": "--angle must name the turntable angle channel (deg or rad)"}.get(
            role, f"every recording's {role} must be in one kind of unit (this run's is {want}); check the "
                  "channel names and headers")
        return factor(have, want, what=f"the {role} {what}", fix=fix)

    def unit(self, role: str) -> str:
        return self.work.get(role, "V")


def _given_frequency_fits(point, y, t, freq, harmonics: int, name: str):
    """The point with ``frequency-mismatch`` added when a --freq is given that the channel ``y`` does not have."""
    if freq is None:
        return point
    import dataclasses

    from senscal.sinefit.freqcheck import frequency_mismatch

    w = frequency_mismatch(y, t, freq, harmonics=harmonics, name=name)
    return dataclasses.replace(point, warnings=tuple(point.warnings) + (w,)) if w else point


def _not_a_length(unit: str, name: str, label: str) -> None:
    """Refuse a velocity-sensor output in a length unit: that channel is a displacement (swapped channels)."""
    from senscal.units import compatible

    if compatible(unit, "m"):
        raise InputError(f"the velocity-sensor channel '{name}' of {label} is in {unit}, a length: it is a "
                         "displacement, not a sensor output; check that --position and --velocity are not swapped")


def _bare_or_converted(value, unit: str, option: str):
    """An option's number in the run's unit: a bare number is in ``unit``, ``'50 mV/(m/s^2)'`` is converted."""
    from senscal.units import parse_quantity

    return parse_quantity(value, unit, option=option)


def _freqs(freq, n: int) -> list[float | None]:
    """One known frequency per recording (Hz) from None, one value, or one value per recording."""
    if freq is None:
        return [None] * n
    fl = [float(freq)] if isinstance(freq, (int, float)) else [float(f) for f in freq]
    if not fl:
        return [None] * n
    if any(not (f > 0 and math.isfinite(f)) for f in fl):
        raise InputError("--freq values must be positive numbers of Hz")
    if len(fl) == 1:
        return fl * n
    if len(fl) != n:
        raise InputError(f"give one --freq for all files or one per file: got {len(fl)} frequencies for {n} files")
    return fl


def _finite_or_none(x):
    """A float that the JSON document keeps (None where it prints null)."""
    return None if x is None or not math.isfinite(float(x)) else float(x)


def _deg(x):
    return None if x is None else math.degrees(x)


def _expanded(budget):
    """Expanded uncertainty of a budget (its own k), None without one."""
    return None if budget is None else budget.expanded


def _points_frame(points: Sequence[dict]):
    """One row per point of a ``to_dict()`` document: its scalar fields (budgets and lists left out)."""
    import pandas as pd

    return pd.DataFrame([{k: v for k, v in p.items() if not isinstance(v, (dict, list))} for p in points])


@dataclass(frozen=True)
class _ReadOptions(ReadOptions):
    """How the recordings are read (:class:`~senscal.jobs._base.ReadOptions`) and the output's unit.

    Attributes
    ----------
    output_unit : str, optional
        Unit of the sensor output for files whose header gives none (default V); a header that gives
        another unit is a contradiction and refused.  A voltage output is worked in V (mV data are
        converted), so the sensitivity is in V/(m/s^2) or V/(m/s).
    """

    output_unit: Optional[str] = None


def _need(value, option: str, what: str):
    if not value:
        raise InputError(f"give {option} NAME: {what}")
    return value


# ---------------------------------------------------------------------------
# velocity
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class VelocityOptions(_ReadOptions):
    """Options of :func:`velocity`.

    Attributes
    ----------
    position : str
        Position-reference channel (m unless its header says mm, um ...: converted to m).
    velocity : str
        Velocity-sensor output channel.
    freq : float or tuple of float, optional
        Known frequency (Hz): one for all recordings or one per recording; estimated when None.
    u_position : float
        Type B relative standard uncertainty of the position reference's scale (fraction, 0.001 = 0.1 %).
    drift : bool
        Fit a linear offset drift.
    harmonics : int
        Harmonics of the motion fitted with the fundamental.
    """

    position: Optional[str] = None
    velocity: Optional[str] = None
    freq: Optional[Union[float, Tuple[float, ...]]] = None
    u_position: float = 0.0
    drift: bool = True
    harmonics: int = 1


@dataclass(frozen=True)
class VelocityResult(JobResult):
    """Velocity-sensor sensitivity per recording and over all of them.

    Attributes
    ----------
    calibration : VelocityCalibration
        Points (one per recording), mean sensitivity (``unit``), its budget.
    unit : str
        Sensitivity unit, e.g. ``V/(m/s)``.
    warnings : tuple of str
        Named warnings.
    """

    job: ClassVar[str] = "velocity"
    calibration: Any
    unit: str
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        cal = self.calibration
        return to_jsonable({
            "points": [{"file": p.source, "frequency_hz": p.frequency, "u_frequency_hz": p.u_frequency,
                        "sensitivity": p.sensitivity, "u_sensitivity": p.u_sensitivity,
                        "U_sensitivity": p.budget.expanded,
                        "phase_deg": math.degrees(p.phase), "u_phase_deg": math.degrees(p.u_phase),
                        "position_amplitude_m": p.position_amplitude, "output_amplitude": p.output_amplitude,
                        "snr_db": p.snr_db, "budget": p.budget} for p in cal.points],
            "sensitivity": cal.sensitivity, "sensitivity_std": cal.sensitivity_std,
            "u_sensitivity": cal.u_sensitivity, "U_sensitivity": cal.budget.expanded,
            "coverage_factor": cal.budget.coverage_factor, "effective_dof": cal.budget.effective_dof,
            "birge_ratio": cal.birge_ratio, "chi2_p": cal.chi2_p, "unit": self.unit, "budget": cal.budget,
            "warnings": list(self.warnings),
        })

    def quantities(self) -> tuple[Quantity, ...]:
        cal = self.calibration
        return (Quantity("sensitivity", float(cal.sensitivity), float(cal.u_sensitivity), self.unit),)

    def to_dataframe(self):
        """One row per recording: frequency (Hz), sensitivity and its u/U, phase (deg), SNR (dB)."""
        return _points_frame(self.to_dict()["points"])


def velocity(sources: Sources, options: VelocityOptions = VelocityOptions(), *,
             progress: Progress = _no_progress) -> VelocityResult:
    """Velocity-sensor sensitivity S = A_s / (w A_p) against a position reference (Yang et al. 2014).

    Parameters
    ----------
    sources : path, Recording, or sequence of them
        One recording per frequency point, each with the position (m) and velocity-sensor channels.
    options : VelocityOptions
    progress : callable, optional
        ``progress(items, description)`` wrapping the loop over recordings (a progress bar).

    Returns
    -------
    VelocityResult

    Raises
    ------
    InputError
        Missing channel names, a recording given twice, a --freq list of the wrong length, bad data.
    """
    from senscal.vibration import velocity_calibration, velocity_point

    o = options
    _need(o.position, "--position", "the position-reference channel (m)")
    _need(o.velocity, "--velocity", "the velocity-sensor output channel")
    srcs = _as_list(sources)
    _distinct(srcs)
    freqs = _freqs(o.freq, len(srcs))
    points, units = [], _Units(o.output_unit)
    for i, (src, f) in enumerate(progress(list(zip(srcs, freqs)), "fitting")):
        rec, label = _read(src, o, [o.position, o.velocity], i)
        # The position in m and the output in the run's unit (mV -> V): S = A_s / (w A_p) needs both.
        position = rec[o.position] * units.scale(rec, o.position, "position", label)
        output = rec[o.velocity] * units.scale(rec, o.velocity, "output", label)
        _not_a_length(units.unit("output"), o.velocity, label)
        unit = units.unit("output") + "/(m/s)"
        points.append(_given_frequency_fits(with_time_warnings(velocity_point(
            position, output, rec.time, freq=f, drift=o.drift, harmonics=o.harmonics,
            u_position=o.u_position, source=label, unit=unit), rec.time, "velocity",
            y=position if f is not None else None, known_hz=f), position, rec.time, f, o.harmonics, o.position))
    cal = velocity_calibration(points, u_position=o.u_position, unit=unit)
    return VelocityResult(calibration=cal, unit=unit, warnings=tuple(cal.warnings))


# ---------------------------------------------------------------------------
# response
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class ResponseOptions(_ReadOptions):
    """Options of :func:`response`.

    Either a known input (``input_amplitude``, double centrifuge / calibrated exciter) or a
    back-to-back reference (``reference`` with ``reference_sensitivity``).

    Attributes
    ----------
    output : str
        Accelerometer output channel.
    input_amplitude : float or str, optional
        Known peak input acceleration: a number in m/s^2, or a quantity such as ``"10 g"``.
    reference : str, optional
        Reference accelerometer channel (back-to-back).
    reference_sensitivity : float or str, optional
        Reference sensitivity: a number in the reference's working unit per m/s^2 (V/(m/s^2) for a
        voltage output, whatever its scale in the file), or a quantity such as ``"10.2 mV/(m/s^2)"``.
    angle : str, optional
        Turntable angle channel (deg unless its header says rad): records cut to whole revolutions,
        input phase from it.
    static_sensitivity : float or str, optional
        Static sensitivity S0 for S_i/S0: a number in the result's unit (V/(m/s^2) for a voltage output,
        also when the file gives mV), or a quantity such as ``"50 mV/(m/s^2)"`` (converted).
    initial_phase_deg : float, optional
        Input phase phi_0 (deg, sine convention) entered from a start-up test.
    u_initial_phase_deg : float
        Standard uncertainty of ``initial_phase_deg`` (deg).
    phase_reference : path or Recording, optional
        Start-up / lowest-frequency double-centrifuge run (same channels) that gives phi_0.
    freq : float or tuple of float, optional
        Known frequency (Hz): one for all recordings or one per recording.
    u_input, u_reference, u_static_sensitivity : float
        Type B relative standard uncertainties (fractions) of the input amplitude, the
        reference sensitivity and S0.
    drift : bool
        Fit a linear offset drift.
    harmonics : int
        Harmonics fitted with the fundamental.
    encoder_lines : int, optional
        Counts per revolution of the turntable encoder (with ``angle``); without it a quantised angle
        channel's step is detected in the readings.  The step's effect is a type B budget component.
    u_angle_deg : float
        Type B standard uncertainty of the encoder's angle reading (accuracy specification), deg: moves the
        phase delay one for one unless phi_0 comes from a reference run with the same encoder.
    """

    output: Optional[str] = None
    input_amplitude: Optional[Union[float, str]] = None
    reference: Optional[str] = None
    reference_sensitivity: Optional[Union[float, str]] = None
    angle: Optional[str] = None
    static_sensitivity: Optional[Union[float, str]] = None
    initial_phase_deg: Optional[float] = None
    u_initial_phase_deg: float = 0.0
    phase_reference: Optional[Union[str, Path, Recording]] = None
    freq: Optional[Union[float, Tuple[float, ...]]] = None
    u_input: float = 0.0
    u_reference: float = 0.0
    u_static_sensitivity: float = 0.0
    drift: bool = False
    harmonics: int = 1
    encoder_lines: Optional[int] = None
    u_angle_deg: float = 0.0


def _check_response_options(o: ResponseOptions) -> None:
    _need(o.output, "--output", "the accelerometer output channel")
    if (o.input_amplitude is None) == (o.reference is None):
        raise InputError("give either --input-amplitude A (m/s^2) or --reference NAME with --reference-sensitivity S")
    if o.reference is not None and o.reference_sensitivity is None:
        raise InputError("--reference needs --reference-sensitivity (reference output unit per m/s^2)")
    if o.reference is not None and o.angle is not None:
        raise InputError("--angle applies to a known input (double centrifuge), not to a back-to-back comparison")
    if o.initial_phase_deg is not None and o.reference is not None:
        raise InputError("--initial-phase-deg is for a known input; with --reference the input phase is the reference channel's")
    if o.initial_phase_deg is not None and not math.isfinite(o.initial_phase_deg):
        raise InputError(f"--initial-phase-deg must be a finite number of degrees, got {o.initial_phase_deg!r}")
    u0 = o.u_initial_phase_deg
    if not (math.isfinite(u0) and 0 <= u0 < 180):
        raise InputError(f"--u-initial-phase-deg must be a standard uncertainty in [0, 180) deg, got {u0!r}")
    if u0 > 0 and o.initial_phase_deg is None:
        raise InputError("--u-initial-phase-deg is the uncertainty of --initial-phase-deg: give that too")
    if (o.encoder_lines is not None or o.u_angle_deg) and o.angle is None:
        raise InputError("--encoder-lines and --u-angle-deg describe the turntable angle channel: give --angle NAME")
    if o.encoder_lines is not None and not (int(o.encoder_lines) == o.encoder_lines and o.encoder_lines >= 4):
        raise InputError(f"--encoder-lines must be a whole number of counts per revolution (>= 4), got {o.encoder_lines!r}")
    if not (math.isfinite(o.u_angle_deg) and 0 <= o.u_angle_deg < 180):
        raise InputError(f"--u-angle-deg must be a standard uncertainty in [0, 180) deg, got {o.u_angle_deg!r}")
    if o.phase_reference is not None:
        if o.angle is None:
            raise InputError("--phase-reference is a double-centrifuge run fitted against the turntable angle: give --angle")
        if o.initial_phase_deg is not None:
            raise InputError("give either --initial-phase-deg (phi_0 entered) or --phase-reference FILE (phi_0 measured), not both")


def _response_points(srcs, freqs, amplitudes, o, *, progress: Progress, job: str):
    """One :class:`ResponsePoint` per recording, with the unit of its sensitivity."""
    from senscal.vibration import response_point

    _distinct(srcs)
    chans = [o.output] + ([o.reference] if o.reference else []) + ([o.angle] if o.angle else [])
    phi0 = None if o.initial_phase_deg is None else math.radians(o.initial_phase_deg)
    points, units = [], _Units(o.output_unit)
    s0 = s_ref = None
    for i, (src, f, a) in enumerate(progress(list(zip(srcs, freqs, amplitudes)), "fitting")):
        rec, label = _read(src, o, chans, i)
        # Every channel in the run's unit (mV -> V, rad -> deg); options without a unit are in those units.
        output = rec[o.output] * units.scale(rec, o.output, "output", label)
        unit = units.unit("output") + "/(m/s^2)"
        reference = angle = None
        if o.reference:
            reference = rec[o.reference] * units.scale(rec, o.reference, "reference", label)
            s_ref = _bare_or_converted(o.reference_sensitivity, units.unit("reference") + "/(m/s^2)",
                                       "--reference-sensitivity")
        if o.angle:
            angle = rec[o.angle] * units.scale(rec, o.angle, "angle", label)
        s0 = _bare_or_converted(o.static_sensitivity, unit, "--static-sensitivity")
        points.append(with_time_warnings(response_point(
            output, rec.time, input_amplitude=a, reference=reference,
            reference_sensitivity=s_ref, angle_deg=angle, freq=f,
            static_sensitivity=s0, initial_phase=phi0,
            u_input_phase=math.radians(o.u_initial_phase_deg), u_input=o.u_input,
            u_reference_sensitivity=o.u_reference, u_static_sensitivity=o.u_static_sensitivity, drift=o.drift,
            harmonics=o.harmonics, encoder_lines=o.encoder_lines, u_angle=math.radians(o.u_angle_deg),
            source=label, unit=unit), rec.time, job,
            y=output if f is not None else None, known_hz=f))
    ref = (s_ref, units.unit("reference") + "/(m/s^2)") if o.reference else (None, "")
    return points, unit, s0, ref


def _measured_phase_reference(srcs, o: ResponseOptions):
    """phi_0 from the start-up run, and the text the result quotes about it."""
    from senscal.vibration import phase_reference_run

    ref_src = o.phase_reference
    rec, label = _read(ref_src, o, [o.output, o.angle], 0)
    if not isinstance(ref_src, Recording):
        # The reference may be one of the response records (the lowest-frequency run): same label, one fit.
        same = [str(s) for s in srcs if not isinstance(s, Recording)
                and os.path.realpath(s) == os.path.realpath(ref_src)]
        label = same[0] if same else str(ref_src)
    units = _Units(o.output_unit)
    ref = phase_reference_run(rec[o.output] * units.scale(rec, o.output, "output", label), rec.time,
                              rec[o.angle] * units.scale(rec, o.angle, "angle", label), harmonics=o.harmonics,
                              drift=o.drift, encoder_lines=o.encoder_lines, source=label)
    shown = (ref_src.source or "(a recording in memory)") if isinstance(ref_src, Recording) else ref_src
    text = (f"phi_0 = {math.degrees(ref.phase):.4f} deg at encoder zero from the {ref.frequency:.4g} Hz "
            f"run {shown} (its own delay extrapolated from the points above it, odd cubic in frequency)")
    return ref, text


@dataclass(frozen=True)
class ResponseResult(JobResult):
    """An accelerometer's frequency response with GUM budgets.

    Attributes
    ----------
    response : FrequencyResponse
        Points sorted by frequency: sensitivity (``unit``), S_i/S0, phase delay (rad).
    repeats : tuple of RepeatedPoint
        The points combined per frequency (one per frequency; shown when some frequency repeats).
    unit : str
        Sensitivity unit, e.g. ``V/(m/s^2)``.
    static_sensitivity : float or None
        S0 in ``unit`` (converted when given with another unit).
    input_amplitude : float or None
        Known peak input in m/s^2 (converted when given with a unit).
    reference_sensitivity : float or None
        Back-to-back reference sensitivity in ``reference_unit``.
    reference_unit : str
        Unit of ``reference_sensitivity`` ('' without a reference).
    phase_reference_run : PhaseReference or None
        phi_0 measured from a start-up run, when one was given.
    warnings : tuple of str
        Named warnings.
    """

    job: ClassVar[str] = "response"
    response: Any
    repeats: tuple = ()
    unit: str = ""
    static_sensitivity: Optional[float] = None
    input_amplitude: Optional[float] = None
    reference_sensitivity: Optional[float] = None
    reference_unit: str = ""
    phase_reference_run: Any = None
    warnings: tuple[str, ...] = ()

    @property
    def repeated(self) -> bool:
        """True when some frequency was measured more than once."""
        return len(self.repeats) < len(self.response.points)

    def to_dict(self) -> dict[str, Any]:
        resp = self.response
        doc: dict[str, Any] = {
            "points": [{"file": p.source, "frequency_hz": p.frequency, "u_frequency_hz": p.u_frequency,
                        "input_amplitude": p.input_amplitude, "output_amplitude": p.output_amplitude,
                        "u_output_amplitude": p.u_output_amplitude,
                        "sensitivity": p.sensitivity, "u_sensitivity": p.u_sensitivity,
                        "U_sensitivity": p.sensitivity_budget.expanded,
                        "normalized_sensitivity": p.normalized_sensitivity,
                        "u_normalized_sensitivity": p.u_normalized_sensitivity,
                        "U_normalized_sensitivity": _expanded(p.normalized_budget),
                        "phase_deg": math.degrees(p.phase), "u_phase_deg": math.degrees(p.u_phase),
                        "phase_delay_deg": _deg(p.phase_delay), "u_phase_delay_deg": _deg(p.u_phase_delay),
                        "U_phase_delay_deg": _deg(_expanded(p.phase_delay_budget)),
                        "phase_reference": p.phase_reference, "warnings": list(p.warnings),
                        "angle_step_deg": p.angle_step_deg, "angle_model": p.angle_model,
                        "revolutions": p.sync.revolutions if p.sync else None, "n_samples": p.n_samples,
                        "snr_db": p.snr_db, "method": p.method,
                        "sensitivity_budget": p.sensitivity_budget, "normalized_budget": p.normalized_budget,
                        "phase_delay_budget": p.phase_delay_budget} for p in resp.points],
            "unit": self.unit, "static_sensitivity": self.static_sensitivity,
            "coverage_factor": max(b.coverage_factor for p in resp.points
                                   for b in (p.sensitivity_budget, p.normalized_budget, p.phase_delay_budget)
                                   if b is not None),
            "method": resp.points[0].method, "phase_reference": resp.phase_reference,
        }
        if self.repeated:
            doc["repeats"] = [{"frequency_hz": g.frequency, "n_repeats": g.n_repeats, "files": list(g.sources),
                               "sensitivity": g.sensitivity, "u_sensitivity": g.u_sensitivity,
                               "U_sensitivity": g.sensitivity_budget.expanded,
                               "sensitivity_std": g.sensitivity_std, "normalized_sensitivity": g.normalized_sensitivity,
                               "u_normalized_sensitivity": g.u_normalized_sensitivity,
                               "U_normalized_sensitivity": _expanded(g.normalized_budget),
                               "phase_delay_deg": _deg(g.phase_delay), "u_phase_delay_deg": _deg(g.u_phase_delay),
                               "U_phase_delay_deg": _deg(_expanded(g.phase_delay_budget)),
                               "coverage_factor": g.sensitivity_budget.coverage_factor,
                               "sensitivity_budget": g.sensitivity_budget, "normalized_budget": g.normalized_budget,
                               "phase_delay_budget": g.phase_delay_budget, "warnings": list(g.warnings)}
                              for g in self.repeats]
        doc["warnings"] = list(self.warnings)
        return to_jsonable(doc)

    def quantities(self) -> tuple[Quantity, ...]:
        """Per frequency: ``sensitivity@<f>Hz`` and, where defined, ``normalized_sensitivity@<f>Hz`` (unit 1)
        and ``phase_delay@<f>Hz`` (deg), f with 4 significant digits.

        A frequency measured more than once is stored once, as its repeats combined (with the coverage
        factor of their budget: Student's t when the type A part comes from few repeats); single points
        are quoted with k = 2.
        """
        qs = []
        for p in (self.repeats if self.repeated else self.response.points):
            tag = f"{p.frequency:.4g}Hz"

            def k_of(budget):
                return float(budget.coverage_factor) if self.repeated and budget is not None else 2.0

            qs.append(Quantity(f"sensitivity@{tag}", float(p.sensitivity), float(p.u_sensitivity), self.unit,
                               k_of(p.sensitivity_budget)))
            if _finite_or_none(p.normalized_sensitivity) is not None:
                qs.append(Quantity(f"normalized_sensitivity@{tag}", float(p.normalized_sensitivity),
                                   float(p.u_normalized_sensitivity), "1", k_of(p.normalized_budget)))
            if _finite_or_none(p.phase_delay) is not None:
                qs.append(Quantity(f"phase_delay@{tag}", math.degrees(p.phase_delay),
                                   math.degrees(p.u_phase_delay), "deg", k_of(p.phase_delay_budget)))
        return tuple(qs)

    def to_dataframe(self):
        """One row per recording (frequency point): sensitivity, S_i/S0, phase delay (deg) with u and U."""
        return _points_frame(self.to_dict()["points"])


def response(sources: Sources, options: ResponseOptions = ResponseOptions(), *,
             progress: Progress = _no_progress) -> ResponseResult:
    """Accelerometer frequency response: sensitivity, S_i/S0 and phase delay with GUM budgets.

    Parameters
    ----------
    sources : path, Recording, or sequence of them
        One recording per frequency point (repeats at one frequency are combined).
    options : ResponseOptions
    progress : callable, optional
        ``progress(items, description)`` wrapping the loop over recordings.

    Returns
    -------
    ResponseResult

    Raises
    ------
    InputError
        Contradictory or missing options, a recording given twice, bad data.

    References
    ----------
    Qin et al., double-centrifuge dynamic calibration (seed 003); ISO 16063-21 (back-to-back).
    """
    from senscal.vibration import apply_phase_reference, combine_repeats, frequency_response
    from senscal.vibration.budget import unique_warnings

    o = options
    _check_response_options(o)
    srcs = _as_list(sources)
    amplitude = _bare_or_converted(o.input_amplitude, "m/s^2", "--input-amplitude")
    points, unit, s0, (s_ref, ref_unit) = _response_points(srcs, _freqs(o.freq, len(srcs)),
                                                           [amplitude] * len(srcs), o, progress=progress,
                                                           job="response")
    ref, text = None, None
    if o.phase_reference is not None:
        ref, text = _measured_phase_reference(srcs, o)
        points = list(apply_phase_reference(points, ref))
    elif o.initial_phase_deg is not None:
        text = (f"phi_0 = {o.initial_phase_deg:g} deg entered (u = {o.u_initial_phase_deg:g} deg)"
                + (" at encoder zero" if o.angle else " at t = 0"))
    resp = frequency_response(points, unit=unit, static_sensitivity=s0, phase_reference=text)
    reps = combine_repeats(resp.points)
    warns = tuple(resp.warnings)
    if len(reps) < len(resp.points):
        warns = tuple(unique_warnings(warns, *(g.warnings for g in reps)))
    return ResponseResult(response=resp, repeats=tuple(reps), unit=unit, static_sensitivity=s0,
                          input_amplitude=amplitude, reference_sensitivity=s_ref, reference_unit=ref_unit,
                          phase_reference_run=ref, warnings=warns)


# ---------------------------------------------------------------------------
# linearity
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class LinearityOptions(_ReadOptions):
    """Options of :func:`linearity`.

    Attributes
    ----------
    output : str
        Accelerometer output channel.
    input_amplitudes : tuple of float
        Peak input of each recording (m/s^2), in the order of the recordings.
    freq : float, optional
        Known frequency (Hz); estimated per recording when None.
    angle : str, optional
        Turntable angle channel (deg): fit against the angle.
    drift : bool
        Fit a linear offset drift.
    harmonics : int
        Harmonics fitted with the fundamental.
    u_input : float
        Relative standard uncertainty of each input level, random from level to level (fraction).
    """

    output: Optional[str] = None
    input_amplitudes: Tuple[float, ...] = ()
    freq: Optional[float] = None
    angle: Optional[str] = None
    drift: bool = False
    harmonics: int = 1
    u_input: float = 0.0


@dataclass(frozen=True)
class LinearityResult(JobResult):
    """Amplitude linearity at a fixed frequency.

    Attributes
    ----------
    linearity : AmplitudeLinearity
        Best straight line (slope in ``unit``), deviations, linearity in % of full scale.
    points : tuple of ResponsePoint
        The sine fit of each recording (its frequency, output amplitude and u).
    unit : str
        Slope unit, e.g. ``V/(m/s^2)``.
    output_unit : str
        Unit of the sensor output, e.g. ``V``.
    warnings : tuple of str
        Named warnings.
    """

    job: ClassVar[str] = "linearity"
    linearity: Any
    points: tuple = ()
    unit: str = ""
    output_unit: str = ""
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        lin = self.linearity
        return to_jsonable({
            "points": [{"file": p.source, "input_amplitude": p.input_amplitude, "output_amplitude": p.output_amplitude,
                        "u_output_amplitude": p.u_output_amplitude, "deviation": p.deviation,
                        "deviation_percent": p.deviation_percent, "frequency_hz": rp.frequency}
                       for p, rp in zip(lin.points, self.points)],
            "slope": lin.slope, "u_slope": lin.u_slope, "U_slope": lin.coverage_factor * lin.u_slope,
            "intercept": lin.intercept, "u_intercept": lin.u_intercept,
            "U_intercept": lin.coverage_factor * lin.u_intercept, "coverage_factor": lin.coverage_factor,
            "dof": lin.dof, "birge_ratio": lin.birge_ratio, "chi2_p": lin.chi2_p,
            "linearity_percent": lin.linearity_percent, "u_linearity_percent": lin.u_linearity_percent,
            "U_linearity_percent": 2 * lin.u_linearity_percent, "linearity_resolved": lin.linearity_resolved,
            "linearity_bound_percent": lin.linearity_bound_percent,
            "full_scale_output": lin.full_scale_output, "unit": self.unit, "output_unit": self.output_unit,
            "warnings": list(self.warnings),
        })

    def quantities(self) -> tuple[Quantity, ...]:
        """``linearity_slope`` (``unit``) and ``linearity_percent`` (% of full scale)."""
        lin = self.linearity
        return (Quantity("linearity_slope", float(lin.slope), float(lin.u_slope), self.unit),
                Quantity("linearity_percent", float(lin.linearity_percent), float(lin.u_linearity_percent), "%"))

    def to_dataframe(self):
        """One row per input level: input (m/s^2), output amplitude and u, deviation from the line."""
        return _points_frame(self.to_dict()["points"])


def linearity(sources: Sources, options: LinearityOptions = LinearityOptions(), *,
              progress: Progress = _no_progress) -> LinearityResult:
    """Amplitude linearity at a fixed frequency: best straight line, deviations, linearity in % of full scale.

    Parameters
    ----------
    sources : path, Recording, or sequence of them
        One recording per input level.
    options : LinearityOptions
        ``input_amplitudes`` gives one peak input (m/s^2) per recording.
    progress : callable, optional
        ``progress(items, description)`` wrapping the loop over recordings.

    Returns
    -------
    LinearityResult

    Raises
    ------
    InputError
        Not one positive input amplitude per recording, bad data.

    References
    ----------
    Qin et al., double-centrifuge dynamic calibration (seed 003).
    """
    from senscal.vibration import amplitude_linearity

    o = options
    _need(o.output, "--output", "the accelerometer output channel")
    srcs = _as_list(sources)
    amps = [float(a) for a in o.input_amplitudes]
    if len(amps) != len(srcs):
        raise InputError(f"give one input amplitude per file: {len(amps)} amplitudes for {len(srcs)} files")
    if any(not a > 0 for a in amps):
        raise InputError("--input-amplitudes must be positive (m/s^2)")
    points, unit, _, _ = _response_points(srcs, [o.freq] * len(srcs), amps, _as_response(o), progress=progress,
                                       job="response")
    lin = amplitude_linearity(amps, [p.output_amplitude for p in points], [p.u_output_amplitude for p in points],
                              [p.source for p in points], u_input=o.u_input)
    # an absolute phase is not part of linearity: its unknown reference is no departure here
    warns = tuple(lin.warnings) + tuple(w for w in dict.fromkeys(w for p in points for w in p.warnings)
                                        if not w.startswith("phase-reference-unknown:"))
    return LinearityResult(linearity=lin, points=tuple(points), unit=unit, output_unit=unit.split("/(m/s^2)")[0],
                           warnings=warns)


def _as_response(o: LinearityOptions) -> ResponseOptions:
    """The per-record fit options of a linearity run (a known input level, no reference).

    The input level's own u enters the line fit (random from level to level), not each point's budget.
    """
    return ResponseOptions(output=o.output, angle=o.angle, drift=o.drift, harmonics=o.harmonics, u_input=0.0,
                           output_unit=o.output_unit, **ReadOptions.words(vars(o)))
