"""Error models of a three-axis sensor and the calibration that applies them.

Axis convention of the seed (Z' along Z, Y' in the YOZ plane): the sensor
matrix ``M = K S`` is upper triangular,

    S = [[cos(a)cos(g), sin(g), sin(a)cos(g)],
         [0,            cos(b), sin(b)      ],
         [0,            0,      1           ]],   K = diag(Kx, Ky, Kz)

and the measurement is ``H_hat = M H + B``.  ``alpha`` (a) and ``gamma`` (g)
are the angles of the real X' axis with the planes X'OZ' and X'OY', ``beta``
(b) the angle between Y and Y'.

References
----------
.. [1] "三轴磁敏传感器转向误差建模与辨识" (Steering-error modelling and
   identification of a three-axis magnetic sensor), seed 004 of
   ``METHODS.md`` section 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import FileFormatError, InputError

__all__ = [
    "MODELS", "LINEAR_NAMES", "sensor_matrix", "matrix_to_angles", "linear_features",
    "TriaxialCalibration", "load_calibration", "IMPORT_FORMS", "from_third_party", "parse_plain_parameters",
]

#: Model names, richest first.
MODELS = ("full", "diagonal", "offsets", "planar")

#: Models a calibration can hold besides the fitted ones: ``imported`` is any invertible matrix and offset
#: taken from a third-party tool (:func:`from_third_party`).
EXTERNAL_MODELS = ("linearised", "imported")

#: Plain forms of a third-party calibration: ``affine`` corrects as ``A h + B`` (Dorveaux, the QMC5883L
#: authors' MagnetometerCalibration), ``centred`` as ``A (h - B)`` (Magneto, most hard/soft-iron tools).
IMPORT_FORMS = ("affine", "centred")

#: The seed's 8 weights of the linearised steering-error model.
LINEAR_NAMES = ("dKx", "dKy", "gamma", "alpha", "beta", "Bx", "By", "Bz")

FORMAT = "senscal.triaxial.calibration"  # the version-1 tag (key "format")
TYPE = "senscal.triaxial.TriaxialCalibration"  # the type key of saved files (senscal.persist)
FORMAT_VERSION = 2


def sensor_matrix(kx: float, ky: float, kz: float, alpha: float, beta: float, gamma: float) -> np.ndarray:
    """``M = K S`` of the seed (upper triangular).

    Parameters
    ----------
    kx, ky, kz : float
        Axis gains (sensor unit per field unit).
    alpha, beta, gamma : float
        Non-orthogonality angles in rad (seed convention, see module doc).

    Returns
    -------
    ndarray, shape (3, 3)
    """
    ca, sa, cb, sb, cg, sg = (math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta),
                              math.cos(gamma), math.sin(gamma))
    return np.array([[kx * ca * cg, kx * sg, kx * sa * cg],
                     [0.0, ky * cb, ky * sb],
                     [0.0, 0.0, kz]])


def matrix_to_angles(m: np.ndarray) -> dict[str, float]:
    """Inverse of :func:`sensor_matrix`: gains and angles (rad) of an upper-triangular M."""
    m = np.asarray(m, float)
    kx = float(np.linalg.norm(m[0]))
    ky = float(np.linalg.norm(m[1, 1:]))
    kz = float(m[2, 2])
    return {"Kx": kx, "Ky": ky, "Kz": kz,
            "alpha": math.atan2(m[0, 2], m[0, 0]),
            "beta": math.atan2(m[1, 2], m[1, 1]),
            "gamma": math.asin(max(-1.0, min(1.0, m[0, 1] / kx)))}


def linear_features(h: np.ndarray) -> np.ndarray:
    """Regressors of the seed's linearised magnitude equation.

    Parameters
    ----------
    h : ndarray, shape (3, N)
        Measured field (any unit; the weights of the squared terms are then
        per that unit).

    Returns
    -------
    ndarray, shape (N, 8)
        ``[Hx^2, Hy^2, HxHy, HxHz, HyHz, Hx, Hy, Hz]`` matching ``LINEAR_NAMES``.
    """
    hx, hy, hz = h
    return np.column_stack([hx * hx, hy * hy, hx * hy, hx * hz, hy * hz, hx, hy, hz])


@dataclass(frozen=True)
class TriaxialCalibration(ResultMixin):
    """A three-axis calibration that corrects new data; saves and loads itself.

    Attributes
    ----------
    model : str
        ``full``, ``diagonal``, ``offsets``, ``planar``, ``linearised``, or
        ``imported`` (another tool's matrix and offset, :func:`from_third_party`).
    method : str
        Estimator that produced it (``ml``, ``ellipsoid``, ``linear``, ``lms``).
    matrix : ndarray, shape (3, 3)
        Sensor matrix ``M = K S`` (for ``linearised``: ``I + dS + dK``).
    offsets : ndarray, shape (3,)
        ``B`` in sensor units.
    field : float
        Field magnitude the corrected data should show (field units).
    unit : str
        Sensor unit of the data it applies to ('' if unknown).
    channels : tuple of str
        Channel names it was made from (X, Y, Z order).
    plane_axes : tuple of int or None
        For ``planar``: the two axes corrected; the third is passed through.
    """

    model: str
    method: str
    matrix: np.ndarray
    offsets: np.ndarray
    field: float
    unit: str = ""
    channels: tuple[str, ...] = ("x", "y", "z")
    plane_axes: tuple[int, int] | None = None
    format: str = FORMAT
    format_version: int = FORMAT_VERSION

    def apply(self, h_hat: np.ndarray, *, unit: str | None = None) -> np.ndarray:
        """Correct measurements.

        Parameters
        ----------
        h_hat : array_like, shape (3, N) or (3,)
            Measured field in sensor units.
        unit : str, optional
            Unit of ``h_hat``; converted to :attr:`unit` when it is another
            unit of the same dimension, refused when it is of another
            (see :func:`senscal.persist.units.unit_factor`).

        Returns
        -------
        ndarray, same shape
            Corrected field in field units.  Exact models invert
            ``H_hat = M H + B``; the linearised model applies the seed's
            first-order correction ``H = H_hat - dH_hat``.
        """
        h = np.asarray(h_hat, float)
        if unit is not None:
            h = h * self.unit_factors({c: unit for c in self.channels})[self.channels[0]]
        if h.shape[0] != 3:
            raise InputError(f"calibration needs 3 axes on the first dimension, got shape {h.shape}")
        vec = h.ndim == 1
        h2 = h.reshape(3, -1)
        m = np.asarray(self.matrix, float)
        b = np.asarray(self.offsets, float)[:, None]
        if self.model == "linearised":
            out = h2 - ((m - np.eye(3)) @ h2 + b)
        elif self.model == "planar":
            i, j = self.plane_axes  # type: ignore[misc]
            out = h2.copy()
            idx = [i, j]
            out[idx] = np.linalg.solve(m[np.ix_(idx, idx)], h2[idx] - b[idx])
        else:
            out = np.linalg.solve(m, h2 - b)
        return out[:, 0] if vec else out

    def save(self, path: str | Path, extra: Mapping[str, Any] | None = None) -> Path:
        """Write as JSON, or HDF5 for a ``.h5``/``.hdf5`` path.

        The file is ``{"type", "format_version", **extra, "calibration": {...}}``
        (:mod:`senscal.persist`): ``extra`` adds fields such as the
        calibration report (``triaxial calibrate --out`` stores its ``--json``
        document there); :func:`senscal.load_calibration` and
        :func:`load_calibration` read it back.
        """
        from senscal.persist import document, write_document

        cal = {k: v for k, v in self.to_dict().items() if k not in ("format", "format_version")}
        doc = document(TYPE, {**to_jsonable(dict(extra or {})), "calibration": cal})
        return write_document(doc, path, what="parameter file")

    def unit_factors(self, units: Mapping[str, str], *, source: str = "the recording") -> dict[str, float]:
        """Per channel, the factor that converts its data into the calibration's unit.

        Parameters
        ----------
        units : mapping
            Channel name -> unit of the data to correct (missing or '' = unknown: factor 1).
        source : str
            Names the data in the message.

        Returns
        -------
        dict
            Channel -> factor (``uT`` data, ``nT`` calibration: 1000; ``m/s²`` and ``m/s^2``: 1).

        Raises
        ------
        InputError
            A channel's unit is of another dimension (``V`` against ``m/s^2``), or no unit at all.
        """
        from senscal.persist.units import unit_factor

        return {c: unit_factor(u, self.unit, what=f"channel '{c}' of {source}", fix="convert the data or calibrate again")
                for c, u in units.items()}

    def check_units(self, units: Mapping[str, str], *, source: str = "the recording") -> None:
        """Refuse channels whose unit cannot be converted to the calibration's (see :meth:`unit_factors`)."""
        self.unit_factors(units, source=source)

    @classmethod
    def from_document(cls, doc: Mapping[str, Any], *, source: str = "parameter file") -> "TriaxialCalibration":
        """Rebuild from a saved document: version 2 (``type``, fields under ``calibration``), or a
        version-1 file (``format``; flat, or a report with the calibration inside)."""
        from senscal.persist import check_version

        if isinstance(doc, dict) and doc.get("type") == TYPE:
            check_version(doc, source)
            doc = doc.get("calibration") if isinstance(doc.get("calibration"), dict) else doc
        else:
            if isinstance(doc, dict) and isinstance(doc.get("calibration"), dict):
                doc = doc["calibration"]
            if not isinstance(doc, dict) or doc.get("format") != FORMAT:
                raise FileFormatError(f"{source} is not a senscal triaxial calibration; give the file written by "
                                      "'senscal triaxial calibrate --out'")
            check_version(doc, source)
        try:
            m = np.array(doc["matrix"], float)
            b = np.array(doc["offsets"], float)
            pa = doc.get("plane_axes")
            cal = cls(model=str(doc["model"]), method=str(doc["method"]), matrix=m, offsets=b,
                      field=float(doc["field"]), unit=str(doc.get("unit") or ""),
                      channels=tuple(doc.get("channels", ("x", "y", "z"))),
                      plane_axes=tuple(int(i) for i in pa) if pa is not None else None)
        except (KeyError, TypeError, ValueError) as exc:
            raise FileFormatError(f"{source} is a damaged triaxial calibration (missing or bad {exc}); "
                                  "re-run calibrate") from None
        if m.shape != (3, 3) or b.shape != (3,) or not (np.all(np.isfinite(m)) and np.all(np.isfinite(b))):
            raise FileFormatError(f"{source} holds a malformed matrix or offsets; re-run calibrate")
        if cal.model not in MODELS + EXTERNAL_MODELS or (cal.model == "planar" and (pa is None or len(pa) != 2)):
            raise FileFormatError(f"{source} names an unknown model {cal.model!r}; re-run calibrate")
        return cal


def load_calibration(path: str | Path) -> TriaxialCalibration:
    """Read a calibration written by :meth:`TriaxialCalibration.save` or ``--out`` (JSON or HDF5, any version).

    Same as ``senscal.load_calibration(path)`` but refuses other calibration types.
    """
    from senscal.persist import load_calibration as load

    return load(path, expect=TYPE)


def parse_plain_parameters(text: str, *, source: str = "parameter file") -> tuple[np.ndarray, np.ndarray]:
    """Matrix A and offset B from the plain text of a third-party calibration.

    The documented plain form: 12 numbers, the 3x3 matrix ``A`` row by row,
    then the offset ``B`` (x, y, z), separated by commas, semicolons,
    whitespace or line breaks in any layout (one per line, as the QMC5883L
    authors publish theirs, or four rows of three).  Text after ``#`` is a
    comment.

    Parameters
    ----------
    text : str
    source : str
        Names the file in messages.

    Returns
    -------
    a : ndarray, shape (3, 3)
    b : ndarray, shape (3,)

    Raises
    ------
    FileFormatError
        Not exactly 12 finite numbers.
    """
    lines = [ln.split("#", 1)[0] for ln in text.splitlines()]
    tokens = [t for ln in lines for t in ln.replace(",", " ").replace(";", " ").split()]
    try:
        vals = np.array([float(t) for t in tokens], float)
    except ValueError:
        bad = next(t for t in tokens if not _is_number(t))
        raise FileFormatError(f"{source} holds {bad!r}, not a number; the plain form is 12 numbers: the matrix A "
                              "row by row, then the offset B") from None
    if vals.size != 12 or not np.all(np.isfinite(vals)):
        raise FileFormatError(f"{source} holds {vals.size} numbers; the plain form is 12 finite numbers: the 3x3 "
                              "matrix A row by row, then the offset B (x, y, z)")
    return vals[:9].reshape(3, 3), vals[9:]


def _is_number(t: str) -> bool:
    try:
        float(t)
    except ValueError:
        return False
    return True


def from_third_party(a: np.ndarray, b: np.ndarray, *, form: str = "affine", field: float = 1.0, unit: str = "",
                     channels: tuple[str, ...] = ("x", "y", "z"), source: str = "the parameters") -> TriaxialCalibration:
    """A calibration from another tool's matrix and offset.

    ``affine``: the tool corrects as ``H = A h + B``; ``centred``: as
    ``H = A (h - B)``.  senscal applies ``H = M^-1 (h - b)``, so
    ``M = A^-1`` and ``b = -A^-1 B`` (affine) or ``b = B`` (centred); the
    corrected values are the same numbers the tool gives.

    Parameters
    ----------
    a : array_like, shape (3, 3)
        The tool's matrix (any invertible matrix, not only the seed's upper-triangular one).
    b : array_like, shape (3,)
        The tool's offset, in the unit of its formula (corrected units for
        ``affine``, sensor units for ``centred``).
    form : {"affine", "centred"}
    field : float
        Field magnitude the corrected data should show, in corrected units
        (tools that normalise the field to 1 give 1).
    unit : str
        Sensor unit of the readings it applies to ('' if unknown).
    channels : tuple of str

    Returns
    -------
    TriaxialCalibration
        ``model="imported"``, ``method="<form>"``; no uncertainties (the tool gives none).

    Raises
    ------
    InputError
        Unknown form, wrong shapes, a singular matrix or a non-positive field.
    """
    a = np.asarray(a, float)
    b = np.asarray(b, float).ravel()
    if form not in IMPORT_FORMS:
        raise InputError(f"unknown form {form!r}; use affine (A h + B) or centred (A (h - B))")
    if a.shape != (3, 3) or b.shape != (3,) or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InputError(f"{source}: need a finite 3x3 matrix A and a 3-vector B, got shapes {a.shape} and {b.shape}")
    if not (math.isfinite(field) and field > 0):
        raise InputError(f"the field magnitude must be a positive number, got {field!r}")
    # A matrix this close to singular would amplify the readings' last digits into the correction.
    if np.linalg.cond(a) > 1e12:
        raise InputError(f"{source}: the matrix A is singular (condition {np.linalg.cond(a):.3g}); check that its 9 "
                         "numbers are the matrix row by row")
    m = np.linalg.inv(a)
    off = -m @ b if form == "affine" else b.copy()
    return TriaxialCalibration(model="imported", method=form, matrix=m, offsets=off, field=float(field), unit=unit,
                               channels=tuple(channels))
