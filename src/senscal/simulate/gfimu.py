"""A rigid body carrying an accelerometer array: readings with known truth.

The attitude is prescribed as yaw-pitch-roll (ZYX Euler) angles, each a
sine, so the body angular velocity, angular acceleration and attitude are
exact closed forms; the array origin sits at a body-fixed offset from the
rotation centre, which itself moves with a prescribed linear acceleration in
gravity.  Channels read the rigid-body acceleration along their (optionally
misaligned) directions at their (optionally displaced) positions, plus a
constant bias per channel and white noise.

References
----------
.. [1] Wang et al., China Measurement & Test 2017(5) (seed 001), section 4
   (simulation: 10 kHz, 10 s, constant error 1e-4 g, noise 1e-3 g,
   L = 0.04 m) and section 5 (angular vibration table, 30 deg, 2 Hz, array
   origin off the rotation centre).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.errors import InputError
from senscal.gfimu.layout import Layout, paper_layout
from senscal.io import Recording

__all__ = ["simulate_gfimu", "euler_motion", "G0"]

G0 = 9.80665


def _angle(amp: float, freq: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # Phase -pi/2: every angle starts at rest (zero rate), so w(0) = 0.
    ph = 2 * math.pi * freq * t - math.pi / 2
    om = 2 * math.pi * freq
    return amp * np.sin(ph), amp * om * np.cos(ph), -amp * om * om * np.sin(ph)


def euler_motion(t: np.ndarray, amplitudes_rad, freqs_hz) -> dict[str, np.ndarray]:
    """Closed-form kinematics of sinusoidal yaw, pitch, roll (ZYX Euler).

    Parameters
    ----------
    t : ndarray, shape (T,)
        Time, s.
    amplitudes_rad : sequence of 3 floats
        Amplitudes of roll (about x), pitch (about y), yaw (about z), rad.
    freqs_hz : sequence of 3 floats
        Their frequencies, Hz.  Each angle is ``A sin(2 pi f t - pi/2)``.

    Returns
    -------
    dict
        ``omega`` (3, T) body angular velocity (rad/s), ``alpha`` (3, T)
        angular acceleration (rad/s^2), ``q`` (4, T) body-to-navigation
        quaternion (w, x, y, z), ``R`` (T, 3, 3) body-to-navigation matrix.
    """
    (phi, dphi, ddphi), (th, dth, ddth), (psi, dpsi, ddpsi) = (
        _angle(a, f, t) for a, f in zip(amplitudes_rad, freqs_hz))
    sf, cf, st, ct, sp, cp = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th), np.sin(psi), np.cos(psi)
    wx = dphi - dpsi * st
    wy = dth * cf + dpsi * ct * sf
    wz = -dth * sf + dpsi * ct * cf
    ax = ddphi - ddpsi * st - dpsi * dth * ct
    ay = (ddth * cf - dth * dphi * sf + ddpsi * ct * sf - dpsi * dth * st * sf + dpsi * dphi * ct * cf)
    az = (-ddth * sf - dth * dphi * cf + ddpsi * ct * cf - dpsi * dth * st * cf - dpsi * dphi * ct * sf)
    R = np.empty((t.size, 3, 3))
    R[:, 0, 0] = cp * ct
    R[:, 0, 1] = cp * st * sf - sp * cf
    R[:, 0, 2] = cp * st * cf + sp * sf
    R[:, 1, 0] = sp * ct
    R[:, 1, 1] = sp * st * sf + cp * cf
    R[:, 1, 2] = sp * st * cf - cp * sf
    R[:, 2, 0] = -st
    R[:, 2, 1] = ct * sf
    R[:, 2, 2] = ct * cf
    c1, s1, c2, s2, c3, s3 = (np.cos(phi / 2), np.sin(phi / 2), np.cos(th / 2), np.sin(th / 2),
                              np.cos(psi / 2), np.sin(psi / 2))
    q = np.stack([c3 * c2 * c1 + s3 * s2 * s1, c3 * c2 * s1 - s3 * s2 * c1,
                  c3 * s2 * c1 + s3 * c2 * s1, s3 * c2 * c1 - c3 * s2 * s1])
    return {"omega": np.stack([wx, wy, wz]), "alpha": np.stack([ax, ay, az]), "q": q, "R": R}


def _perturb_directions(dirs: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    if sigma <= 0:
        return dirs
    # Small random tilt of std sigma (rad): a component orthogonal to the nominal direction.
    e = rng.normal(0.0, sigma, dirs.shape)
    e -= np.sum(e * dirs, axis=1, keepdims=True) * dirs
    d = dirs + e
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def simulate_gfimu(*, paper: bool = False, layout: Layout | None = None, distance: float = 0.04,
                   fs: float | None = None, duration: float | None = None,
                   amplitudes_deg=None, freqs_hz=None,
                   offset_m=None, linear_amplitude: float | None = None, linear_freqs_hz=(5.0, 7.0, 11.0),
                   bias_g: float = 1e-4, noise_g: float = 1e-3,
                   position_error_m: float = 0.0, direction_error_rad: float = 0.0, rest_s: float = 0.0,
                   scale_error: float = 0.0, seed: int | None = None) -> tuple[Recording, Recording, dict[str, Any]]:
    """Accelerometer-array readings on a moving rigid body, with the truth.

    Parameters
    ----------
    paper : bool
        The paper's set-up: single-axis angular vibration about z, 30 deg,
        2 Hz, array origin 0.1 m off the rotation centre, no linear motion,
        10 kHz, 10 s.  Otherwise a three-axis motion (roll 10 deg at 1.3 Hz,
        pitch 15 deg at 0.7 Hz, yaw 30 deg at 2 Hz) with 2 m/s^2 linear
        vibration, 1 kHz, 10 s.  Explicit arguments override either.
    layout : Layout, optional
        Array layout; default the paper's with mounting distance ``distance`` (m).
    fs, duration : float
        Sample rate (Hz) and record length (s).
    amplitudes_deg, freqs_hz : sequence of 3 floats
        Roll, pitch, yaw amplitudes (deg) and frequencies (Hz).
    offset_m : sequence of 3 floats
        Position of the array origin relative to the rotation centre, body
        frame, m.
    linear_amplitude : float
        Amplitude of the rotation centre's linear acceleration per
        navigation axis, m/s^2.
    bias_g, noise_g : float
        Per-channel constant bias magnitude (random sign) and white-noise
        standard deviation, in g (9.80665 m/s^2).
    position_error_m, direction_error_rad : float
        Standard deviation of the actual mounting position (m) and direction
        (rad) about the nominal layout (the solver sees the nominal one).
    scale_error : float
        Per-channel scale-factor error (a fraction: 5e-4 is 0.05 %), random
        sign: channel ``i`` reads ``(1 + e_i)`` times its acceleration, which
        the solver does not know (the layout assumes unit gains).
    rest_s : float
        The body rests (at its starting attitude, rotation centre still)
        for this long, s, before the motion starts; the record is
        ``duration`` s of motion after it (so that a rest segment can be
        marked, ``senscal gfimu --rest 0:REST``).
    seed : int, optional
        Random seed.

    Returns
    -------
    readings : Recording
        One channel per layout row, m/s^2.
    truth : Recording
        ``wx, wy, wz`` (rad/s), ``alpha_x..z`` (rad/s^2), ``f_x..z``
        (m/s^2, specific force at the origin), ``qw, qx, qy, qz``.
    info : dict
        The simulation parameters, per-channel biases and the actual layout.
    """
    fs = float(fs if fs is not None else (10000.0 if paper else 1000.0))
    duration = float(duration if duration is not None else 10.0)
    if paper:
        amplitudes_deg = amplitudes_deg if amplitudes_deg is not None else (0.0, 0.0, 30.0)
        freqs_hz = freqs_hz if freqs_hz is not None else (1.0, 1.0, 2.0)
        offset_m = offset_m if offset_m is not None else (0.1, 0.0, 0.0)
        linear_amplitude = linear_amplitude if linear_amplitude is not None else 0.0
    else:
        amplitudes_deg = amplitudes_deg if amplitudes_deg is not None else (10.0, 15.0, 30.0)
        freqs_hz = freqs_hz if freqs_hz is not None else (1.3, 0.7, 2.0)
        offset_m = offset_m if offset_m is not None else (0.05, -0.03, 0.02)
        linear_amplitude = linear_amplitude if linear_amplitude is not None else 2.0
    if not (fs > 0 and duration > 0 and noise_g >= 0 and bias_g >= 0 and position_error_m >= 0
            and direction_error_rad >= 0 and rest_s >= 0 and 0 <= scale_error < 1):
        raise InputError("fs > 0, duration > 0, non-negative bias, noise, mounting errors and rest, and a scale error "
                         "in [0, 1) are required")
    vals = [float(v) for v in (*amplitudes_deg, *freqs_hz, *offset_m, linear_amplitude)]
    if not (len(amplitudes_deg) == len(freqs_hz) == len(offset_m) == 3) or not all(math.isfinite(v) for v in vals) or any(f < 0 for f in freqs_hz):
        raise InputError("amplitudes (3, deg), frequencies (3, Hz, non-negative), offset (3, m) and the linear "
                         "amplitude must be finite numbers")
    n = int(round((duration + rest_s) * fs))
    if n < 3:
        raise InputError("the simulated record needs at least 3 samples; raise fs or duration")
    layout = layout if layout is not None else paper_layout(distance)
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    # During the rest the motion's clock stands at 0: every angle at its start value, zero rate, and
    # (the sines' phase) zero linear acceleration; the angular acceleration steps on at the start.
    tm = np.maximum(t - rest_s, 0.0)
    mot = euler_motion(tm, np.radians(amplitudes_deg), freqs_hz)
    if rest_s > 0:
        mot["alpha"][:, t < rest_s] = 0.0
    w, al = mot["omega"], mot["alpha"]
    off = np.asarray(offset_m, float)
    lin_f = np.asarray(linear_freqs_hz, float)
    a_nav = linear_amplitude * np.sin(2 * math.pi * lin_f[:, None] * tm)
    a_nav[2] += G0  # specific force = a - g, g = (0, 0, -G0) with z up
    f_c = np.einsum("tji,jt->it", mot["R"], a_nav)  # R^T (a - g): into the body frame
    wxo = np.cross(w.T, off).T
    f_o = f_c + np.cross(al.T, off).T + np.cross(w.T, wxo.T).T
    pos = layout.positions + rng.normal(0.0, position_error_m, layout.positions.shape) * (position_error_m > 0)
    dirs = _perturb_directions(layout.directions, direction_error_rad, rng)
    # a_i = n_i . (f + alpha x r_i + w x (w x r_i))
    wxr = np.cross(w.T[:, None, :], pos[None, :, :])
    acc = (f_o.T[:, None, :] + np.cross(al.T[:, None, :], pos[None, :, :])
           + np.cross(w.T[:, None, :], wxr))
    ideal = np.einsum("tmi,mi->mt", acc, dirs)
    bias = bias_g * G0 * rng.choice([-1.0, 1.0], size=layout.n_channels)
    noise = rng.normal(0.0, noise_g * G0, ideal.shape)
    # Drawn after the noise, and only when asked for: records without scale errors keep their seeds' values.
    scale = scale_error * rng.choice([-1.0, 1.0], size=layout.n_channels) if scale_error > 0 else np.zeros(layout.n_channels)
    y = ideal * (1.0 + scale[:, None]) + bias[:, None] + noise
    rec = Recording(channels=dict(zip(layout.names, y)), fs=fs, units={k: "m/s^2" for k in layout.names},
                    metadata={"simulator": "gfimu", "paper": paper})
    names = ["wx", "wy", "wz", "alpha_x", "alpha_y", "alpha_z", "f_x", "f_y", "f_z", "qw", "qx", "qy", "qz"]
    truth = Recording(channels=dict(zip(names, np.concatenate([w, al, f_o, mot["q"]]))), fs=fs,
                      units=dict(zip(names, ["rad/s"] * 3 + ["rad/s^2"] * 3 + ["m/s^2"] * 3 + [""] * 4)))
    info = {
        "paper": paper, "fs_hz": fs, "duration_s": duration, "distance_m": distance,
        "amplitudes_deg": list(map(float, amplitudes_deg)), "freqs_hz": list(map(float, freqs_hz)),
        "offset_m": off.tolist(), "linear_amplitude_m_s2": float(linear_amplitude), "rest_s": float(rest_s),
        "bias_g": bias_g, "noise_g": noise_g, "noise_std_m_s2": noise_g * G0,
        "bias_m_s2": dict(zip(layout.names, bias.tolist())),
        "position_error_m": position_error_m, "direction_error_rad": direction_error_rad,
        "scale_error": float(scale_error), "scale_errors": dict(zip(layout.names, scale.tolist())),
        "actual_positions_m": pos.tolist(), "actual_directions": dirs.tolist(),
    }
    return rec, truth, info
