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

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import FileFormatError, InputError

__all__ = [
    "MODELS", "LINEAR_NAMES", "sensor_matrix", "matrix_to_angles", "linear_features",
    "TriaxialCalibration", "load_calibration",
]

#: Model names, richest first.
MODELS = ("full", "diagonal", "offsets", "planar")

#: The seed's 8 weights of the linearised steering-error model.
LINEAR_NAMES = ("dKx", "dKy", "gamma", "alpha", "beta", "Bx", "By", "Bz")

FORMAT = "senscal.triaxial.calibration"
FORMAT_VERSION = 1


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
        ``full``, ``diagonal``, ``offsets``, ``planar`` or ``linearised``.
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

    def apply(self, h_hat: np.ndarray) -> np.ndarray:
        """Correct measurements.

        Parameters
        ----------
        h_hat : array_like, shape (3, N) or (3,)
            Measured field in sensor units.

        Returns
        -------
        ndarray, same shape
            Corrected field in field units.  Exact models invert
            ``H_hat = M H + B``; the linearised model applies the seed's
            first-order correction ``H = H_hat - dH_hat``.
        """
        h = np.asarray(h_hat, float)
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
        """Write as JSON (``extra`` adds fields such as the parameter report)."""
        from senscal.io.guard import check_output, write_text

        path = check_output(path, what="parameter file")
        doc = self.to_dict()
        if extra:
            doc = {**to_jsonable(dict(extra)), **doc}
        write_text(path, json.dumps(doc, indent=2) + "\n", what="parameter file")
        return path


def load_calibration(path: str | Path) -> TriaxialCalibration:
    """Read a calibration written by :meth:`TriaxialCalibration.save` or ``--out``."""
    from senscal.io.guard import note_input

    path = Path(path)
    note_input(path)
    if not path.exists():
        raise FileFormatError(f"parameter file not found: {path}")
    from senscal.io.sidefiles import read_json

    doc = read_json(path, "parameter file", expect=None)  # the format check below names a wrong type
    if isinstance(doc, dict) and "calibration" in doc and isinstance(doc["calibration"], dict):
        doc = doc["calibration"]
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise FileFormatError(f"{path} is not a senscal triaxial calibration; give the file written by "
                              "'senscal triaxial calibrate --out'")
    if int(doc.get("format_version", 0)) > FORMAT_VERSION:
        raise FileFormatError(f"{path} has format version {doc['format_version']}, newer than this senscal "
                              f"understands ({FORMAT_VERSION}); upgrade senscal")
    try:
        m = np.array(doc["matrix"], float)
        b = np.array(doc["offsets"], float)
        pa = doc.get("plane_axes")
        cal = TriaxialCalibration(model=str(doc["model"]), method=str(doc["method"]), matrix=m, offsets=b,
                                  field=float(doc["field"]), unit=str(doc.get("unit", "")),
                                  channels=tuple(doc.get("channels", ("x", "y", "z"))),
                                  plane_axes=tuple(pa) if pa is not None else None)
    except (KeyError, TypeError, ValueError) as exc:
        raise FileFormatError(f"{path} is a damaged triaxial calibration (missing or bad {exc}); re-run calibrate") from None
    if m.shape != (3, 3) or b.shape != (3,) or not (np.all(np.isfinite(m)) and np.all(np.isfinite(b))):
        raise FileFormatError(f"{path} holds a malformed matrix or offsets; re-run calibrate")
    return cal
