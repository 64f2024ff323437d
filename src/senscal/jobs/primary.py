"""Primary vibration calibration by laser interferometry (``senscal primary``, ISO 16063-11 method 3, issue 28)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, source_name

__all__ = ["PrimaryOptions", "PrimaryResult", "primary"]


def _pair(names: Any) -> tuple[str, str]:
    listed = [s.strip() for s in names.split(",") if s.strip()] if isinstance(names, str) else list(names or ())
    if len(listed) != 2:
        raise InputError(f"--quadrature needs two channel names I,Q (the interferometer's quadrature outputs), "
                         f"got {names!r}; a single channel is not a quadrature pair")
    if listed[0] == listed[1]:
        raise InputError(f"--quadrature names one channel twice ({listed[0]}): a single channel is not a "
                         "quadrature pair; give the I and Q outputs")
    return str(listed[0]), str(listed[1])


# budget keys -> (sensitivity component, phase component) as the certificate names them (ISO 16063-11 Annex A)
_ANNEX_A = {
    "displacement_fit": ("interferometer signal disturbance (displacement fit)", "interferometer signal disturbance"),
    "output_fit": ("output voltage measurement, noise (output fit)", "output phase measurement, noise (output fit)"),
    "unmodelled_slices": ("residual effects (per-period fits)", "residual effects (per-period fits)"),
    "heydemann": ("quadrature output disturbance (Heydemann correction)",
                  "quadrature output disturbance (Heydemann correction)"),
    "frequency": ("frequency measurement", "frequency measurement"),
    "wavelength": ("laser wavelength", "laser wavelength"),
    "output_gain": ("output voltage amplitude measurement", "output voltage phase measurement"),
    "other": ("other effects (transverse, rocking, base strain, mounting)",
              "other effects (transverse, rocking, base strain, mounting)"),
    "demodulation_filter": ("heterodyne demodulation filter (ripple, stopband)",
                            "heterodyne demodulation filter (ripple, stopband)"),
}

HETERODYNE_METHOD = "ISO 16063-41 style heterodyne carrier (quadrature mixing, low-pass), sine approximation"


@dataclass(frozen=True)
class PrimaryOptions(ReadOptions):
    """Options of :func:`primary` (the ``senscal primary`` options).

    Attributes
    ----------
    quadrature : str or (str, str)
        Channels of the interferometer's quadrature outputs, I then Q.
    output : str
        Channel of the accelerometer's output.
    wavelength_nm : float
        Laser wavelength, nm (632.8 for a HeNe).
    freq : float, optional
        Excitation frequency, Hz (estimated per file when omitted).
    harmonics : int
        Harmonics fitted with the fundamental (exciter distortion).
    drift : bool
        Fit a linear drift of the offsets.
    slices : int
        Per-period (sliced) fits for the type A term of what the model lacks.
    u_wavelength_rel, u_gain_rel, u_other_rel : float
        Type B relative standard uncertainties (wavelength; output voltage
        measurement; other, e.g. transverse motion).
    u_gain_phase_deg, u_other_phase_deg : float
        Type B phase standard uncertainties, deg.
    sign_check : bool
        Refuse an output near 180 deg from the acceleration (I/Q swapped).
    heterodyne : str, optional
        Channel of a heterodyne interferometer's carrier (instead of ``quadrature``).
    carrier_hz : float, optional
        Its nominal carrier frequency, Hz.
    carrier_channel : str, optional
        Channel of the reference carrier (cancels the carrier's offset and drift).
    carrier_sign : int
        -1 when the Doppler phase runs against the displacement.
    """

    quadrature: str | tuple[str, str] = ("I", "Q")
    output: str = "out"
    wavelength_nm: float = 632.8
    freq: float | None = None
    harmonics: int = 3
    drift: bool = True
    slices: int = 10
    u_wavelength_rel: float = 0.0
    u_gain_rel: float = 0.0
    u_gain_phase_deg: float = 0.0
    u_other_rel: float = 0.0
    u_other_phase_deg: float = 0.0
    sign_check: bool = True
    heterodyne: str | None = None
    carrier_hz: float | None = None
    carrier_channel: str | None = None
    carrier_sign: int = 1


@dataclass(frozen=True)
class PrimaryResult(JobResult):
    """A primary calibration: one point per recording.

    Attributes
    ----------
    points : tuple of senscal.primary.PrimaryPoint
        Sorted by frequency.
    sources : tuple of str
    quadrature : (str, str)
    output : str
    unit : str
        Sensitivity unit (output unit per m/s^2).
    wavelength_nm : float
    warnings : tuple of str
    """

    job: ClassVar[str] = "primary"

    points: tuple
    sources: tuple[str, ...]
    quadrature: tuple[str, str]
    output: str
    unit: str
    wavelength_nm: float
    warnings: tuple[str, ...] = ()
    output_unit: str = ""
    demodulations: tuple = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal primary --json`` document."""
        pts = []
        for i, (src, p) in enumerate(zip(self.sources, self.points)):
            d = p.to_dict()
            d["file"] = src
            if self.demodulations:
                d["demodulation"] = self.demodulations[i].to_dict()
            pts.append(d)
        method = (HETERODYNE_METHOD if self.demodulations else
                  "ISO 16063-11 method 3 (homodyne quadrature, sine approximation)")
        return to_jsonable({"method": method,
                            "quadrature": list(self.quadrature), "output": self.output,
                            "wavelength_nm": self.wavelength_nm, "sensitivity_unit": self.unit,
                            "phase_unit": "deg", "points": pts, "warnings": list(self.warnings)})

    def quantities(self) -> tuple[Quantity, ...]:
        """Sensitivity and phase at each frequency."""
        out = []
        for p in self.points:
            tag = f"{p.frequency_hz:g}Hz"
            out.append(Quantity(f"sensitivity@{tag}", p.sensitivity, p.u_sensitivity, self.unit))
            out.append(Quantity(f"phase@{tag}", p.phase_deg, p.u_phase_deg, "deg"))
        return tuple(out)

    def response(self, output_unit: str | None = None):
        """The points as a :class:`~senscal.vibration.FrequencyResponse`, for the certificate and the DCC.

        Each point's budget becomes a GUM budget with the components of ISO 16063-11 Annex A by name; the
        phase delay is ``phase_deg`` (output minus acceleration, negative for a lag, as in ``response``).

        Parameters
        ----------
        output_unit : str, optional
            The output's unit when the files give none (default V).
        """
        from senscal.vibration.budget import make_budget
        from senscal.vibration.response import FrequencyResponse, ResponsePoint

        from senscal.units import same_unit

        if self.output_unit and output_unit and not same_unit(self.output_unit, output_unit):
            raise InputError(f"--output-unit {output_unit} contradicts the recordings, whose header gives "
                             f"{self.output} in {self.output_unit}; drop --output-unit (it is for files without one)")
        unit = f"{self.output_unit or output_unit or 'V'}/(m/s^2)"
        pts = []
        for src, p in zip(self.sources, self.points):
            s_comp = [(_ANNEX_A[k][0], v["type"], abs(p.sensitivity) * v["u_rel"]) for k, v in p.budget.items()]
            ph_comp = [(_ANNEX_A[k][1], v["type"], math.radians(v["u_phase_deg"])) for k, v in p.budget.items()
                       if k != "frequency" and k != "wavelength"]
            out_amp = p.sensitivity * p.acceleration
            rms = float(p.residual.get("output_rms", float("nan")))
            snr = 20.0 * math.log10(abs(out_amp) / (math.sqrt(2.0) * rms)) if rms > 0 else float("inf")
            pts.append(ResponsePoint(
                source=src, method=(HETERODYNE_METHOD if self.demodulations else
                                    "ISO 16063-11 method 3 (homodyne quadrature, sine approximation)"),
                frequency=p.frequency_hz, u_frequency=0.5 * p.frequency_hz * p.budget["frequency"]["u_rel"],
                input_amplitude=p.acceleration, output_amplitude=out_amp,
                u_output_amplitude=abs(out_amp) * p.budget["output_fit"]["u_rel"], sensitivity=p.sensitivity,
                u_sensitivity=p.u_sensitivity, normalized_sensitivity=None, u_normalized_sensitivity=None,
                phase=math.radians(p.phase_deg), u_phase=math.radians(p.u_phase_deg),
                phase_delay=math.radians(p.phase_deg), u_phase_delay=math.radians(p.u_phase_deg),
                sensitivity_budget=make_budget("sensitivity", p.sensitivity, unit, s_comp),
                normalized_budget=None,
                phase_delay_budget=make_budget("phase delay", math.radians(p.phase_deg), "rad", ph_comp),
                sync=None, n_samples=0, snr_db=snr, phase_reference="laser interferometer (displacement)",
                warnings=tuple(p.warnings)))
        return FrequencyResponse(points=tuple(pts), unit=unit, static_sensitivity=None,
                                 phase_reference="the table's displacement by laser interferometry",
                                 warnings=tuple(self.warnings))

    def to_dataframe(self):
        import pandas as pd

        cols = ["file", "frequency_hz", "sensitivity", "u_sensitivity", "phase_deg", "u_phase_deg", "fringes"]
        return pd.DataFrame([{c: d[c] for c in cols} for d in self.to_dict()["points"]], columns=cols)


def primary(source, options: PrimaryOptions = PrimaryOptions()) -> PrimaryResult:
    """Calibrate an accelerometer against a homodyne quadrature interferometer, one recording per frequency.

    Parameters
    ----------
    source : str, Path, Recording or sequence of them
        One recording per frequency, each with the I, Q and output channels.
    options : PrimaryOptions

    Returns
    -------
    PrimaryResult

    Raises
    ------
    SenscalError
        Missing channels, I/Q swapped, one channel given as a pair, a
        wavelength in metres, too few fringes (one line, with the fix).
    """
    from senscal.primary import calibrate_point
    from senscal.primary.core import check_wavelength
    from senscal.primary.repeats import repeat_warnings

    o = options
    check_wavelength(o.wavelength_nm)
    for opt, v in (("--u-wavelength-rel", o.u_wavelength_rel), ("--u-gain-rel", o.u_gain_rel),
                   ("--u-other-rel", o.u_other_rel), ("--u-gain-phase-deg", o.u_gain_phase_deg),
                   ("--u-other-phase-deg", o.u_other_phase_deg)):
        # a standard uncertainty: a negative one entered the budget as given, NaN printed as null, 1e308 overflowed
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and 0 <= v < 1e6):
            raise InputError(f"{opt} is a standard uncertainty: a finite number, 0 or more (relative ones a "
                             f"fraction or a percentage like 0.2%), got {v!r}")
    if o.heterodyne:
        return _primary_heterodyne(source, o)
    qi, qq = _pair(o.quadrature)
    if o.output in (qi, qq):
        raise InputError(f"--output {o.output} is one of the quadrature channels; name the accelerometer's channel")
    sources = _sources(source, o)
    rows = []
    warnings: list[str] = []
    from senscal.jobs._units import CommonUnit
    from senscal.units import factor as unit_factor, same_unit

    common = CommonUnit(o.output, "--output")  # one file in mV, another in V: all in the first's unit
    for name, rec, fs, out in _each_file(sources, o, [qi, qq, o.output], common, warnings):
        # I in V and Q in mV: Q in I's unit, so that the gain ratio and the offsets are the interferometer's
        q_sig = np.asarray(rec.channels[qq], float)
        ui, uq = rec.unit(qi), rec.unit(qq)
        if ui and uq and not same_unit(ui, uq):
            q_sig = q_sig * unit_factor(uq, ui, what=f"quadrature channel '{qq}' of {name}",
                                        fix=f"I and Q are the two outputs of one interferometer ('{qi}' is in {ui})")
        try:
            p = calibrate_point(rec.channels[qi], q_sig, out, fs, freq=o.freq, wavelength_nm=o.wavelength_nm, harmonics=int(o.harmonics),
                                drift=bool(o.drift), slices=int(o.slices), u_wavelength_rel=o.u_wavelength_rel,
                                u_gain_rel=o.u_gain_rel, u_gain_phase_deg=o.u_gain_phase_deg,
                                u_other_rel=o.u_other_rel, u_other_phase_deg=o.u_other_phase_deg,
                                sign_check=o.sign_check)
        except InputError as exc:
            raise type(exc)(f"{name}: {exc}") from None
        warnings.extend(f"{w} ({name})" for w in p.warnings)
        rows.append((p.frequency_hz, name, p))
    rows.sort(key=lambda r: r[0])
    warnings.extend(repeat_warnings(r[2] for r in rows))
    raw_unit = common.unit or ""  # the first file's, every other file's output put in it
    unit = f"{raw_unit or 'output'} per m/s^2"
    return PrimaryResult(points=tuple(r[2] for r in rows), sources=tuple(r[1] for r in rows),
                         quadrature=(qi, qq), output=o.output, unit=unit, wavelength_nm=float(o.wavelength_nm),
                         warnings=tuple(dict.fromkeys(warnings)), output_unit=raw_unit)


