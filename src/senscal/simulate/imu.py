"""A multi-pose IMU session with known truth (the IMU-TK protocol).

A still start, then ``n_poses`` static poses joined by smooth rotations about
random axes (each about one fixed axis, so the truth attitude and rate are
exact).  The accelerometer reads ``Ma f + Ba + noise`` (``Ma`` the triaxial
engine's upper-triangular ``K S``), the gyroscope ``Mg w + b(t) + noise``
(``Mg`` full: scales and misalignment to the accelerometer's frame).
Departures are options: a drifting gyro bias, coloured gyro noise, short
poses, fast rotations, few poses, rotations that leave an axis unturned, a
temperature warm-up with bias and scale temperature coefficients (accelerometer bias and scale, gyro bias and
scale), a gyro
sensitive to specific force (g-sensitivity), a turn about the vertical inside a pose (``yaw_poses``: the
accelerometer sees one pose, the gyro a rotation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording
from senscal.triaxial.models import sensor_matrix

__all__ = ["simulate_imu", "gyro_truth"]

CHANNELS = ("ax", "ay", "az", "gx", "gy", "gz")


def _rot(e: np.ndarray, th: float) -> np.ndarray:
    k = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    return np.eye(3) + math.sin(th) * k + (1 - math.cos(th)) * (k @ k)


def gyro_truth(matrix: np.ndarray) -> dict[str, float]:
    """Scale (signed row norm, reading per rad/s) and misalignment angles (rad) of a gyro matrix."""
    from senscal.imu.calibrate import GYRO_ANGLES, _derived

    d = _derived(np.asarray(matrix, float).ravel())
    return {**{f"scale_{a}": float(d[i]) for i, a in enumerate("xyz")},
            **{f"angle_{n}": float(d[3 + i]) for i, n in enumerate(GYRO_ANGLES)}}


def simulate_imu(*, n_poses: int = 30, fs: float = 100.0, init_s: float = 20.0, pose_s: float = 3.0,
                 rotation_s: float = 1.5, angle_deg: tuple[float, float] = (60.0, 150.0), gravity: float = 9.80665,
                 accel_noise: float = 0.02, gyro_noise: float = 0.002,
                 accel_gains: tuple[float, float, float] = (1.02, 0.99, 1.01),
                 accel_angles_deg: tuple[float, float, float] = (0.5, -0.8, 0.3),
                 accel_offsets: tuple[float, float, float] = (0.15, -0.10, 0.20),
                 gyro_scales: tuple[float, float, float] = (1.01, 0.985, 1.005),
                 gyro_misalignment_deg: tuple[float, ...] = (0.3, -0.5, 0.4, 0.2, -0.3, 0.6),
                 gyro_bias: tuple[float, float, float] = (0.01, -0.02, 0.015),
                 gyro_bias_drift: tuple[float, float, float] = (0.0, 0.0, 0.0), gyro_ar1: float = 0.0,
                 exclude_axis: int | None = None, temperature: tuple[float, float] | None = None,
                 temp_nominal: float = 25.0, temp_noise: float = 0.01,
                 accel_bias_tc: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 accel_scale_tc: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 gyro_bias_tc: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 gyro_scale_tc: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 gyro_g_sensitivity: Any = None, rate_table: Any = None, yaw_poses: int = 0, yaw_deg: float = 90.0,
                 yaw_hold_s: float | None = None, seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
    """Simulate an IMU calibration session.

    Parameters
    ----------
    n_poses : int
        Static poses after the still start.
    fs : float
        Sample rate, Hz.
    init_s, pose_s, rotation_s : float
        Still start, each pose and each rotation, s (``rotation_s`` small: fast motion).
    angle_deg : (float, float)
        Range of each rotation's angle, deg.
    gravity : float
        Local g, m/s^2.
    accel_noise : float
        White noise per accelerometer sample, m/s^2.
    gyro_noise : float
        Noise per gyro sample, rad/s (white, or AR(1) with ``gyro_ar1``, same per-sample std).
    accel_gains, accel_angles_deg, accel_offsets :
        Accelerometer model (triaxial convention: gains, alpha/beta/gamma in deg, offsets in m/s^2).
    gyro_scales : (float, float, float)
        Gyro scale per axis (reading per rad/s, before misalignment).
    gyro_misalignment_deg : 6 floats
        Off-diagonal elements of ``Mg = diag(scales) (I + A)`` as angles: xy, xz, yx, yz, zx, zy (deg).
    gyro_bias : (float, float, float)
        Gyro bias at mid-session, rad/s.
    gyro_bias_drift : (float, float, float)
        Gyro bias change per second (departure: a bias drifting during the session).
    gyro_ar1 : float
        AR(1) coefficient of the gyro noise (departure: coloured noise).
    exclude_axis : int, optional
        Never rotate about this body axis (0, 1, 2): the departure that leaves a gyro axis unexcited.
    temperature : (float, float), optional
        Warm-up from the first to the second temperature (degC) over the session, ``1 - exp(-3 t / T)``
        shaped; adds the channel ``temp``.  None: no temperature channel, no temperature effects.
    temp_nominal : float
        Temperature at which the accelerometer and gyro parameters above hold, degC.
    temp_noise : float
        Per-sample noise of the temperature channel, K.
    accel_bias_tc, accel_scale_tc : 3 floats
        Accelerometer bias change (m/s^2 per K) and relative scale change (per K):
        ``a = (1 + s dT) (Ma f + Ba) + c dT``, ``dT = T - temp_nominal``.
    gyro_bias_tc : 3 floats
        Gyro bias change, rad/s per K.
    gyro_scale_tc : 3 floats
        Relative gyro scale change per K, per gyro axis: ``g = (1 + s_g dT) Mg w + ...`` (each row of ``Mg``
        scaled, so the misalignment angles stay).
    gyro_g_sensitivity : array_like (3, 3), optional
        Gyro reading per m/s^2 of specific force (rad/s per m/s^2).
    yaw_poses : int
        Departure: this many poses (spread evenly over the session) hold a turn about the vertical by ``yaw_deg``
        (alternating sign) in their middle: ``yaw_hold_s`` still, the turn (``rotation_s``), ``yaw_hold_s``
        still.  Gravity stays fixed in the body frame, so the accelerometer sees one pose; the gyro sees the turn.
    yaw_deg : float
        Angle of each such turn, deg.
    yaw_hold_s : float, optional
        Still time before and after the turn, s (default ``pose_s``: two full poses; below the detector's
        ``--min-pose`` the pose cannot be split).
    rate_table : senscal.simulate.imu_table.TableSpec, optional
        Rate-table runs after the poses (:func:`senscal.simulate.imu_table.table_motion`); the stated table is
        ``truth["rate_table"]`` (:func:`senscal.simulate.imu_table.rate_table_of`).
    seed : int, optional

    Returns
    -------
    (Recording, dict)
        Channels ax, ay, az (m/s^2), gx, gy, gz (rad/s); the truth (accelerometer parameters, the gyro matrix,
        bias, drift, noise, the time of mid-session).
    """
    rng = np.random.default_rng(seed)
    dt = 1.0 / fs
    n_init, n_pose, n_rot = int(round(init_s * fs)), int(round(pose_s * fs)), max(int(round(rotation_s * fs)), 2)
    up = np.array([0.0, 0.0, gravity])
    f_list, w_list = [], []
    r_now = np.eye(3)
    f_list.append(np.repeat((r_now.T @ up)[:, None], n_init, axis=1))
    w_list.append(np.zeros((3, n_init)))
    tau = (np.arange(n_rot) + 0.5) / n_rot
    # Poses holding a turn about the vertical (no random draw: the other departures' seeds stay as they were).
    yaw_at = set(np.linspace(0, n_poses - 1, int(yaw_poses) + 2)[1:-1].round().astype(int).tolist()) if yaw_poses else set()
    n_hold = int(round((pose_s if yaw_hold_s is None else yaw_hold_s) * fs))
    yaw_sign = 1.0
    for p_i in range(n_poses):
        e = rng.normal(size=3)
        if exclude_axis is not None:
            e[exclude_axis] = 0.0
        e /= np.linalg.norm(e)
        th = math.radians(rng.uniform(*angle_deg)) * rng.choice([-1.0, 1.0])
        prof = th * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi))
        # The rate over the n_rot samples actually drawn (rotation_s * fs rounds to whole samples): its sum
        # is the angle turned.
        rate = th / (n_rot * dt) * (1 - np.cos(2 * np.pi * tau))
        f_list.append(np.stack([(r_now @ _rot(e, p)).T @ up for p in prof], axis=1))
        w_list.append(e[:, None] * rate[None, :])
        r_now = r_now @ _rot(e, th)
        if p_i in yaw_at:
            # Still, a turn about the vertical (gravity fixed in the body frame), still: one pose to the
            # accelerometer.
            f_list.append(np.repeat((r_now.T @ up)[:, None], n_hold, axis=1))
            w_list.append(np.zeros((3, n_hold)))
            ev = r_now.T @ np.array([0.0, 0.0, 1.0])
            th_y = yaw_sign * math.radians(yaw_deg)
            yaw_sign = -yaw_sign
            f_list.append(np.repeat((r_now.T @ up)[:, None], n_rot, axis=1))
            w_list.append(ev[:, None] * (th_y / (n_rot * dt) * (1 - np.cos(2 * np.pi * tau)))[None, :])
            r_now = r_now @ _rot(ev, th_y)
            f_list.append(np.repeat((r_now.T @ up)[:, None], n_hold, axis=1))
            w_list.append(np.zeros((3, n_hold)))
            continue
        f_list.append(np.repeat((r_now.T @ up)[:, None], n_pose, axis=1))
        w_list.append(np.zeros((3, n_pose)))
    table = None
    if rate_table is not None:
        from senscal.simulate.imu_table import table_motion

        r_now, table, table_truth = table_motion(rate_table, r_now, gravity, fs, f_list, w_list, rng)
    f = np.concatenate(f_list, axis=1)
    w = np.concatenate(w_list, axis=1)
    n = f.shape[1]
    t = np.arange(n) * dt
    ma = sensor_matrix(*accel_gains, *(math.radians(a) for a in accel_angles_deg))
    ba = np.asarray(accel_offsets, float)
    a_meas = ma @ f + ba[:, None] + accel_noise * rng.normal(size=(3, n))
    mis = np.zeros((3, 3))
    for (i, j), ang in zip(((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)), gyro_misalignment_deg):
        mis[i, j] = math.radians(ang)
    mg = np.diag(gyro_scales) @ (np.eye(3) + mis)
    t_mid = 0.5 * (t[0] + t[-1])
    b = np.asarray(gyro_bias, float)[:, None] + np.asarray(gyro_bias_drift, float)[:, None] * (t - t_mid)[None, :]
    e = rng.normal(size=(3, n))
    if gyro_ar1:
        from scipy.signal import lfilter

        e = lfilter([math.sqrt(1 - gyro_ar1 ** 2)], [1.0, -gyro_ar1], e, axis=1)
    g_meas = mg @ w + b + gyro_noise * e
    chans = {**{c: a_meas[i] for i, c in enumerate(CHANNELS[:3])}, **{c: g_meas[i] for i, c in enumerate(CHANNELS[3:])}}
    units = {**{c: "m/s^2" for c in CHANNELS[:3]}, **{c: "rad/s" for c in CHANNELS[3:]}}
    if gyro_g_sensitivity is not None:
        g_meas += np.asarray(gyro_g_sensitivity, float) @ f
    if temperature is not None:
        t_end = getattr(rate_table, "temperature_end", None)
        n_w = table_truth["first_sample"] if table is not None and t_end is not None else n
        span = max(t[n_w - 1] - t[0], 1e-9)
        temp = temperature[0] + (temperature[1] - temperature[0]) * (1 - np.exp(-3 * (t - t[0]) / span)) / (1 - math.exp(-3))
        if n_w < n:
            # The table runs: linear from the warm-up's last temperature to the stated end.
            temp[n_w:] = temp[n_w - 1] + (float(t_end) - temp[n_w - 1]) * (t[n_w:] - t[n_w - 1]) / (t[-1] - t[n_w - 1])
        dtn = temp - temp_nominal
        noise_a = a_meas - (ma @ f + ba[:, None])
        a_meas[:] = ((1 + np.asarray(accel_scale_tc, float)[:, None] * dtn[None, :]) * (ma @ f + ba[:, None])
                     + np.asarray(accel_bias_tc, float)[:, None] * dtn[None, :] + noise_a)
        g_meas += np.asarray(gyro_bias_tc, float)[:, None] * dtn[None, :]
        g_meas += np.asarray(gyro_scale_tc, float)[:, None] * dtn[None, :] * (mg @ w)
        chans["temp"] = temp + temp_noise * rng.normal(size=n)
        units["temp"] = "degC"
    rec = Recording(chans, t=t, units=units, source="<simulated imu>")
    truth = {"gravity": gravity, "fs": fs, "n_poses": n_poses, "t_mid": t_mid,
             "accelerometer": {"Kx": accel_gains[0], "Ky": accel_gains[1], "Kz": accel_gains[2],
                               "alpha": math.radians(accel_angles_deg[0]), "beta": math.radians(accel_angles_deg[1]),
                               "gamma": math.radians(accel_angles_deg[2]), "Bx": ba[0], "By": ba[1], "Bz": ba[2]},
             "gyroscope": {"matrix": mg.tolist(), **gyro_truth(mg), "bias": list(map(float, gyro_bias)),
                           "bias_drift": list(map(float, gyro_bias_drift)), "noise": gyro_noise, "ar1": gyro_ar1},
             "accel_noise": accel_noise,
             "temperature": None if temperature is None else {
                 "range": list(map(float, temperature)), "nominal": temp_nominal, "accel_bias_tc": list(accel_bias_tc),
                 "accel_scale_tc": list(accel_scale_tc), "gyro_bias_tc": list(gyro_bias_tc),
                 "gyro_scale_tc": list(gyro_scale_tc)},
             "g_sensitivity": None if gyro_g_sensitivity is None else np.asarray(gyro_g_sensitivity, float).tolist(),
             "yaw_poses": sorted(yaw_at), "yaw_deg": float(yaw_deg) if yaw_at else 0.0}
    if table is not None:
        truth["rate_table"] = {**table.to_dict(), "truth": table_truth}
    return rec, truth
