"""Shock calibration (``senscal shock``): ISO 16063-22 comparison and ISO 16063-13 laser primary (issue 28)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, source_name

__all__ = ["ShockOptions", "ShockResult", "shock"]

_LASER_UNITS = {"velocity": "m/s", "displacement": "m"}

# budget keys -> the components as the certificate names them (ISO 16063-22 comparison, ISO 16063-13 primary)
_ISO_16063 = {
    "reference_peak": "reference accelerometer's peak: noise, zero line and filter (ISO 16063-22)",
    "laser_peak": "laser's peak: noise, differentiation and filter (ISO 16063-13)",
    "output_peak": "output's peak: noise, zero line and filter",
    "reference_sensitivity": "reference accelerometer's sensitivity (its calibration, ISO 16063-22)",
    "zero_shift": "zero shift of the output (half the shift, rectangular)",
    "other": "other effects (transverse motion, mounting, amplitude linearity)",
}


@dataclass(frozen=True)
class ShockOptions(ReadOptions):
    """Options of :func:`shock` (the ``senscal shock`` options).

    Attributes
    ----------
    output : str
        Channel of the accelerometer under test.
    reference : str, optional
        Channel of the reference accelerometer (ISO 16063-22 comparison).
    reference_sensitivity : float or str, optional
        Reference sensitivity: a number in the reference channel's unit per m/s^2, or with a unit
        (``'0.1 mV/(m/s^2)'``).
    u_reference : float
        Relative standard u of the reference sensitivity (type B).
    laser : str, optional
        Channel of the laser (ISO 16063-13 primary): velocity (m/s, mm/s ...) or displacement (m, um ...),
        told by its unit.
    laser_quantity : {"velocity", "displacement"}, optional
        What the laser channel measures when its unit is not in the file (then in m/s or m).
    lowpass_hz : float, optional
        The stated low-pass (zero-phase Butterworth, -6 dB here) applied alike to both channels.
    lowpass_order : int
        Its order.
    u_other : float
        Other relative standard u (type B: transverse motion, mounting, amplitude linearity ...).
    """

    output: str = "out"
    reference: str | None = None
    reference_sensitivity: float | str | None = None
    u_reference: float = 0.0
    laser: str | None = None
    laser_quantity: str | None = None
    lowpass_hz: float | None = None
    lowpass_order: int = 4
    u_other: float = 0.0


@dataclass(frozen=True)
class ShockResult(JobResult):
    """A shock calibration: one entry per pulse (all files).

    Attributes
    ----------
    pulses : tuple of senscal.shock.ShockPulse
    sources : tuple of str
        The file of each pulse.
    method : str
    unit : str
        Sensitivity unit (output unit per m/s^2).
    filter : str
        The stated low-pass, in words ("none" without one).
    warnings : tuple of str
    """

    job: ClassVar[str] = "shock"

    pulses: tuple
    sources: tuple[str, ...]
    method: str
    unit: str
    filter: str
    warnings: tuple[str, ...] = ()
    output_unit: str = ""

    @property
    def comparison(self) -> bool:
        """ISO 16063-22 comparison (True) or ISO 16063-13 laser primary (False)."""
        return "16063-22" in self.method

    def sensitivity_unit(self, output_unit: str | None = None) -> str:
        """The sensitivity's unit as a quantity, ``'<output unit>/(m/s^2)'`` (V when neither file nor option says)."""
        return f"{self.output_unit or output_unit or 'V'}/(m/s^2)"

    def budgets(self, output_unit: str | None = None) -> tuple:
        """Each pulse's sensitivity budget with its components named after ISO 16063-22 / -13.

        Parameters
        ----------
        output_unit : str, optional
            The output's unit when the files give none (default V).

        Returns
        -------
        tuple of senscal.vibration.budget.UncertaintyBudget
            Standard u of each component in the sensitivity's unit; k = 2.
        """
        from senscal.vibration.budget import make_budget

        unit = self.sensitivity_unit(output_unit)

        def kept(k: str, v: dict) -> bool:
            # a laser has no reference sensitivity, and a zero shift not found beyond chance is not applied:
            # neither is a type B input given as 0 (which the certificate's budget-zero-component would name)
            return not ((k == "reference_sensitivity" and not self.comparison) or (k == "zero_shift" and not v["u_rel"]))

        return tuple(make_budget("shock sensitivity", p.sensitivity, unit,
                                 [(_ISO_16063.get(k, k), v["type"], abs(p.sensitivity) * v["u_rel"])
                                  for k, v in p.budget.items() if kept(k, v)], 2.0) for p in self.pulses)

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal shock --json`` document."""
        pts = []
        for src, p in zip(self.sources, self.pulses):
            d = p.to_dict()
            d["file"] = src
            pts.append(d)
        return to_jsonable({"method": self.method, "sensitivity_unit": self.unit, "filter": self.filter,
                            "pulses": pts, "warnings": list(self.warnings)})

    def quantities(self) -> tuple[Quantity, ...]:
        """The peak-ratio sensitivity of each pulse, named by its duration and peak acceleration."""
        return tuple(Quantity(f"shock_sensitivity@{p.duration_ms:.3g}ms,{abs(p.peak_acceleration):.4g}m/s^2#{i}",
                              p.sensitivity, p.u_sensitivity, self.unit) for i, p in enumerate(self.pulses))

    def to_dataframe(self):
        import pandas as pd

        cols = ["file", "index", "duration_ms", "peak_acceleration", "sensitivity", "u_sensitivity"]
        return pd.DataFrame([{c: d[c] for c in cols} for d in self.to_dict()["pulses"]], columns=cols)


def _laser_quantity(unit: str, given: str | None, channel: str) -> tuple[str, float]:
    """(velocity|displacement, factor to m/s or m) from the channel's unit, or the option when it has none."""
    from senscal.units import compatible, factor

    if given is not None and given not in _LASER_UNITS:
        raise InputError(f"--laser-quantity must be velocity or displacement, got {given!r}")
    if not unit:
        if given is None:
            raise InputError(f"the laser channel {channel} has no unit in the file: say what it measures with "
                             "--laser-quantity velocity (m/s) or displacement (m)")
        return given, 1.0
    for q, want in _LASER_UNITS.items():
        if compatible(unit, want):
            if given is not None and given != q:
                raise InputError(f"--laser-quantity {given} contradicts the laser channel's unit {unit} ({q})")
            return q, factor(unit, want, what=f"the laser channel {channel}")
    raise InputError(f"the laser channel {channel} is in {unit}: a laser gives velocity (m/s) or displacement (m)")


