"""Triaxial jobs: calibration without a reference (``triaxial-calibrate``) and correction (``triaxial-apply``).

``triaxial_calibrate`` identifies non-orthogonality, gains and offsets of a
three-axis magnetometer (or accelerometer) from readings in a constant field;
``triaxial_apply`` corrects a recording with a saved calibration.  Writing
the parameter file and the corrected recording stays with the caller (the
CLI): the results carry what to write.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from senscal._result import to_jsonable
from senscal.errors import InputError
from senscal.jobs._base import JobResult, Quantity, ReadOptions, given_or_loaded, source_name

if TYPE_CHECKING:  # the engines load when a job runs, not when the CLI starts
    from senscal.io import Recording
    from senscal.triaxial import TriaxialCalibration, TriaxialResult
    from senscal.triaxial.static import StaticIntervals

__all__ = ["TriaxialCalibrateOptions", "TriaxialCalibrateResult", "triaxial_calibrate", "TriaxialApplyOptions",
           "TriaxialApplyResult", "triaxial_apply", "parameter_table", "TriaxialImportOptions", "TriaxialImportResult",
           "triaxial_import"]

ANGLES = ("alpha", "beta", "gamma")


def _three(names: Any, what: str) -> tuple[str, str, str]:
    """Three channel names from ``"x,y,z"`` or a sequence."""
    if isinstance(names, str):
        text = names
        names = [s.strip() for s in names.split(",") if s.strip()]
    else:
        text = ",".join(map(str, names))
    if len(names) != 3:
        raise InputError(f"{what} needs exactly three names X,Y,Z, got {text!r}")
    return tuple(str(n) for n in names)  # type: ignore[return-value]


def parameter_table(params: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Parameters in the seed's terms for JSON: angles in degrees, U = 2u (k=2)."""
    out = {}
    for n, p in params.items():
        v, u = p["value"], p["u"]
        key, unit = n, p["unit"]
        if n in ANGLES:
            key, unit = f"{n}_deg", "deg"
            v = None if v is None else math.degrees(v)
            u = None if u is None else math.degrees(u)
        out[key] = {"value": v, "u": u, "U_k2": None if u is None else 2 * u, "unit": unit}
    return out


def _finite(x: Any) -> bool:
    return x is not None and math.isfinite(float(x))


# ---------------------------------------------------------------------------
# triaxial-calibrate
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class TriaxialCalibrateOptions(ReadOptions):
    """Options of :func:`triaxial_calibrate` (the ``senscal triaxial calibrate`` options).

    Attributes
    ----------
    channels : str or tuple of 3 str
        The X, Y, Z field channels (``"x,y,z"`` or a tuple).
    field : float, str or None
        Field magnitude in the channels' unit (50000 for nT data), or a
        quantity converted to it (``"50 uT"``, ``"1 g"``); None: estimated
        (scale then arbitrary).
    method : str
        ``auto``, ``ml``, ``ellipsoid``, ``linear`` or ``lms``.
    model : str or None
        Force ``full``, ``diagonal``, ``offsets`` or ``planar`` (None: the
        richest the data support).
    lr : float
        LMS learning rate (on field-scaled features).
    epochs : int
        LMS passes over the data.
    strict : bool
        Insufficient coverage or implausible parameters raise (the engine's strict mode).
    static : bool
        Accelerometer session: detect static poses and fit their means.
    static_window : float
        Moving-variance window of ``static``, s.
    min_pose : float
        Shortest static pose kept, s.
    outlier_sigma : float
        Exclude readings this many robust sigma off (0: keep all).
    accel_channels : str, tuple of 3 str or None
        An accelerometer recorded alongside: calibrated too, and the
        tilt-compensated heading is compared before/after.
    time_column, fs, names, time_unit, skip_rows
        How the recording is read (:class:`~senscal.jobs._base.ReadOptions`).
    """

    channels: str | tuple[str, str, str] = ("x", "y", "z")
    field: float | str | None = None
    method: str = "auto"
    model: str | None = None
    lr: float = 0.01
    epochs: int = 50
    strict: bool = False
    static: bool = False
    static_window: float = 0.5
    min_pose: float = 1.0
    outlier_sigma: float = 5.0
    accel_channels: str | tuple[str, str, str] | None = None


