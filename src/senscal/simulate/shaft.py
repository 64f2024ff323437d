"""A tangential accelerometer on a tilted rotating shaft, with its encoder."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.signal import lfilter

from senscal.errors import InputError
from senscal.io import Recording

__all__ = ["angle_locked_motion", "ar1_noise", "simulate_shaft", "shaft_motion"]

G = 9.80665


def shaft_motion(t: np.ndarray, speed: float, terms: list[tuple[float, float, float]]):
    """Angle, angular velocity and acceleration of ``w(t) = speed * (1 + sum m_i sin(2 pi f_i t + p_i))``.

    Parameters
    ----------
    t : ndarray
        Time, s.
    speed : float
        Mean angular velocity, rad/s.
    terms : list of (m, f, p)
        Relative modulation depth, frequency (Hz) and phase (rad) of each term.

    Returns
    -------
    theta, omega, alpha : ndarray
        rad, rad/s, rad/s^2 (closed form, no integration error).
    """
    theta = speed * t
    omega = np.full_like(t, speed)
    alpha = np.zeros_like(t)
    for m, f, p in terms:
        wm = 2.0 * math.pi * f
        theta = theta - speed * m / wm * (np.cos(wm * t + p) - math.cos(p))
        omega = omega + speed * m * np.sin(wm * t + p)
        alpha = alpha + speed * m * wm * np.cos(wm * t + p)
    return theta, omega, alpha


def angle_locked_motion(t: np.ndarray, speed: float, m: float, p: float):
    """Angle, angular velocity and acceleration of ``w = speed * (1 + m sin(theta + p))`` (speed a function of angle).

    ``t(theta) = int dtheta / w(theta)`` on a grid of 1 mrad (trapezoid rule, error ~1e-9 s per
    turn) is inverted by linear interpolation (error ~ h^2 alpha / 8, below 1e-8 rad); the velocity
    and acceleration are then exact functions of the angle: ``alpha = w dw/dtheta``.

    Parameters
    ----------
    t : ndarray
        Time from 0, s (increasing).
    speed : float
        ``w0``, rad/s (> 0).
    m : float
        Relative ripple, |m| < 1.
    p : float
        Phase, rad.
    """
    span = speed * (1.0 + abs(m)) * float(t[-1] - t[0]) + 1.0
    grid = np.linspace(0.0, span, int(math.ceil(span / 1e-3)) + 2)
    inv = 1.0 / (speed * (1.0 + m * np.sin(grid + p)))
    tg = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(grid))])
    theta = np.interp(t - t[0], tg, grid)
    omega = speed * (1.0 + m * np.sin(theta + p))
    alpha = omega * speed * m * np.cos(theta + p)
    return theta, omega, alpha


def ar1_noise(rng: np.random.Generator, std: float, rho: float, n: int) -> np.ndarray:
    """Stationary AR(1) noise of standard deviation ``std`` and lag-one correlation ``rho`` (white for 0)."""
    white = rng.normal(0.0, std, n)
    if rho == 0.0 or n == 0:
        return white
    # x_k = rho x_(k-1) + sqrt(1 - rho^2) w_k, started in the stationary state (x_0 = w_0).
    c = math.sqrt(1.0 - rho * rho)
    return lfilter([c], [1.0, -rho], white, zi=[(1.0 - c) * white[0]])[0]


def simulate_shaft(*, tilt_deg: float = 20.0, radius: float = 0.1, sensitivity: float = 1.0, bias: float = 0.05,
                   misalignment_deg: float = 0.5, noise: float = 0.02, encoder_counts: int = 4096,
                   phase_deg: float = 30.0, fs: float = 1000.0, speed_rps: float = 1.0, ripple: float = 0.03,
                   ripple_freq: float = 2.7, sync_ripple: float = 0.0, cal_duration: float = 20.0,
                   test_speed_rps: float = 2.0, modulation: float = 0.5, modulation_freq: float = 0.5,
                   test_duration: float = 10.0, wrap: bool = True, g: float = G, noise_rho: float = 0.0,
                   angle_ripple: float = 0.0, angle_ripple_phase_deg: float = 0.0, eccentricity_deg: float = 0.0,
                   start_angle_deg: float = 0.0, seed: int | None = None) -> tuple[Recording, Recording, dict[str, Any]]:
    """Calibration and test runs of a tangential accelerometer on a tilted shaft.

    The sensitive axis is turned by ``misalignment`` from the tangent towards
    the axis of rotation (in the plane of rotation), so the output is::

        v = S * (cos(d) r alpha + sin(d) r w^2 + g cos(tilt) sin(theta + phase)) + bias + noise

    with ``phase = phase_deg + misalignment`` (the misalignment turns the
    gravity sinusoid too).  The encoder angle is ``theta`` rounded to
    ``encoder_counts`` per revolution, in degrees (wrapped to 0..360 unless
    ``wrap`` is false).

    Parameters
    ----------
    tilt_deg : float
        Shaft axis tilt from horizontal, deg (90 = vertical: no gravity term).
    radius : float
        Sensor distance from the axis, m.
    sensitivity : float
        Output per m/s^2 (1: output in m/s^2).
    bias : float
        Sensor bias, output unit.
    misalignment_deg : float
        Sensitive axis angle from the tangent toward the centre, deg.
    noise : float
        Noise standard deviation of the output, output unit (white unless ``noise_rho``).
    encoder_counts : int
        Encoder resolution, counts per revolution.
    phase_deg : float
        Gravity phase at encoder zero for a perfectly aligned sensor, deg.
    fs : float
        Sample rate, Hz.
    speed_rps : float
        Calibration speed, rev/s.
    ripple, ripple_freq : float
        Relative speed ripple of the calibration run and its frequency (Hz).
    sync_ripple : float
        Relative speed ripple at the rotation frequency (locked to the turn,
        like an unbalanced shaft); it cannot be told from gravity without the radius.
    cal_duration : float
        Calibration run length, s.
    test_speed_rps, modulation, modulation_freq, test_duration : float
        Test run: mean speed (rev/s), relative sinusoidal speed modulation,
        its frequency (Hz) and the run length (s).
    wrap : bool
        Write the encoder angle wrapped to 0..360 deg.
    g : float
        Local gravity, m/s^2.
    noise_rho : float
        Lag-one correlation of the output noise, in [0, 1): AR(1) noise of
        standard deviation ``noise`` (a departure from white noise: an
        accelerometer's own low-pass, mains hum or mechanical vibration).
    angle_ripple : float
        Relative speed ripple of the calibration run as a function of the
        shaft angle: ``w = w0 (1 + angle_ripple sin(theta + angle_ripple_phase))``
        (a once-per-turn drive or load torque; its harmonics follow the angle
        exactly).  Replaces the time-domain terms (``ripple``,
        ``sync_ripple``) of the calibration run when nonzero; must be < 1.
    angle_ripple_phase_deg : float
        Its phase, deg.
    eccentricity_deg : float
        Once-per-turn error of the encoder angle (an eccentric or tilted
        disc), deg: the encoder reads ``theta + e sin(theta + q)`` before
        rounding, in both runs, with ``q`` drawn at random (in ``truth``).
    start_angle_deg : float
        True shaft angle at the start of each run, deg.  With 0 the angle
        starts on a count of the encoder; another value puts the count grid
        elsewhere against the angle (what a real run does): a run whose
        readings advance a whole number of counts per sample then reads every
        angle off by the same fraction of a count.
    seed : int, optional
        Random seed.

    Returns
    -------
    calibration, test : Recording
        Channels ``angle`` (deg) and ``accel`` (output unit).
    truth : dict
        Parameters, the true gravity model (amplitude, phase, offset of the
        calibration run), and the noise floor of the angular acceleration.
    """
    if not (radius > 0 and fs > 0 and noise >= 0 and encoder_counts >= 4 and cal_duration > 0 and test_duration > 0):
        raise InputError("radius > 0, fs > 0, noise >= 0, encoder_counts >= 4 and positive durations are required")
    if sensitivity <= 0:
        raise InputError("sensitivity must be positive")
    if not (0.0 <= noise_rho < 1.0):
        raise InputError(f"noise_rho (--noise-rho) must be in [0, 1), got {noise_rho!r}; 0 gives white noise")
    if not (0.0 <= abs(angle_ripple) < 1.0 and math.isfinite(eccentricity_deg) and math.isfinite(start_angle_deg)):
        raise InputError(f"angle_ripple must be in (-1, 1) and eccentricity finite, got {angle_ripple!r}, "
                         f"{eccentricity_deg!r}")
    rng = np.random.default_rng(seed)
    d = math.radians(misalignment_deg)
    ecc = math.radians(eccentricity_deg)
    start = math.radians(start_angle_deg)
    # Drawn only when asked for, so the other runs' random streams stay those of earlier versions.
    ecc_phase = float(rng.uniform(0, 2 * math.pi)) if ecc else 0.0
    amp = sensitivity * g * math.cos(math.radians(tilt_deg))
    ph = math.radians(phase_deg) + d
    step = 2.0 * math.pi / encoder_counts
    out_unit = "m/s^2" if sensitivity == 1.0 else "V"

    def run(duration, speed, terms, name, locked=0.0):
        t = np.arange(int(round(duration * fs))) / fs
        if locked:
            theta, omega, alpha = angle_locked_motion(t, speed, locked, math.radians(angle_ripple_phase_deg) + start)
        else:
            theta, omega, alpha = shaft_motion(t, speed, terms)
        theta = theta + start
        v = sensitivity * (math.cos(d) * radius * alpha + math.sin(d) * radius * omega**2) \
            + amp * np.sin(theta + ph) + bias + ar1_noise(rng, noise, noise_rho, t.size)
        read = theta + ecc * np.sin(theta + ecc_phase) if ecc else theta
        enc = np.degrees(np.round(read / step) * step)
        if wrap:
            enc = np.mod(enc, 360.0)
        rec = Recording(channels={"angle": enc, "accel": v}, t=t, units={"angle": "deg", "accel": out_unit},
                        metadata={"simulator": "shaft", "run": name})
        return rec, omega, alpha

    w0 = 2.0 * math.pi * speed_rps
    cal_terms = [(ripple, ripple_freq, float(rng.uniform(0, 2 * math.pi)))]
    if sync_ripple:
        cal_terms.append((sync_ripple, speed_rps, float(rng.uniform(0, 2 * math.pi))))
    cal, w_cal, _ = run(cal_duration, w0, cal_terms, "calibration", locked=angle_ripple)
    w1 = 2.0 * math.pi * test_speed_rps
    test, w_test, al_test = run(test_duration, w1, [(modulation, modulation_freq, 0.0)], "test")
    leak = math.sin(d) * radius
    truth = {
        "noise_rho": noise_rho, "tilt_deg": tilt_deg, "radius": radius, "sensitivity": sensitivity, "bias": bias,
        "misalignment_deg": misalignment_deg, "noise_std": noise, "encoder_counts": encoder_counts, "fs": fs, "g": g,
        "output_unit": out_unit,
        "gravity": {"amplitude": amp, "phase_deg": math.degrees(math.atan2(math.sin(ph), math.cos(ph))),
                    # the misaligned axis adds its centripetal term at the calibration speeds to the offset
                    "offset": bias + sensitivity * leak * float(np.mean(w_cal**2))},
        "calibration": {"speed_rps": speed_rps, "ripple": ripple, "ripple_freq_hz": ripple_freq,
                        "sync_ripple": sync_ripple, "angle_ripple": angle_ripple,
                        "angle_ripple_phase_deg": angle_ripple_phase_deg, "duration_s": cal_duration,
                        "mean_square_speed": float(np.mean(w_cal**2))},
        "test": {"speed_rps": test_speed_rps, "modulation": modulation, "modulation_freq_hz": modulation_freq,
                 "duration_s": test_duration,
                 "angular_acceleration_rms": float(np.sqrt(np.mean(al_test**2))),
                 "angular_acceleration_amplitude": w1 * modulation * 2 * math.pi * modulation_freq},
        "eccentricity_deg": eccentricity_deg, "eccentricity_phase_deg": math.degrees(ecc_phase),
        "start_angle_deg": start_angle_deg,
        "centripetal_leakage_coefficient_m": leak,
        "angular_acceleration_noise_floor": noise / (sensitivity * radius),
        "uncompensated_error_amplitude": g * math.cos(math.radians(tilt_deg)) / radius,
    }
    truth["_test_angular_acceleration"] = al_test
    return cal, test, truth