def _is_bare_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def shock(source, options: ShockOptions = ShockOptions()) -> ShockResult:
    """Shock sensitivity of an accelerometer from half-sine pulses, one or more per recording.

    Parameters
    ----------
    source : str, Path, Recording or sequence of them
        Recordings with the output channel and the reference (or laser) channel.
    options : ShockOptions

    Returns
    -------
    ShockResult

    Raises
    ------
    SenscalError
        Neither or both of --reference and --laser, a missing reference sensitivity, no pulse, a pulse
        too short for the sample rate, a clipped channel (one line, with the fix).
    """
    from senscal.io.plausibility import merge_time_warnings
    from senscal.shock import shock_pulses
    from senscal.units import parse_quantity

    o = options
    if (o.reference is None) == (o.laser is None):
        raise InputError("give either --reference CH with --reference-sensitivity S (ISO 16063-22 comparison) or "
                         "--laser CH (ISO 16063-13 primary)")
    if o.reference is not None and o.reference_sensitivity is None:
        raise InputError("--reference needs --reference-sensitivity (reference output per m/s^2, e.g. "
                         "'0.1 mV/(m/s^2)')")
    if o.laser is not None and (o.reference_sensitivity is not None or o.u_reference):
        raise InputError("--reference-sensitivity and --u-reference describe a reference accelerometer, not a laser")
    other = o.reference or o.laser
    if o.output == other:
        raise InputError(f"--output {o.output} is also the {'reference' if o.reference else 'laser'} channel; name "
                         "the accelerometer under test")
    if o.lowpass_hz is not None and not (math.isfinite(o.lowpass_hz) and o.lowpass_hz > 0):
        raise InputError(f"--lowpass-hz must be a positive number of Hz, got {o.lowpass_hz!r}")
    sources: Sequence[Any] = list(source) if isinstance(source, (list, tuple)) else [source]
    if not sources:
        raise InputError("senscal shock needs at least one recording")
    pulses, names, units, warnings = [], [], set(), []
    method = ("ISO 16063-22 comparison with a reference accelerometer (peak ratio, transfer function)"
              if o.reference else "ISO 16063-13 primary by laser (differentiated, peak ratio, transfer function)")
    from senscal.diagnostics import named
    from senscal.jobs._units import CommonUnit, check_magnitude, check_session_time

    # One file in mV, another in V: every file in the first's unit (a bare --reference-sensitivity too).
    common_out = CommonUnit(o.output, "--output")
    common_ref = CommonUnit(o.reference or "", "--reference")
    for src in sources:
        rec = o.read(src, channels=[o.output, other], job="shock")
        check_session_time(rec, source_name(src), "shock")
        check_magnitude(rec, [o.output, other], source_name(src))
        fs = float(rec.fs) if rec.fs else 1.0 / float(np.median(np.diff(np.asarray(rec.time, float))))
        name = source_name(src)
        ref = np.asarray(rec.channels[other], float)
        out = common_out.factor(rec.unit(o.output), name) * np.asarray(rec.channels[o.output], float)
        kw: dict[str, Any] = {}
        if o.reference:
            ref = common_ref.factor(rec.unit(o.reference), name) * ref
            runit = common_ref.unit or "V"
            if not common_ref.unit and isinstance(o.reference_sensitivity, str) and \
                    not _is_bare_number(o.reference_sensitivity):
                warnings.append(named("reference-unit-assumed", f"{name} gives no unit for the reference channel "
                                      f"{o.reference}: read in V to match --reference-sensitivity "
                                      f"{o.reference_sensitivity}; write its unit in the header "
                                      f"(e.g. '{o.reference} [V]')"))
            kw["reference_sensitivity"] = parse_quantity(o.reference_sensitivity, f"{runit}/(m/s^2)",
                                                         option="--reference-sensitivity")
            kw["u_reference_rel"] = float(o.u_reference)
        else:
            q, fac = _laser_quantity(rec.unit(o.laser), o.laser_quantity, o.laser)
            ref = ref * fac
            kw["laser"] = q
            if "by laser (" in method:
                method = method.replace("by laser (", f"by laser {q} (")
        try:
            ps = shock_pulses(ref, out, fs, cutoff_hz=o.lowpass_hz,
                              filter_order=int(o.lowpass_order), u_other_rel=float(o.u_other), **kw)
        except InputError as exc:
            raise type(exc)(f"{name}: {exc}") from None
        units.add(common_out.unit)
        for p in ps:
            pulses.append(p)
            names.append(name)
            warnings.extend(f"{w} ({name})" for w in p.warnings)
        warnings.extend(merge_time_warnings((), rec.warnings))
    unit = units.pop() if len(units) == 1 else ""
    filt = "none" if o.lowpass_hz is None else (f"zero-phase Butterworth order {int(o.lowpass_order)}, "
                                                 f"-6 dB at {o.lowpass_hz:g} Hz, on both channels")
    return ShockResult(pulses=tuple(pulses), sources=tuple(names), method=method,
                       unit=f"{unit or 'output'} per m/s^2", filter=filt, warnings=tuple(dict.fromkeys(warnings)),
                       output_unit=unit)
