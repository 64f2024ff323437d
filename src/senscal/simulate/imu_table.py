"""Rate-table runs appended to a simulated multi-pose IMU session (``senscal simulate imu --rate-table``).

After the poses the IMU is mounted on a single-axis table whose axis is vertical: for each stated axis a
hand rotation brings that body axis up, the table rests, spins up (a raised-cosine ramp), turns at a
constant rate, spins down and rests; with ``both_signs`` the same again the other way.  Turning about the
vertical leaves gravity fixed in the body frame, so the accelerometer sees none of it (as on a real
table).  Departures are options: the table's true rate off its stated one (``rate_error_rel``), the IMU
mounted with its axis tilted from the stated one (``mount_tilt``), the temperature changing over the table
runs (``temperature_end``, with the session's warm-up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from senscal.io.ratetable import RateTable

__all__ = ["TableSpec", "table_motion", "rate_table_of"]


@dataclass(frozen=True)
class TableSpec:
    """The rate-table runs to simulate.

    Attributes
    ----------
    axes : tuple
        Body axes put on the table, in order (``"x"``, ``"-y"`` or 3-vectors).
    rate : float
        Table rate, rad/s (each axis turned at ``+rate``, and ``-rate`` with ``both_signs``).
    both_signs : bool
    hold_s, ramp_s, rest_s, mount_s : float
        Constant-rate part, spin-up/down, rest before and after, and the hand rotation onto the axis, s.
    margin_s : float
        The stated segment starts this long after the constant rate begins and stops this long before it ends.
    u_rate_rel : float
        The stated relative standard u of the rate (what the table file says); the table's true rate is off by
        one relative error drawn with it, common to all segments.
    u_axis : float
        The stated standard u of the axis direction per tilt direction, rad; each mount is tilted by a draw
        with it.
    rate_error_rel : float
        Departure: stated rate = true rate * (1 + rate_error_rel).
    mount_tilt : float
        Departure: the true table axis is tilted this far (rad) from the stated body axis, in a random direction.
    temperature_end : float, optional
        With the simulator's ``temperature`` warm-up: the warm-up spans the poses only and the temperature then
        changes linearly over the table runs to this value (degC), so it varies during and between the
        segments (the gyro's bias and scale follow it by their temperature coefficients).  None: the warm-up
        spans the whole session.
    """

    axes: tuple = ("x", "y", "z")
    rate: float = 1.0
    both_signs: bool = True
    hold_s: float = 20.0
    ramp_s: float = 1.0
    rest_s: float = 3.0
    mount_s: float = 2.0
    margin_s: float = 0.2
    u_rate_rel: float = 5e-5
    u_axis: float = 0.0
    rate_error_rel: float = 0.0
    mount_tilt: float = 0.0
    temperature_end: float | None = None


def _rot(e: np.ndarray, th: float) -> np.ndarray:
    k = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    return np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * (k @ k)


def _vec(axis) -> np.ndarray:
    if isinstance(axis, str):
        s = axis.strip().lower()
        v = np.zeros(3)
        v["xyz".index(s[-1])] = -1.0 if s.startswith("-") else 1.0
        return v
    v = np.asarray(axis, float)
    return v / np.linalg.norm(v)


def table_motion(spec: TableSpec, r_now: np.ndarray, gravity: float, fs: float, f_list: list, w_list: list,
                 rng: np.random.Generator) -> tuple[np.ndarray, RateTable, dict]:
    """Append the table runs to the simulator's specific-force and rate lists (in place).

    Parameters
    ----------
    spec : TableSpec
    r_now : ndarray (3, 3)
        Attitude at the end of the poses (body to world).
    gravity, fs : float
    f_list, w_list : list of ndarray (3, n)
        The session so far (its sample count sets the segments' times).
    rng : numpy Generator

    Returns
    -------
    (r_now, RateTable, truth)
        The final attitude, the table as its file states it, and the truth (true axes and rates).
    """
    up = np.array([0.0, 0.0, gravity])
    pos = sum(x.shape[1] for x in f_list)
    first = pos

    def still(n):
        nonlocal pos
        f_list.append(np.repeat((r_now.T @ up)[:, None], n, axis=1))
        w_list.append(np.zeros((3, n)))
        pos += n

    starts, stops, axes, rates, true_axes, true_rates = [], [], [], [], [], []
    eps = spec.u_rate_rel * rng.normal()  # the table's own rate error, within its stated u
    n_mount, n_rest = max(int(round(spec.mount_s * fs)), 2), int(round(spec.rest_s * fs))
    n_ramp, n_hold = max(int(round(spec.ramp_s * fs)), 2), int(round(spec.hold_s * fs))
    for axis in spec.axes:
        a = _vec(axis)
        ta = a
        if spec.mount_tilt:
            p = np.cross(a, rng.normal(size=3))
            ta = _rot(p / np.linalg.norm(p), spec.mount_tilt) @ a
        if spec.u_axis:
            # The mount tilts the axis within its stated u: towards two perpendicular directions, N(0, u_axis) each.
            e1 = np.cross(ta, rng.normal(size=3))
            e1 /= np.linalg.norm(e1)
            d = spec.u_axis * rng.normal(size=2)
            ta = ta + d[0] * e1 + d[1] * np.cross(ta, e1)
            ta /= np.linalg.norm(ta)
        # Hand rotation bringing the (true) table axis of the body up.
        v = r_now @ ta
        c = np.cross(v, [0.0, 0.0, 1.0])
        ang = math.atan2(float(np.linalg.norm(c)), float(v[2]))
        if ang > 1e-9:
            if np.linalg.norm(c) < 1e-9:
                c = np.cross(v, [1.0, 0.0, 0.0])
            e = r_now.T @ (c / np.linalg.norm(c))
            tau = (np.arange(n_mount) + 0.5) / n_mount
            prof = ang * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi))
            rate = ang / (n_mount / fs) * (1 - np.cos(2 * np.pi * tau))
            f_list.append(np.stack([(r_now @ _rot(e, q)).T @ up for q in prof], axis=1))
            w_list.append(e[:, None] * rate[None, :])
            pos += n_mount
            r_now = r_now @ _rot(e, ang)
        still(n_rest)
        for sign in ((1.0, -1.0) if spec.both_signs else (1.0,)):
            om = sign * spec.rate / (1.0 + eps)  # the table turns off its stated rate by its own error
            tau = (np.arange(n_ramp) + 0.5) / n_ramp
            ramp = 0.5 * (1 - np.cos(np.pi * tau))
            # Turning about the vertical: gravity stays fixed in the body frame.
            fb = np.repeat((r_now.T @ up)[:, None], 2 * n_ramp + n_hold, axis=1)
            wr = np.concatenate([om * ramp, np.full(n_hold, om), om * ramp[::-1]])
            f_list.append(fb)
            w_list.append(ta[:, None] * wr[None, :])
            r_now = r_now @ _rot(ta, float(wr.sum()) / fs)
            t0 = (pos + n_ramp) / fs
            starts.append(t0 + spec.margin_s)
            stops.append(t0 + (n_hold - 1) / fs - spec.margin_s)
            axes.append(a)
            rates.append(sign * spec.rate * (1.0 + spec.rate_error_rel))
            true_axes.append(ta)
            true_rates.append(om)
            pos += 2 * n_ramp + n_hold
            still(n_rest)
    rates_a = np.array(rates)
    table = RateTable(start=np.array(starts), stop=np.array(stops), axis=np.array(axes), rate=rates_a,
                      u_rate=np.abs(rates_a) * spec.u_rate_rel, u_axis=np.full(rates_a.size, spec.u_axis),
                      source="<simulated rate table>")
    truth = {"axis": np.array(true_axes).tolist(), "rate": list(map(float, true_rates)),
             "rate_error_rel": spec.rate_error_rel, "mount_tilt": spec.mount_tilt, "first_sample": int(first)}
    return r_now, table, truth


def rate_table_of(truth: dict) -> RateTable:
    """The stated rate table of a simulation's truth (``truth["rate_table"]``)."""
    d = truth["rate_table"]
    return RateTable(start=np.asarray(d["start"], float), stop=np.asarray(d["stop"], float),
                     axis=np.asarray(d["axis"], float), rate=np.asarray(d["rate"], float),
                     u_rate=np.asarray(d["u_rate"], float), u_axis=np.asarray(d["u_axis"], float),
                     source=str(d.get("source", "<simulated rate table>")))
