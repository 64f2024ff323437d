"""The saved IMU calibration: corrects new accelerometer and gyroscope data.

Written by ``senscal imu calibrate --out FILE`` (JSON, or HDF5 for ``.h5``) in senscal's one format
(``type`` = ``senscal.imu.ImuCalibration``, ``format_version``); read by :func:`senscal.load_calibration`
and :func:`load_calibration`.  The model it inverts, per sample:

    a = (1 + S(dT)) (Ma f + Ba) + C(dT)                 accelerometer reading
    g = (1 + Q(dT)) Mg w + Bg + P(dT) + G f            gyroscope reading

``f`` specific force (m/s^2), ``w`` rate (rad/s) in the accelerometer's frame, ``dT = T - T_ref``,
``S``, ``C``, ``P``, ``Q`` polynomials without constant term (absent without a temperature channel), ``G`` the
gyro's g-sensitivity (absent unless fitted).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import FileFormatError, InputError

__all__ = ["ImuCalibration", "load_calibration", "TYPE"]

TYPE = "senscal.imu.ImuCalibration"


def _poly(coef: np.ndarray, dtemp: np.ndarray) -> np.ndarray:
    """``sum_j coef[j] dT^(j+1)`` per axis, shape (3, N)."""
    out = np.zeros((3, dtemp.size))
    for j in range(coef.shape[0]):
        out += coef[j][:, None] * dtemp[None, :] ** (j + 1)
    return out


@dataclass(frozen=True)
class ImuCalibration(ResultMixin):
    """An IMU's accelerometer and gyroscope calibration (what ``--out`` saves).

    Attributes
    ----------
    accel_matrix : ndarray, shape (3, 3)
        ``Ma``: accelerometer reading per m/s^2 (gains and non-orthogonality).
    accel_bias : ndarray, shape (3,)
        ``Ba``: accelerometer reading at zero specific force (at ``temp_reference``).
    gyro_matrix : ndarray, shape (3, 3)
        ``Mg``: gyro reading per rad/s about the accelerometer frame's axes.
    gyro_bias : ndarray, shape (3,)
        ``Bg``: gyro reading at zero rate (at ``temp_reference``; at zero specific force with ``g_sensitivity``).
    gravity : float
        Local g of the calibration, m/s^2.
    accel_unit, gyro_unit : str
        Units of the readings it applies to (the gyro's ``rad/s`` when the readings were an angular rate).
    accel_channels, gyro_channels : tuple of 3 str
    g_sensitivity : ndarray (3, 3) or None
        ``G``: gyro reading per m/s^2.
    temp_reference : float or None
        Temperature at which biases and scales hold; None: no temperature terms.
    temp_unit, temp_channel : str
    accel_bias_tc, accel_scale_tc, gyro_bias_tc : ndarray, shape (d, 3)
        Polynomial coefficients of ``C``, ``S``, ``P`` (row ``j`` multiplies ``dT^(j+1)``).
    gyro_scale_tc : ndarray, shape (d, 3)
        Coefficients of ``Q``: the gyro's relative scale change per gyro axis (row ``j`` multiplies ``dT^(j+1)``).
    parameters : dict
        The reported numbers with their u (informational: ``apply`` does not use them).
    """

    accel_matrix: np.ndarray
    accel_bias: np.ndarray
    gyro_matrix: np.ndarray
    gyro_bias: np.ndarray
    gravity: float = 9.80665
    accel_unit: str = ""
    gyro_unit: str = ""
    accel_channels: tuple[str, ...] = ("ax", "ay", "az")
    gyro_channels: tuple[str, ...] = ("gx", "gy", "gz")
    g_sensitivity: np.ndarray | None = None
    temp_reference: float | None = None
    temp_unit: str = ""
    temp_channel: str | None = None
    accel_bias_tc: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    accel_scale_tc: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gyro_bias_tc: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    parameters: dict = field(default_factory=dict)
    gyro_scale_tc: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def has_temperature(self) -> bool:
        return self.temp_reference is not None and (self.accel_bias_tc.size + self.gyro_bias_tc.size
                                                    + self.gyro_scale_tc.size) > 0

    def _dtemp(self, temperature, n: int) -> np.ndarray:
        if self.temp_reference is None or temperature is None:
            return np.zeros(n)
        tt = np.broadcast_to(np.asarray(temperature, float), (n,))
        return tt - self.temp_reference

    def apply_accel(self, accel: np.ndarray, temperature: np.ndarray | float | None = None) -> np.ndarray:
        """Specific force in m/s^2 (accelerometer frame) from readings.

        Parameters
        ----------
        accel : array_like, shape (3, N) or (3,)
            Accelerometer readings in :attr:`accel_unit`.
        temperature : array_like (N,) or float, optional
            The IMU's temperature (:attr:`temp_unit`); None: at the reference temperature.
        """
        a = np.asarray(accel, float)
        vec = a.ndim == 1
        a2 = a.reshape(3, -1)
        dt = self._dtemp(temperature, a2.shape[1])
        a2 = (a2 - _poly(self.accel_bias_tc, dt)) / (1.0 + _poly(self.accel_scale_tc, dt))
        f = np.linalg.solve(self.accel_matrix, a2 - self.accel_bias[:, None])
        return f[:, 0] if vec else f

    def apply(self, accel: np.ndarray, gyro: np.ndarray, temperature: np.ndarray | float | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """Correct both triads.

        Parameters
        ----------
        accel, gyro : array_like, shape (3, N)
            Readings in :attr:`accel_unit` and :attr:`gyro_unit`, sample for sample.
        temperature : array_like (N,) or float, optional
            The IMU's temperature; None: at the reference temperature.

        Returns
        -------
        (f, w)
            Specific force (m/s^2) and rate (rad/s), both in the accelerometer's frame, shape (3, N).
        """
        a = np.asarray(accel, float).reshape(3, -1)
        g = np.asarray(gyro, float).reshape(3, -1)
        if a.shape != g.shape:
            raise InputError(f"accelerometer and gyroscope need the same samples, got shapes {a.shape} and {g.shape}")
        f = self.apply_accel(a, temperature)
        dt = self._dtemp(temperature, g.shape[1])
        g = g - self.gyro_bias[:, None] - _poly(self.gyro_bias_tc, dt)
        if self.g_sensitivity is not None:
            g = g - self.g_sensitivity @ f
        if self.gyro_scale_tc.size:
            g = g / (1.0 + _poly(self.gyro_scale_tc, dt))
        return f, np.linalg.solve(self.gyro_matrix, g)

    def save(self, path: str | Path, extra: Mapping[str, Any] | None = None) -> Path:
        """Write as JSON, or HDF5 for ``.h5``: ``{"type", "format_version", **extra, "calibration": {...}}``."""
        from senscal.persist import document, write_document

        doc = document(TYPE, {**to_jsonable(dict(extra or {})), "calibration": self.to_dict()})
        return write_document(doc, path, what="calibration file")

    @classmethod
    def from_document(cls, doc: Mapping[str, Any], *, source: str = "calibration file") -> "ImuCalibration":
        """Rebuild from a saved document (checked: shapes, finite numbers)."""
        from senscal.persist import check_version

        if not isinstance(doc, Mapping) or doc.get("type") != TYPE or not isinstance(doc.get("calibration"), Mapping):
            raise FileFormatError(f"{source} is not a senscal IMU calibration; give the file written by "
                                  "'senscal imu calibrate --out FILE'")
        check_version(doc, source)
        d = doc["calibration"]

        def arr(key, shape):
            v = np.array(d[key], float)
            if v.shape != shape:
                raise FileFormatError(f"{source}: '{key}' has shape {v.shape}, expected {shape}; save the "
                                      "calibration again")
            return v

        def tc(key):
            v = np.array(d.get(key) or [], float).reshape(-1, 3)
            return v

        gs = d.get("g_sensitivity")
        tr = d.get("temp_reference")
        return cls(accel_matrix=arr("accel_matrix", (3, 3)), accel_bias=arr("accel_bias", (3,)),
                   gyro_matrix=arr("gyro_matrix", (3, 3)), gyro_bias=arr("gyro_bias", (3,)),
                   gravity=float(d.get("gravity", 9.80665)), accel_unit=str(d.get("accel_unit") or ""),
                   gyro_unit=str(d.get("gyro_unit") or ""),
                   accel_channels=tuple(d.get("accel_channels", ("ax", "ay", "az"))),
                   gyro_channels=tuple(d.get("gyro_channels", ("gx", "gy", "gz"))),
                   g_sensitivity=None if gs is None else arr("g_sensitivity", (3, 3)),
                   temp_reference=None if tr is None else float(tr), temp_unit=str(d.get("temp_unit") or ""),
                   temp_channel=d.get("temp_channel"), accel_bias_tc=tc("accel_bias_tc"),
                   accel_scale_tc=tc("accel_scale_tc"), gyro_bias_tc=tc("gyro_bias_tc"),
                   gyro_scale_tc=tc("gyro_scale_tc"),
                   parameters=dict(d.get("parameters") or {}))


def load_calibration(path: str | Path) -> ImuCalibration:
    """Read a file written by ``senscal imu calibrate --out`` (refuses other calibration types)."""
    from senscal.persist import load_calibration as load

    return load(path, expect=TYPE)