def _sources(source, o: PrimaryOptions) -> Sequence[Any]:
    """The recordings (one per frequency) as a list, after the options both input modes share are checked."""
    if int(o.harmonics) < 1 or int(o.slices) < 0:
        raise InputError("--harmonics must be at least 1 and --slices not negative")
    sources: Sequence[Any] = list(source) if isinstance(source, (list, tuple)) else [source]
    if not sources:
        raise InputError("senscal primary needs at least one recording (one per frequency)")
    return sources


def _each_file(sources, o: PrimaryOptions, chans: list, common, warnings: list[str]):
    """Each recording read and checked as both input modes need it: yields ``(name, rec, fs, out)``.

    Parameters
    ----------
    sources : sequence
        The recordings, one per frequency.
    o : PrimaryOptions
    chans : list of str
        The channels to read (the output among them).
    common : senscal.jobs._units.CommonUnit
        The output's unit across files: ``out`` is the output channel in the first file's unit.
    warnings : list of str
        A file's time-base warnings are appended when the caller asks for the next file, that is after the
        caller appended the point's own warnings (the order the report lists them in).
    """
    from senscal.io.plausibility import merge_time_warnings
    from senscal.jobs._units import check_magnitude, check_session_time

    for src in sources:
        rec = o.read(src, channels=chans, job="primary")
        check_session_time(rec, source_name(src), "primary vibration")
        check_magnitude(rec, chans, source_name(src))
        fs = float(rec.fs) if rec.fs else 1.0 / float(np.median(np.diff(np.asarray(rec.time, float))))
        name = source_name(src)
        out = common.factor(rec.unit(o.output), name) * np.asarray(rec.channels[o.output], float)
        yield name, rec, fs, out
        warnings.extend(merge_time_warnings((), rec.warnings))


