"""Compass heading before and after calibration.

A compass user does not quote the field-norm spread; they quote how many
degrees the heading is off.  Heading here is the azimuth of the horizontal
field component in the sensor frame, ``psi = atan2(-Hy, Hx)`` (deg,
clockwise seen from above with Z down, the usual compass convention).  Its
*deviation* before calibration is the raw heading minus the calibrated one
(the classic compass deviation curve: hard iron gives a once-per-turn,
soft iron a twice-per-turn error); after calibration what is left is the
uncertainty of the calibrated heading itself, from the parameter covariance
and the per-reading noise.  With an accelerometer recorded alongside, both
are tilt-compensated (the field is rotated into the local level frame
first), and the spread of the dip angle between field and gravity, which
must be constant, checks both calibrations without any reference.

References
----------
.. [1] M. J. Caruso, "Applications of magnetic sensors for low cost compass
   systems", IEEE PLANS 2000, 177-184 (heading, tilt compensation,
   hard/soft-iron deviation curves).
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

__all__ = ["heading_deg", "wrap_deg", "tilt_compensate", "dip_deg", "heading_report", "tilt_heading_report",
           "summary"]


def wrap_deg(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-180, 180) deg."""
    return (np.asarray(a, float) + 180.0) % 360.0 - 180.0


def heading_deg(hx: np.ndarray, hy: np.ndarray) -> np.ndarray:
    """Heading ``atan2(-Hy, Hx)`` in degrees [0, 360)."""
    return np.degrees(np.arctan2(-np.asarray(hy, float), np.asarray(hx, float))) % 360.0


def tilt_compensate(m: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal field components from a magnetometer and an accelerometer.

    Parameters
    ----------
    m, a : ndarray, shape (3, N)
        Magnetic field and specific force (any units) in the same sensor frame.

    Returns
    -------
    (xh, yh) : ndarray
        Field components in the local level frame (roll and pitch removed).
    """
    ax, ay, az = a
    roll = np.arctan2(ay, az)
    pitch = np.arctan2(-ax, ay * np.sin(roll) + az * np.cos(roll))
    mx, my, mz = m
    xh = mx * np.cos(pitch) + (my * np.sin(roll) + mz * np.cos(roll)) * np.sin(pitch)
    yh = my * np.cos(roll) - mz * np.sin(roll)
    return xh, yh


def dip_deg(m: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Angle between the field and the horizontal plane (deg), from the field and gravity directions."""
    c = np.einsum("ij,ij->j", m, a) / (np.linalg.norm(m, axis=0) * np.linalg.norm(a, axis=0))
    return np.degrees(np.arcsin(np.clip(c, -1.0, 1.0)))


def _stats(e: np.ndarray) -> dict[str, float]:
    return {"rms": float(np.sqrt(np.mean(e ** 2))), "max_abs": float(np.max(np.abs(e)))}


def heading_report(raw: np.ndarray, corrected: Callable[[np.ndarray], np.ndarray], theta: np.ndarray,
                   cov: np.ndarray | None, noise: float, axes: tuple[int, int] = (0, 1)) -> dict[str, Any]:
    """Heading deviation before calibration and heading uncertainty after, for a turn about one axis.

    Parameters
    ----------
    raw : ndarray, shape (3, N)
        Readings, sensor units.
    corrected : callable
        ``corrected(theta) -> (3, N)`` calibrated readings for parameters ``theta``.
    theta, cov : ndarray
        Fitted parameters and their covariance (None: no uncertainty after).
    noise : float
        Per-axis noise of one reading, sensor units.
    axes : (int, int)
        The horizontal axes (the plane of the turn).

    Returns
    -------
    dict
        ``heading_deg`` (calibrated, per reading), ``deviation_before_deg``
        (raw minus calibrated: rms, max_abs, and per reading),
        ``U_after_deg`` (k=2 uncertainty of the calibrated heading: rms,
        max_abs over readings, and per reading).
    """
    i, j = axes
    c = corrected(theta)
    psi = heading_deg(c[i], c[j])
    dev = wrap_deg(heading_deg(raw[i], raw[j]) - psi)
    out: dict[str, Any] = {"convention": "heading = atan2(-H_second_axis, H_first_axis) of the turn's plane axes, deg",
                           "axes": [int(i), int(j)], "heading_deg": psi,
                           "deviation_before_deg": {**_stats(dev), "per_reading": dev}}
    # Per reading, the calibrated heading moves by noise / horizontal radius
    # (the tangential noise component), and with the parameters by J cov J^T.
    rad = np.hypot(c[i], c[j])
    scale = np.median(np.hypot(raw[i] - np.median(raw[i]), raw[j] - np.median(raw[j]))) / np.median(rad)
    var = (noise / (rad * scale)) ** 2
    if cov is not None and np.all(np.isfinite(cov)):
        cols = []
        for k in range(len(theta)):
            step = 1e-6 * max(abs(theta[k]), 1e-3)
            tp, tm = np.array(theta, float), np.array(theta, float)
            tp[k] += step
            tm[k] -= step
            cp, cm = corrected(tp), corrected(tm)
            d = wrap_deg(heading_deg(cp[i], cp[j]) - heading_deg(cm[i], cm[j]))
            cols.append(np.radians(d) / (2 * step))
        jac = np.column_stack(cols)
        var = var + np.einsum("nk,kl,nl->n", jac, cov, jac)
    u2 = 2.0 * np.degrees(np.sqrt(var))
    out["U_after_deg"] = {**_stats(u2), "per_reading": u2, "k": 2}
    return out


def tilt_heading_report(m_raw: np.ndarray, m_cal: np.ndarray, a_raw: np.ndarray, a_cal: np.ndarray
                        ) -> dict[str, Any]:
    """Tilt-compensated heading deviation and dip-angle spread, before and after calibration.

    Parameters
    ----------
    m_raw, m_cal : ndarray, shape (3, N)
        Magnetometer readings raw and calibrated.
    a_raw, a_cal : ndarray, shape (3, N)
        Accelerometer readings raw and calibrated (same instants).

    Returns
    -------
    dict
        ``heading_deg`` (calibrated, tilt-compensated), ``deviation_before_deg``
        (raw minus calibrated), ``dip_before_deg`` and ``dip_after_deg``
        (mean and standard deviation: the dip is constant in a fixed field,
        so its spread measures what is left of both calibrations).
    """
    psi_raw = heading_deg(*tilt_compensate(m_raw, a_raw))
    psi = heading_deg(*tilt_compensate(m_cal, a_cal))
    dev = wrap_deg(psi_raw - psi)
    d0, d1 = dip_deg(m_raw, a_raw), dip_deg(m_cal, a_cal)
    return {"heading_deg": psi, "deviation_before_deg": {**_stats(dev), "per_reading": dev},
            "dip_before_deg": {"mean": float(d0.mean()), "std": float(d0.std(ddof=1))},
            "dip_after_deg": {"mean": float(d1.mean()), "std": float(d1.std(ddof=1))},
            "tilt_compensated": True}


def summary(rep: dict[str, Any]) -> dict[str, Any]:
    """The report without per-reading arrays (for JSON and printing)."""
    out = {}
    for k, v in rep.items():
        if isinstance(v, dict):
            out[k] = {kk: vv for kk, vv in v.items() if kk != "per_reading"}
        elif isinstance(v, np.ndarray):
            continue
        else:
            out[k] = v
    return out
