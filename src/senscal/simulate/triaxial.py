"""A rotated three-axis magnetometer (or accelerometer in gravity) with known errors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from senscal.errors import InputError
from senscal.io import Recording
from senscal.triaxial.models import sensor_matrix

__all__ = ["simulate_magnetometer", "MOTIONS"]

MOTIONS = ("sphere", "hemisphere", "band", "planar", "tumble")


def simulate_magnetometer(*, motion: str = "sphere", n: int | None = None, field: float | None = None,
                          alpha_deg: float = 0.8, beta_deg: float = -1.1, gamma_deg: float = 0.6,
                          gains: tuple[float, float, float] = (1.03, 0.98, 1.0),
                          offsets: tuple[float, float, float] | None = None, noise: float | None = None,
                          inclination_deg: float = 60.0, tilt_deg: float = 0.0, fs: float | None = None,
                          hold_s: float = 3.0, move_s: float = 1.5, clip: float | None = None,
                          n_outliers: int = 0, band_deg: float = 15.0, order: str = "random",
                          drift: tuple[float, float, float] | None = None, drift_shape: str = "linear",
                          field_step: float = 0.0, step_at: float = 0.5,
                          seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
    """Readings ``H_hat = K S R^T H + B + noise`` of a sensor turned in a constant field.

    Parameters
    ----------
    motion : {"sphere", "planar", "tumble"}
        ``sphere``: ``n`` (default 500) orientations uniform over all
        directions; ``hemisphere``: uniform over the directions with a
        positive Z component (a sensor that is never turned upside down);
        ``band``: uniform over the directions within ``band_deg`` of the XY
        plane (a vehicle that only rolls and pitches a little); ``planar``: the seed's protocol, ``n`` (default 15)
        headings of one horizontal turn (level sensor, field inclined by
        ``inclination_deg``; ``tilt_deg`` adds random tilt of that standard
        deviation); ``tumble``: an accelerometer-style session of ``n``
        (default 30) static poses held ``hold_s`` s, joined by moves of
        ``move_s`` s with hand-motion acceleration, sampled at ``fs``.
    n : int, optional
        Readings (sphere, planar) or poses (tumble).
    field : float, optional
        Field magnitude; default 50,000 nT, or 9.80665 m/s^2 for ``tumble``.
    alpha_deg, beta_deg, gamma_deg : float
        Non-orthogonality angles in degrees (seed convention).
    gains : (float, float, float)
        Kx, Ky, Kz.
    offsets : (float, float, float), optional
        B in sensor units; default (300, -200, 150) nT scaled to ``field``.
    noise : float, optional
        White noise standard deviation per axis; default 20 nT scaled to ``field``.
    band_deg : float
        Half-width of the ``band`` motion, deg.
    clip : float, optional
        Saturate every axis at +/- this value (sensor units).
    n_outliers : int
        Readings replaced by gross errors (spikes of 5-20 % of the field).
    order : {"random", "tumble"}
        ``sphere`` only.  ``random``: orientations in random order (the
        default).  ``tumble``: a systematic session, the sensor's Z axis
        turned from straight up to straight down (orientations sorted by the
        elevation of the Z axis; the field is inclined by
        ``inclination_deg``), so anything that changes slowly in time
        follows the orientation.
    drift : (float, float, float), optional
        Offset change over the session, sensor units (e.g. 10-30 nT while
        the sensor warms up).  The offsets of the truth are the session
        averages (mid-session values of a linear drift); ``drift_linear``
        is the change over the session of the best straight line through
        the offsets' path (``drift`` itself for a linear drift).
    drift_shape : {"linear", "warmup"}
        ``linear`` ramp, or a ``warmup`` that settles (``1 - exp(-3 s)``,
        ``s`` the session fraction): a drift the linear drift term models
        only approximately.
    field_step : float
        The field's magnitude changes by this much (field units) at
        ``step_at`` of the session (something nearby switching on); the
        change is parallel to the field.  The truth's ``field`` is then the
        session average (``field_before`` the value before the step).
    step_at : float
        Session fraction of the step.
    seed : int, optional

    Returns
    -------
    recording : Recording
        Channels ``x, y, z`` (unit nT or m/s^2).
    truth : dict
        Angles (deg), gains, offsets, field, noise, the linearised weights,
        and for ``tumble`` the true static intervals.
    """
    if motion not in MOTIONS:
        raise InputError(f"unknown motion {motion!r}; use one of {', '.join(MOTIONS)}")
    rng = np.random.default_rng(seed)
    accel = motion == "tumble"
    f = float(field) if field is not None else (9.80665 if accel else 50_000.0)
    scale = f / 50_000.0
    b = np.array(offsets if offsets is not None else (300.0 * scale, -200.0 * scale, 150.0 * scale), float)
    sigma = float(noise) if noise is not None else 20.0 * scale
    if not (f > 0 and sigma >= 0 and min(gains) > 0):
        raise InputError("field and gains must be positive and noise non-negative")
    if n_outliers < 0:
        raise InputError(f"the number of outliers must not be negative, got {n_outliers}")
    m = sensor_matrix(*gains, math.radians(alpha_deg), math.radians(beta_deg), math.radians(gamma_deg))
    intervals: list[list[float]] = []
    if order not in ("random", "tumble"):
        raise InputError(f"unknown order {order!r}; use random or tumble")
    if order == "tumble" and motion != "sphere":
        raise InputError("order='tumble' is a sphere session (Z up to Z down); use motion='sphere'")
    if drift_shape not in ("linear", "warmup"):
        raise InputError(f"unknown drift shape {drift_shape!r}; use linear or warmup")
    if not 0.0 < step_at < 1.0:
        raise InputError(f"step_at is a session fraction in (0, 1), got {step_at!r}")
    timed = order == "tumble" or field_step != 0.0
    if timed and motion != "sphere":
        raise InputError("a field step is simulated for motion='sphere'")
    if motion == "sphere" and timed:
        # Sensor orientations (not only field directions), so that a field fixed in the room can step and the
        # session can be ordered by where the Z axis points.
        n = 500 if n is None else n
        rots = Rotation.random(n, random_state=rng.integers(2**31))
        if order == "tumble":
            rots = rots[np.argsort(-rots.as_matrix()[:, 2, 2], kind="stable")]
        inc = math.radians(inclination_deg)
        earth = np.array([math.cos(inc), 0.0, -math.sin(inc)])
        frac = np.arange(n) / max(n - 1, 1)
        mag = f + field_step * (frac >= step_at)
        h = rots.inv().apply(earth).T * mag[None, :]
        f_avg = float(np.mean(mag))
        rate = 10.0 if fs is None else fs
        t = np.arange(n) / rate
    elif motion in ("sphere", "hemisphere", "band"):
        n = 500 if n is None else n
        if motion == "band" and not 0 < band_deg <= 90:
            raise InputError(f"the band half-width must be in (0, 90] deg, got {band_deg!r}")
        # Uniform on the sphere (or a zone of it): z uniform (Archimedes), azimuth uniform.
        zmax = {"sphere": (-1.0, 1.0), "hemisphere": (0.0, 1.0),
                "band": (-math.sin(math.radians(band_deg)), math.sin(math.radians(band_deg)))}[motion]
        if motion == "sphere":
            v = rng.normal(size=(3, n))
            h = f * v / np.linalg.norm(v, axis=0)
        else:
            z = rng.uniform(*zmax, size=n)
            az = rng.uniform(0.0, 2 * math.pi, size=n)
            rxy = np.sqrt(1.0 - z * z)
            h = f * np.vstack([rxy * np.cos(az), rxy * np.sin(az), z])
        rate = 10.0 if fs is None else fs
        t = np.arange(n) / rate
    elif motion == "planar":
        n = 15 if n is None else n
        inc = math.radians(inclination_deg)
        earth = f * np.array([math.cos(inc), 0.0, math.sin(inc)])
        psi = 2 * math.pi * np.arange(n) / n
        rots = Rotation.from_euler("z", psi[:, None])
        if tilt_deg > 0:
            tilt = Rotation.from_euler("xy", rng.normal(0.0, math.radians(tilt_deg), size=(n, 2)))
            rots = tilt * rots
        h = rots.inv().apply(earth).T
        rate = 1.0 if fs is None else fs
        t = np.arange(n) / rate
    else:
        n = 30 if n is None else n
        rate = 100.0 if fs is None else fs
        nh, nm = int(round(hold_s * rate)), int(round(move_s * rate))
        poses = Rotation.random(n, random_state=rng.integers(2**31))
        g_world = np.array([0.0, 0.0, f])
        parts = []
        k0 = 0
        for p in range(n):
            parts.append(np.repeat(poses[p].inv().apply(g_world)[:, None], nh, axis=1))
            intervals.append([k0 / rate, (k0 + nh - 1) / rate])
            k0 += nh
            if p < n - 1:
                s = np.linspace(0, 1, nm + 2)[1:-1]
                slerp = Slerp([0.0, 1.0], Rotation.concatenate([poses[p], poses[p + 1]]))
                rs = slerp(s)
                # Hand motion: a smooth acceleration burst while turning.
                burst = 0.3 * f * np.sin(np.pi * s) ** 2 * rng.normal(size=(3, 1))
                parts.append(rs.inv().apply(g_world).T + burst)
                k0 += nm
        h = np.concatenate(parts, axis=1)
        t = np.arange(h.shape[1]) / rate
    y = m @ h + b[:, None] + rng.normal(0.0, sigma, size=h.shape)
    drift_line = None
    if drift is not None:
        d = np.asarray(drift, float)
        sfrac = np.arange(h.shape[1]) / max(h.shape[1] - 1, 1)
        shape = sfrac if drift_shape == "linear" else (1 - np.exp(-3 * sfrac)) / (1 - math.exp(-3))
        # The truth's offsets are the session averages (the mid-session values of a linear drift), and its
        # drift the change over the session of the straight line that fits the offsets' path best.
        y = y + d[:, None] * (shape - shape.mean())[None, :]
        tc = sfrac - sfrac.mean()
        drift_line = (d * float(tc @ (shape - shape.mean()) / (tc @ tc))).tolist()
    out_idx: list[int] = []
    if n_outliers:
        out_idx = sorted(rng.choice(y.shape[1], size=n_outliers, replace=False).tolist())
        y[:, out_idx] += rng.choice([-1, 1], size=(3, n_outliers)) * rng.uniform(0.05, 0.2, (3, n_outliers)) * f
    if clip is not None:
        y = np.clip(y, -clip, clip)
    unit = "m/s^2" if accel else "nT"
    rec = Recording(channels={"x": y[0], "y": y[1], "z": y[2]}, t=t, units=dict.fromkeys("xyz", unit),
                    metadata={"simulator": "triaxial", "motion": motion})
    truth = {
        "motion": motion, "field": f if not timed or motion != "sphere" else f_avg, "unit": unit, "noise_std": sigma,
        "alpha_deg": alpha_deg, "beta_deg": beta_deg, "gamma_deg": gamma_deg,
        "Kx": gains[0], "Ky": gains[1], "Kz": gains[2], "Bx": b[0], "By": b[1], "Bz": b[2],
        "linear_weights": {"dKx": gains[0] - 1, "dKy": gains[1] - 1, "gamma": math.radians(gamma_deg),
                           "alpha": math.radians(alpha_deg), "beta": math.radians(beta_deg),
                           "Bx": b[0], "By": b[1], "Bz": b[2]},
        "matrix": m, "outlier_indices": out_idx, "clip": clip, "order": order,
        "drift": list(drift) if drift is not None else None, "drift_shape": drift_shape,
        "drift_linear": drift_line if drift is not None else None, "field_step": field_step,
        "step_at": step_at, "field_before": f,
        "static_intervals_s": intervals,
    }
    return rec, truth