def _primary_heterodyne(source, o: PrimaryOptions) -> PrimaryResult:
    """:func:`primary` for a heterodyne carrier channel (``--heterodyne CH --carrier-hz F | --carrier-channel REF``)."""
    from senscal.primary.heterodyne import calibrate_heterodyne
    from senscal.primary.repeats import repeat_warnings

    het, ref = str(o.heterodyne), o.carrier_channel
    if o.carrier_hz is None and not ref:
        raise InputError("--heterodyne needs the carrier: give --carrier-hz F (Hz) or --carrier-channel REF")
    if o.output in (het, ref):
        raise InputError(f"--output {o.output} is the heterodyne or the carrier channel; name the accelerometer's")
    if ref == het:
        raise InputError(f"--carrier-channel {ref} is the heterodyne channel itself; name the reference carrier")
    if int(o.carrier_sign) not in (1, -1):
        raise InputError(f"--carrier-sign must be 1 or -1, got {o.carrier_sign!r}")
    sources = _sources(source, o)
    rows = []
    warnings: list[str] = []
    from senscal.jobs._units import CommonUnit

    common = CommonUnit(o.output, "--output")  # one file in mV, another in V: all in the first's unit
    for name, rec, fs, out in _each_file(sources, o, [het, o.output] + ([ref] if ref else []), common, warnings):
        try:
            p, dem = calibrate_heterodyne(rec.channels[het], out, fs, carrier_hz=o.carrier_hz,
                                          reference=rec.channels[ref] if ref else None, freq=o.freq,
                                          sign=int(o.carrier_sign), harmonics=int(o.harmonics),
                                          wavelength_nm=o.wavelength_nm, drift=bool(o.drift), slices=int(o.slices),
                                          u_wavelength_rel=o.u_wavelength_rel, u_gain_rel=o.u_gain_rel,
                                          u_gain_phase_deg=o.u_gain_phase_deg, u_other_rel=o.u_other_rel,
                                          u_other_phase_deg=o.u_other_phase_deg, sign_check=o.sign_check)
        except InputError as exc:
            raise type(exc)(f"{name}: {exc}") from None
        warnings.extend(f"{w} ({name})" for w in p.warnings)
        rows.append((p.frequency_hz, name, p, dem))
    rows.sort(key=lambda r: r[0])
    warnings.extend(repeat_warnings(r[2] for r in rows))
    raw_unit = common.unit or ""
    return PrimaryResult(points=tuple(r[2] for r in rows), sources=tuple(r[1] for r in rows),
                         quadrature=(het, ref or ""), output=o.output, unit=f"{raw_unit or 'output'} per m/s^2",
                         wavelength_nm=float(o.wavelength_nm), warnings=tuple(dict.fromkeys(warnings)),
                         output_unit=raw_unit, demodulations=tuple(r[3] for r in rows))