@dataclass(frozen=True)
class TriaxialCalibrateResult(JobResult):
    """Calibration of a three-axis sensor, with the readings it came from.

    Attributes
    ----------
    calibration : senscal.triaxial.TriaxialResult
        Parameters with standard uncertainties (angles rad, gains 1, offsets
        in the channels' unit), diagnostics and the applicable
        :class:`~senscal.triaxial.TriaxialCalibration` (``.calibration``).
    source : str
        The recording.
    channels : tuple of 3 str
    unit : str
        Unit of the field channels ('' if unknown).
    readings : ndarray, shape (3, N)
        What was fitted: the readings, or the static pose means.
    static : senscal.triaxial.static.StaticIntervals or None
        The detected poses (``static``).
    accelerometer : senscal.triaxial.TriaxialResult or None
        Calibration of ``accel_channels``.
    accel_channels : tuple of 3 str or None
    tilt : dict or None
        Tilt-compensated heading before/after (:func:`senscal.triaxial.heading.tilt_heading_report`), deg.
    warnings : tuple of str
        The calibration's named warnings, then the accelerometer's (a bad
        tilt spoils the heading).
    """

    job: ClassVar[str] = "triaxial-calibrate"

    calibration: TriaxialResult
    source: str
    channels: tuple[str, str, str]
    unit: str
    readings: np.ndarray = field(repr=False)
    static: StaticIntervals | None = None
    accelerometer: TriaxialResult | None = None
    accel_channels: tuple[str, str, str] | None = None
    tilt: dict[str, Any] | None = None
    warnings: tuple[str, ...] = ()

    @property
    def method(self) -> str:
        """How the registry describes the method: ``<model> model, <method>``."""
        return f"{self.calibration.model} model, {self.calibration.method}"

    @property
    def conditions(self) -> dict[str, Any]:
        """The calibration conditions the registry keeps: field, whether estimated, coverage fraction."""
        res = self.calibration
        return {"field": res.field, "field_estimated": res.field_estimated, "coverage": res.coverage["fraction"]}

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal triaxial calibrate --json`` document (also the ``--out`` parameter file)."""
        from senscal.triaxial.heading import summary as heading_summary

        res = self.calibration
        doc = {
            "file": self.source, "channels": list(self.channels), "model": res.model, "method": res.method,
            "field": {"value": res.field,
                      "u": res.parameters.get("field", res.parameters.get("plane_field", {})).get("u"),
                      "estimated": res.field_estimated, "note": res.scale_note},
            "parameters": parameter_table(res.parameters),
            "unidentifiable": list(res.unidentifiable), "model_choice": list(res.model_choice),
            "coverage": res.coverage, "planarity": res.planarity, "conditioning": res.conditioning,
            "noise": res.noise, "norm_error_before": res.norm_error_before, "norm_error_after": res.norm_error_after,
            "outliers": {"count": len(res.outliers), "indices": list(res.outliers)},
            "saturated": {"count": len(res.saturated)}, "plausibility": list(res.plausibility),
            "plausibility_supported": list(res.plausibility_supported), "time_terms": res.time_terms,
            "warnings": list(res.warnings), "lms_vs_least_squares": res.lms_vs_least_squares,
            "n_samples": res.n_samples, "n_used": res.n_used,
            "model_evidence": list(res.model_evidence),
            "heading": heading_summary(res.heading) if res.heading is not None else None,
            "calibration": res.calibration.to_dict(),
        }
        st = self.static
        if st is not None:
            doc["static"] = {"n_poses": st.n_poses, "starts": st.starts.tolist(), "stops": st.stops.tolist(),
                             "samples_per_pose_min": int(st.counts.min()) if st.n_poses else 0,
                             "threshold": st.threshold}
        if self.tilt is not None:
            ra = self.accelerometer
            doc["tilt_heading"] = {**heading_summary(self.tilt), "accelerometer": {
                "channels": list(self.accel_channels), "model": ra.model, "method": ra.method,
                "norm_error_after": ra.norm_error_after, "warnings": list(ra.warnings),
                "calibration": ra.calibration.to_dict()}}
        return to_jsonable(doc)

    def quantities(self) -> tuple[Quantity, ...]:
        """Every parameter the data determined (unidentifiable ones are left out), angles in deg."""
        return tuple(Quantity(name, float(p["value"]), float(p["u"]), p["unit"])
                     for name, p in parameter_table(self.calibration.parameters).items()
                     if _finite(p["value"]) and _finite(p["u"]))

    def to_dataframe(self):
        """One row per parameter: value, standard u (k=1), U (k=2), unit (angles in deg; NaN where unidentifiable)."""
        import pandas as pd

        rows = [{"parameter": n, "value": np.nan if p["value"] is None else float(p["value"]),
                 "u": np.nan if p["u"] is None else float(p["u"]),
                 "U": np.nan if p["U_k2"] is None else float(p["U_k2"]), "unit": p["unit"]}
                for n, p in parameter_table(self.calibration.parameters).items()]
        return pd.DataFrame(rows, columns=["parameter", "value", "u", "U", "unit"])

    def corrected(self) -> np.ndarray:
        """The readings corrected with the calibration, shape (3, N), channels' unit."""
        return self.calibration.calibration.apply(self.readings)


