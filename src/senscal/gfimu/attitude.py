"""Attitude from the array's angular velocity, and how its error grows.

References
----------
.. [1] Wang et al., China Measurement & Test 2017(5) (seed 001), section 1.3:
   the angular velocity feeds the attitude update; attitude plus specific
   force give position.  METHODS.md 2e.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from senscal._result import ResultMixin
from senscal.errors import InputError
from senscal.gfimu._kernels import quaternion_integrate

__all__ = ["integrate_attitude", "attitude_error", "AttitudeError"]

G0 = 9.80665


def integrate_attitude(omega: np.ndarray, t: np.ndarray, q0=(1.0, 0.0, 0.0, 0.0)) -> np.ndarray:
    """Integrate body angular velocity into a body-to-navigation quaternion.

    Parameters
    ----------
    omega : ndarray, shape (3, T)
        Body angular velocity, rad/s (NaN not allowed).
    t : ndarray, shape (T,)
        Time, s.
    q0 : sequence of 4 floats
        Initial attitude ``(w, x, y, z)``; normalised.

    Returns
    -------
    ndarray, shape (4, T)
        Unit quaternions ``(qw, qx, qy, qz)``, ``q' = q (x) (0, w) / 2``.
    """
    omega = np.ascontiguousarray(omega, dtype=float)
    t = np.ascontiguousarray(t, dtype=float)
    if omega.ndim != 2 or omega.shape[0] != 3 or t.shape != (omega.shape[1],):
        raise InputError(f"omega must be (3, T) with t (T,), got {omega.shape} and {t.shape}")
    if not np.all(np.isfinite(omega)):
        raise InputError("angular velocity has NaN (rejected samples); fill them or use another method for attitude")
    q0 = np.asarray(q0, float)
    if q0.shape != (4,) or not np.linalg.norm(q0) > 0:
        raise InputError("initial quaternion must be 4 numbers, not all zero")
    return quaternion_integrate(omega, t, q0)


def attitude_angle_error(q: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Rotation angle between two attitude histories, rad (T,)."""
    dot = np.abs(np.sum(np.asarray(q) * np.asarray(q_true), axis=0))
    return 2.0 * np.arccos(np.clip(dot, 0.0, 1.0))


@dataclass(frozen=True)
class AttitudeError(ResultMixin):
    """How the attitude error grows over a record.

    Attributes
    ----------
    max_deg, final_deg : float
        Largest and last rotation-angle error, deg.
    growth_deg_per_s : float
        Slope of a straight line fitted to the error, deg/s.
    position_drift_m : float
        Position error at the end of the record that the attitude error
        alone causes through gravity leaking into the horizontal channels,
        ``g * double integral of the error angle``, m (a lower bound: noise
        and bias of the specific force add to it).
    error_deg : ndarray, shape (T,)
        The error angle over time, deg.
    """

    max_deg: float
    final_deg: float
    growth_deg_per_s: float
    position_drift_m: float
    error_deg: np.ndarray = field(repr=False)


def attitude_error(q: np.ndarray, q_true: np.ndarray, t: np.ndarray) -> AttitudeError:
    """Compare an attitude history with the truth.

    Parameters
    ----------
    q, q_true : ndarray, shape (4, T)
        Estimated and true quaternions.
    t : ndarray, shape (T,)
        Time, s.
    """
    e = attitude_angle_error(q, q_true)
    t = np.asarray(t, float)
    slope = float(np.polyfit(t - t[0], e, 1)[0]) if t.size > 1 else 0.0
    dt = np.diff(t)
    v = np.concatenate([[0.0], np.cumsum(0.5 * dt * (e[1:] + e[:-1]))])
    p = np.concatenate([[0.0], np.cumsum(0.5 * dt * (v[1:] + v[:-1]))])
    ed = np.degrees(e)
    return AttitudeError(max_deg=float(ed.max()), final_deg=float(ed[-1]), growth_deg_per_s=float(np.degrees(slope)),
                         position_drift_m=float(G0 * p[-1]), error_deg=ed)