def _one_unit(rec, chans, source) -> tuple[np.ndarray, str]:
    """The three axes in one unit (the first axis that names one): ``x [uT], y [nT]`` would fit a wrong ellipsoid."""
    from senscal.units import factor

    units = [rec.units.get(c, "") for c in chans]
    unit = next((u for u in units if u.strip()), "")
    data = rec.data(list(chans))
    if not unit:
        return data, unit
    scale = [factor(u or unit, unit, what=f"channel '{c}' of {source_name(source)}",
                    fix="give the three axes of one sensor in one kind of unit") for c, u in zip(chans, units)]
    return data * np.asarray(scale)[:, None], unit


def _field_in(field: float | str | None, unit: str, chans, source) -> float | None:
    """``--field`` in the readings' unit: a bare number is in it; ``'50 uT'`` is converted to it.

    A field with a unit is refused when the readings' header gives none or one of another dimension
    (counts, V): the calibration scales the readings to the field, so the two must be in one unit.
    """
    if field is None:
        return None
    try:
        return float(field)
    except (TypeError, ValueError):
        pass
    from senscal.units import parse_quantity

    if unit:
        return parse_quantity(field, unit, option="--field")  # '50 uT' -> 50000 for nT readings; V refused
    from senscal.units import _QTY

    m = _QTY.match(str(field))
    if m is None or not m.group(2):
        parse_quantity(field, "1", option="--field")  # not a number: the grammar's one-line refusal
    raise InputError(f"--field {field} has a unit but the header of {source_name(source)} gives none for "
                     f"{','.join(chans)}; give the unit in the header (e.g. 'x [uT]') or --field as a bare number in "
                     "the readings' unit")


def triaxial_calibrate(source, options: TriaxialCalibrateOptions = TriaxialCalibrateOptions()
                       ) -> TriaxialCalibrateResult:
    """Calibrate a three-axis magnetometer or accelerometer from readings in a constant field.

    Parameters
    ----------
    source : str, Path or Recording
        Readings of the three field channels (and ``accel_channels``).
    options : TriaxialCalibrateOptions

    Returns
    -------
    TriaxialCalibrateResult

    Raises
    ------
    SenscalError
        Unreadable recording, unknown channel, too few readings or poses,
        degenerate coverage (with ``strict``) ... (one line, with the fix).
    """
    from senscal.triaxial import calibrate, detect_static

    o = options
    chans = _three(o.channels, "--channels")
    extra = _three(o.accel_channels, "--accel-channels") if o.accel_channels is not None else None
    outlier = None if o.outlier_sigma == 0 else o.outlier_sigma
    # Only static poses use time: a headerless x,y,z file needs no sample rate otherwise.
    rec = o.read(source, channels=list(chans) + list(extra or ()), time_required=o.static, job="triaxial")
    h, unit = _one_unit(rec, chans, source)
    field = _field_in(o.field, unit, chans, source)
    st = None
    if o.static:
        st = detect_static(h, rec.sample_rate, window_s=o.static_window, min_duration_s=o.min_pose)
        if st.n_poses < 5:
            raise InputError(f"found {st.n_poses} static poses in {source_name(source)}; a calibration needs many "
                             "(>= 9 for the full model): hold the sensor still longer in more orientations or adjust "
                             "--static-window")
        h = st.means
    res = calibrate(h, field=field, method=o.method, model=o.model, lr=o.lr, epochs=o.epochs, strict=o.strict,
                    outlier_sigma=outlier, unit=unit, channels=chans)
    ra = tilt = None
    if extra is not None:
        from senscal.triaxial.heading import tilt_heading_report

        if o.static:
            raise InputError("--accel-channels needs the readings themselves, not --static pose means; drop --static")
        if set(extra) & set(chans):
            raise InputError("--accel-channels must name the accelerometer's channels, not the calibrated ones")
        a, a_unit = _one_unit(rec, extra, source)
        ra = calibrate(a, outlier_sigma=outlier, unit=a_unit, channels=extra)
        tilt = tilt_heading_report(h, res.calibration.apply(h), a, ra.calibration.apply(a))
    warnings = tuple(res.warnings) + (tuple(ra.warnings) if ra is not None else ())
    if o.static:  # only static poses use time: their windows are in seconds
        from senscal.io.plausibility import merge_time_warnings

        warnings = merge_time_warnings(warnings, rec.warnings)
    return TriaxialCalibrateResult(calibration=res, source=source_name(source), channels=chans, unit=unit,
                                   readings=np.asarray(h, dtype=float), static=st, accelerometer=ra,
                                   accel_channels=extra, tilt=tilt, warnings=warnings)


# ---------------------------------------------------------------------------
# triaxial-apply
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class TriaxialApplyOptions(ReadOptions):
    """Options of :func:`triaxial_apply` (the ``senscal triaxial apply`` options).

    Attributes
    ----------
    params : str, Path or senscal.triaxial.TriaxialCalibration
        The parameter file of ``triaxial calibrate --out`` (or a calibration in memory).
    channels : str or tuple of 3 str
        The X, Y, Z channels to correct.
    time_column, fs, names, time_unit, skip_rows
        How the recording is read (:class:`~senscal.jobs._base.ReadOptions`).
    """

    params: str | Path | TriaxialCalibration | None = None
    channels: str | tuple[str, str, str] = ("x", "y", "z")


@dataclass(frozen=True)
class TriaxialApplyResult(JobResult):
    """A recording with three channels corrected; the other channels are copied.

    Attributes
    ----------
    calibration : senscal.triaxial.TriaxialCalibration
    recording : senscal.io.Recording
        The corrected recording (what ``--out`` writes).
    source : str
    params_source : str
        The parameter file (or ``"<calibration>"``).
    channels : tuple of 3 str
    corrected_norm : ndarray, shape (N,)
        ``|H|`` after correction, channels' unit.
    warnings : tuple of str
    """

    job: ClassVar[str] = "triaxial-apply"

    calibration: TriaxialCalibration
    recording: Recording = field(repr=False)
    source: str
    params_source: str
    channels: tuple[str, str, str]
    corrected_norm: np.ndarray = field(repr=False)
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal triaxial apply --json`` document (``out``, the written file, is set by the writer)."""
        cal, norm = self.calibration, self.corrected_norm
        return to_jsonable({"file": self.source, "out": None, "model": cal.model,
                "method": cal.method, "n_samples": int(norm.size), "corrected_norm_mean": float(norm.mean()),
                "corrected_norm_std": float(norm.std(ddof=1)) if norm.size > 1 else 0.0, "field": cal.field})

    def to_dataframe(self):
        """The corrected recording, one row per sample: t (s) and every channel."""
        import pandas as pd

        rec = self.recording
        return pd.DataFrame({"t": rec.time, **{k: np.asarray(v) for k, v in rec.channels.items()}})


def _calibration_of(params) -> tuple[Any, str]:
    from senscal.triaxial import TriaxialCalibration, load_calibration

    if params is None:
        raise InputError("triaxial apply needs the calibration: give --params PARAMS.json from "
                         "'senscal triaxial calibrate --out PARAMS.json'")
    return given_or_loaded(params, TriaxialCalibration, load_calibration, label="<calibration>",
                           what="the calibration",
                           path="parameter file")


# The geomagnetic total intensity at the Earth's surface spans about 22 to 67 uT (IGRF), a factor of 3.05, and
# gravity varies by 0.5 %: no change of place explains a corrected field further than this factor from the one
# the calibration was made in.  Beyond it the data are in another unit, from another sensor, or the wrong file.
_FIELD_FACTOR = 67.0 / 22.0


def _field_mismatch(norm: np.ndarray, field: float) -> str:
    """Describe a corrected field whose median magnitude is implausibly far from the calibration's.

    Parameters
    ----------
    norm : ndarray
        Corrected field magnitude per sample (field units).
    field : float
        Field magnitude of the calibration session (field units).

    Returns
    -------
    str
        Empty when the median magnitude lies within a factor ``_FIELD_FACTOR`` of ``field``.
    """
    if norm.size == 0 or not (np.isfinite(field) and field > 0):
        return ""
    med = float(np.median(norm))
    if field / _FIELD_FACTOR <= med <= field * _FIELD_FACTOR:
        return ""
    return (f"the corrected field's median magnitude is {med:.5g}, {med / field:.3g} times the calibration's "
            f"{field:.5g}; no change of place explains a factor beyond {_FIELD_FACTOR:.2f}: check the data's unit, "
            "the channels and that the calibration is this sensor's")


def triaxial_apply(source, options: TriaxialApplyOptions = TriaxialApplyOptions()) -> TriaxialApplyResult:
    """Correct three field channels of a recording with a saved calibration.

    Parameters
    ----------
    source : str, Path or Recording
        The recording to correct (never modified).
    options : TriaxialApplyOptions
        ``params`` is required.

    Returns
    -------
    TriaxialApplyResult

    Raises
    ------
    SenscalError
        Unreadable parameter file or recording, unknown channel, channels in
        a unit of another dimension than the calibration's (one line, with the fix).  Channels in another
        unit of its dimension (uT data, nT calibration) are converted; a unit stated on one side only is
        named ``triaxial-units-assumed``.
    """
    from senscal.io import Recording

    o = options
    cal, params_source = _calibration_of(o.params)
    chans = _three(o.channels, "--channels")
    rec = o.read(source)
    rec.data(list(chans))  # unknown channel -> one-line error listing the channels
    # Channels in another unit of the calibration's dimension (uT data, nT calibration) are converted to it;
    # another dimension is refused; a channel of unknown unit passes.
    scales = cal.unit_factors({c: rec.units.get(c, "") for c in chans}, source=source_name(source))
    # A unit on one side only is read as the other side's: named, since uT data read as nT is a factor of 1000.
    from senscal.diagnostics import named
    from senscal.jobs._units import one_side_unit

    warnings = []
    assumed = one_side_unit(chans, rec.units, cal.unit)
    if assumed:
        warnings.append(named("triaxial-units-assumed", f"{source_name(source)}: {assumed}; write the units in the "
                              "header ('x [nT]', 'x [m/s^2]'), or calibrate from a file that states them"))
    corr = cal.apply(rec.data(list(chans)) * np.array([scales[c] for c in chans])[:, None])
    with np.errstate(over="ignore", invalid="ignore"):
        norm = np.linalg.norm(corr, axis=0)
    bad = ~(np.isfinite(corr).all(axis=0) & np.isfinite(norm))
    if bad.any():
        # Readings near the float limit (1e308) overflow in the correction or its norm: a damaged file, not a field.
        from senscal.errors import DataError

        i = int(np.flatnonzero(bad)[0])
        raise DataError(f"{source_name(source)}: the corrected field overflows in data row {i + 1} (readings up to "
                        f"{float(np.max(np.abs(rec.data(list(chans))))):.3g}); check the file and --channels")
    mismatch = _field_mismatch(norm, cal.field)
    if mismatch:
        warnings.append(named("triaxial-field-mismatch", f"{source_name(source)}: {mismatch}"))
    new = dict(rec.channels)
    units = dict(rec.units)
    for k, c in enumerate(chans):
        # Corrected readings are in the calibration's unit; unknown there, in the data's (the assumption named).
        new[c], units[c] = corr[k], (cal.unit or "").strip() or rec.units.get(c, "")
    out = Recording(channels=new, t=rec.t, fs=rec.fs, t0=rec.t0, units=units,
                    metadata={**rec.metadata, "triaxial_calibration": f"{cal.model}/{cal.method} from {params_source}"})
    return TriaxialApplyResult(calibration=cal, recording=out, source=source_name(source),
                               params_source=params_source, channels=chans,
                               corrected_norm=norm, warnings=tuple(warnings))



# ---------------------------------------------------------------------------
# triaxial-import
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class TriaxialImportOptions:
    """Options of :func:`triaxial_import` (the ``senscal triaxial import`` options).

    Attributes
    ----------
    form : str
        ``affine`` (the tool corrects as ``A h + B``) or ``centred`` (``A (h - B)``).
    field : float
        Field magnitude the corrected data should show, in corrected units (1 for tools that normalise it).
    unit : str
        Sensor unit of the readings the calibration applies to ('' if unknown).
    channels : str or tuple of 3 str
        The X, Y, Z channel names the calibration is for.
    """

    form: str = "affine"
    field: float = 1.0
    unit: str = ""
    channels: str | tuple[str, str, str] = ("x", "y", "z")


@dataclass(frozen=True)
class TriaxialImportResult(JobResult):
    """A third-party calibration in senscal's form (what ``--out`` saves and ``triaxial apply`` reads).

    Attributes
    ----------
    calibration : senscal.triaxial.TriaxialCalibration
        ``model="imported"``; no uncertainties (the plain form carries none).
    source : str
        The plain parameter file.
    a, b : ndarray
        The matrix and offset as read.
    form : str
    warnings : tuple of str
    """

    job: ClassVar[str] = "triaxial-import"

    calibration: TriaxialCalibration
    source: str
    a: np.ndarray = field(repr=False)
    b: np.ndarray = field(repr=False)
    form: str = "affine"
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``senscal triaxial import --json`` document (also stored beside the calibration by ``--out``)."""
        return to_jsonable({"file": self.source, "form": self.form, "A": self.a, "B": self.b,
                            "calibration": self.calibration.to_dict()})


def triaxial_import(source, options: TriaxialImportOptions = TriaxialImportOptions()) -> TriaxialImportResult:
    """Read a third-party calibration in the documented plain form.

    Parameters
    ----------
    source : str or Path
        Text file of 12 numbers: the matrix A row by row, then the offset B
        (any separators; ``#`` starts a comment; ``-`` reads standard input).
    options : TriaxialImportOptions

    Returns
    -------
    TriaxialImportResult

    Raises
    ------
    SenscalError
        Missing or unreadable file, not 12 numbers, a singular matrix (one line, with the fix).
    """
    from senscal.io.sidefiles import read_text
    from senscal.triaxial.models import from_third_party, parse_plain_parameters

    o = options
    chans = _three(o.channels, "--channels")
    name = source_name(source)
    a, b = parse_plain_parameters(read_text(source, "parameter file"), source=f"parameter file {name}")
    cal = from_third_party(a, b, form=o.form, field=o.field, unit=o.unit, channels=chans,
                           source=f"parameter file {name}")
    return TriaxialImportResult(calibration=cal, source=name, a=a, b=b, form=o.form)
