"""Simulated vibration-calibration rigs with known truth: hydraulic rig
(velocity sensor vs position reference), double centrifuge (accelerometer as
a second-order system under a rotating 1 g-class field), back-to-back shaker.

References
----------
.. [1] Yang et al. 2014 (seed 000), experiment 1 (``shared/METHODS.md`` 1b).
.. [2] Qin Chaojun (seed 003), double-centrifuge calibration (METHODS.md 4).
.. [3] ISO 16063-21:2003, back-to-back comparison.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from senscal.errors import InputError
from senscal.io import Recording

__all__ = ["simulate_hydraulic", "simulate_centrifuge", "simulate_shaker", "second_order_response"]

TWO_PI = 2.0 * math.pi


def second_order_response(frequency, natural_frequency: float, damping: float) -> np.ndarray:
    """Complex response ``H(jw) = wn^2 / (wn^2 - w^2 + 2 j zeta wn w)`` of a
    spring-mass accelerometer (``H(0) = 1``).

    Parameters
    ----------
    frequency : array_like
        Hz.
    natural_frequency : float
        Undamped natural frequency in Hz.
    damping : float
        Damping ratio (dimensionless).
    """
    w = TWO_PI * np.asarray(frequency, dtype=float)
    wn = TWO_PI * natural_frequency
    return wn**2 / (wn**2 - w**2 + 2j * damping * wn * w)


def _check_freqs(freqs: Sequence[float], fs: float, what: str) -> list[float]:
    freqs = [float(f) for f in freqs]
    if not freqs or any(not (0 < f < 0.5 * fs) for f in freqs):
        raise InputError(f"{what} frequencies must be positive and below the Nyquist frequency {0.5 * fs:g} Hz")
    return freqs


def simulate_hydraulic(*, frequencies: Sequence[float] | None = None, fs: float = 1000.0, periods: float = 8.3,
                       min_duration: float = 4.0, position_amplitude: float = 0.02, sensitivity: float = 0.1368,
                       delay: float = 5e-4, position_noise: float = 2e-6, velocity_noise: float = 3e-4,
                       offset: float = 0.01, drift: float = 1e-3, distortion: float = 0.0,
                       sensitivity_scatter: float = 0.0, position_scale: float = 1.0, swap_channels: bool = False,
                       seed: int | None = None,
                       ) -> tuple[list[Recording], dict[str, Any]]:
    """Servo cylinder moving sinusoidally; position sensor and velocity sensor.

    The cylinder follows ``x(t) = A_p sin(w t + phi)`` (m), plus a third
    harmonic of relative amplitude ``distortion`` (servo-valve nonlinearity).  The position
    sensor reads ``x`` with white noise; the velocity sensor reads
    ``S * dx/dt`` delayed by ``delay`` (its electronics: a pure delay, flat
    amplitude, phase ``-360 f delay`` deg), plus an offset with a linear
    drift and white noise.

    Parameters
    ----------
    frequencies : sequence of float, optional
        Excitation frequencies in Hz (default: the seed's w = 2 pi .. 11 pi
        rad/s, i.e. 1.0 .. 5.5 Hz in 10 points).
    fs : float
        Sample rate, Hz.
    periods, min_duration : float
        Each record holds ``max(periods / f, min_duration)`` seconds (not a
        whole number of periods, as in a real acquisition).
    position_amplitude : float
        Peak displacement, m.
    sensitivity : float
        Velocity-sensor sensitivity, V/(m/s).
    delay : float
        Sensor delay, s.
    position_noise, velocity_noise : float
        Noise standard deviations, m and V.
    offset, drift : float
        Velocity-sensor offset (V) and its drift (V/s).
    distortion : float
        Third-harmonic amplitude of the motion relative to the fundamental.
    sensitivity_scatter : float
        Departure (off by default): relative standard deviation of the
        sensor's sensitivity from record to record (remounting, temperature),
        which no single record can show.  ``truth["sensitivity"]`` stays the
        mean; each point's truth is its own record's sensitivity.
    position_scale : float
        Departure (1 = off): the position channel holds the displacement
        times this factor while its unit still says m (a reference recorded
        in mm, 1000, or um, 1e6, under a bare header).
    swap_channels : bool
        Departure (off by default): the ``position`` and ``velocity`` columns
        hold each other's data (a wiring or export mix-up); units stay as named.
    seed : int, optional

    Returns
    -------
    recordings : list of Recording
        Channels ``position`` (m) and ``velocity`` (V).
    truth : dict
        ``sensitivity``, ``delay_s``, and per point ``frequency_hz``,
        ``sensitivity``, ``phase_deg`` (sensor vs true velocity).
    """
    rng = np.random.default_rng(seed)
    freqs = _check_freqs(frequencies if frequencies is not None else [k / 2.0 for k in range(2, 12)], fs, "hydraulic")
    if not (position_noise >= 0 and velocity_noise >= 0):
        raise InputError("noise levels must be non-negative")
    if not 0 <= sensitivity_scatter < 0.5:
        raise InputError(f"sensitivity scatter must be a relative standard deviation in [0, 0.5), got {sensitivity_scatter!r}")
    if not (math.isfinite(position_scale) and position_scale > 0):
        raise InputError(f"position scale must be a positive factor, got {position_scale!r}")
    recs, points = [], []
    for f in freqs:
        n = int(round(max(periods / f, min_duration) * fs))
        t = np.arange(n) / fs
        w = TWO_PI * f
        phi = rng.uniform(-math.pi, math.pi)
        phi3 = rng.uniform(-math.pi, math.pi)
        a3 = distortion * position_amplitude
        pos = (position_amplitude * np.sin(w * t + phi) + a3 * np.sin(3 * (w * t) + phi3)
               + rng.normal(0.0, position_noise, n))
        td = t - delay
        vel_true_delayed = w * position_amplitude * np.cos(w * td + phi) + 3 * w * a3 * np.cos(3 * w * td + phi3)
        off = offset * rng.uniform(0.5, 1.5)
        # Drawn only when asked, so the default simulation keeps its random stream.
        s_rec = sensitivity * (1.0 + sensitivity_scatter * rng.standard_normal()) if sensitivity_scatter else sensitivity
        vel = s_rec * vel_true_delayed + off + drift * t + rng.normal(0.0, velocity_noise, n)
        if swap_channels:
            pos, vel = vel, pos
        recs.append(Recording(channels={"position": pos * position_scale, "velocity": vel}, t=t,
                              units={"position": "m", "velocity": "V"},
                              metadata={"simulator": "hydraulic", "frequency_hz": f}))
        points.append({"frequency_hz": f, "sensitivity": s_rec, "phase_deg": -360.0 * f * delay})
    truth = {"sensitivity": sensitivity, "unit": "V/(m/s)", "delay_s": delay, "position_amplitude_m": position_amplitude,
             "position_noise_m": position_noise, "velocity_noise_v": velocity_noise, "distortion": distortion,
             "sensitivity_scatter": sensitivity_scatter, "position_scale": position_scale,
             "swap_channels": swap_channels, "points": points}
    return recs, truth


def simulate_centrifuge(*, frequencies: Sequence[float] = (0.1, 1.0, 5.0, 10.0), accelerations: Sequence[float] = (100.0,),
                        fs: float = 100.0, arm_radius: float = 1.0, static_sensitivity: float = 0.05,
                        natural_frequency: float = 40.0, damping: float = 0.6, bias: float = 0.02,
                        noise: float = 2e-3, quadratic: float = 0.0, cubic: float = 0.0, angle_noise_deg: float = 0.0,
                        revolutions: float = 3.4, min_duration: float = 20.0, encoder_zero_deg: float = 0.0,
                        sensitivity_scatter: float = 0.0, input_scatter: float = 0.0, encoder_lines: int = 0,
                        encoder_eccentricity_deg: float = 0.0, seed: int | None = None,
                        ) -> tuple[list[Recording], dict[str, Any]]:
    """Double centrifuge: constant centripetal field turned by a secondary turntable.

    The main arm (radius ``R``) spins at ``w1 = sqrt(a0 / R)`` so the test
    station sees a constant centripetal acceleration ``a0``; the secondary
    turntable turns the accelerometer at frequency ``f``, so its sensitive
    axis sees ``a0 cos(theta(t))`` with ``theta`` the turntable angle.  The
    accelerometer is a second-order system ``H`` (natural frequency,
    damping) with static sensitivity ``S0``, bias, white noise and an
    optional polynomial nonlinearity applied to its proof-mass response
    ``x``: ``out = S0 (x + quadratic x^2 + cubic x^3) + bias + noise``.
    The records start at a random turntable angle (not a 360 deg crossing)
    and do not hold whole revolutions, so angle synchronisation is needed.
    The angle channel is wrapped to [0, 360) like an encoder.

    Parameters
    ----------
    frequencies : sequence of float
        Turntable frequencies in Hz (seed: 0.1, 1, 5, 10).
    accelerations : sequence of float
        Peak accelerations ``a0`` in m/s^2; one record per (frequency, a0).
    fs : float
        Sample rate of every channel in Hz (seed: 100 Hz).
    arm_radius : float
        Main-arm radius in m (sets the main speed in the truth).
    static_sensitivity : float
        ``S0`` in V/(m/s^2).
    natural_frequency, damping : float
        Second-order model (Hz, ratio).
    bias, noise : float
        Output bias and white-noise standard deviation, V.
    quadratic, cubic : float
        Nonlinearity coefficients in 1/(m/s^2) and 1/(m/s^2)^2.
    angle_noise_deg : float
        Angle-encoder noise standard deviation, degrees.
    revolutions, min_duration : float
        Each record lasts ``max(revolutions / f, min_duration)`` s.
    encoder_zero_deg : float
        Departure (off by default): the encoder reads ``theta - offset``, so
        encoder zero lies ``offset`` degrees from the field direction and
        the input phase at encoder zero is ``phi_0 = 90 + offset`` deg
        (``truth["initial_phase_deg"]``).
    sensitivity_scatter : float
        Departure: relative standard deviation of ``S0`` from record to record
        (remounting between repeats); each point's truth is its own record's.
    input_scatter : float
        Departure: relative standard deviation of the actual peak acceleration
        about the nominal ``a0`` from record to record (main-arm speed set
        anew); the recordings' metadata and the truth keep the nominal ``a0``,
        the truth's sensitivity is the sensor's own.
    encoder_lines : int
        Departure (0, off, by default): the angle comes from an incremental
        encoder with this many counts per revolution, read as a counter does
        (``step * floor(angle / step)``, ``step = 360 / lines``), so every
        reading lies up to one step behind the true angle.  The readings are
        centred half a step behind, so the input phase at encoder zero that a
        start-up test with this encoder measures is ``90 + offset + step / 2``
        deg (``truth["initial_phase_deg"]``).
    encoder_eccentricity_deg : float
        Departure: once-per-turn angle error of the encoder (an eccentric
        disc), ``e sin(theta + beta)`` deg with a random ``beta`` per record.
    seed : int, optional

    Returns
    -------
    recordings : list of Recording
        Channels ``angle`` (deg) and ``output`` (V).
    truth : dict
        Model parameters and per record ``frequency_hz``, ``acceleration``,
        ``sensitivity`` (fundamental output / a0), ``normalized_sensitivity``
        (``S_i / S_0``) and ``phase_delay_deg`` (exact for the model,
        including the cubic term's effect on the fundamental).
    """
    rng = np.random.default_rng(seed)
    freqs = _check_freqs(frequencies, fs, "turntable")
    accs = [float(a) for a in accelerations]
    if not accs or any(a <= 0 for a in accs):
        raise InputError("peak accelerations must be positive (m/s^2)")
    if not (natural_frequency > 0 and damping > 0):
        raise InputError("natural frequency and damping must be positive")
    if not (noise >= 0 and angle_noise_deg >= 0):
        raise InputError("noise levels must be non-negative")
    if not math.isfinite(encoder_zero_deg):
        raise InputError(f"encoder zero offset must be a finite number of degrees, got {encoder_zero_deg!r}")
    for name, v in (("sensitivity scatter", sensitivity_scatter), ("input scatter", input_scatter)):
        if not 0 <= v < 0.5:
            raise InputError(f"{name} must be a relative standard deviation in [0, 0.5), got {v!r}")
    if int(encoder_lines) != encoder_lines or encoder_lines < 0 or 0 < encoder_lines < 4:
        raise InputError(f"encoder lines must be a whole number of counts per revolution (>= 4, 0 = ideal), "
                         f"got {encoder_lines!r}")
    if not (math.isfinite(encoder_eccentricity_deg) and 0 <= encoder_eccentricity_deg < 90):
        raise InputError(f"encoder eccentricity must be in [0, 90) deg, got {encoder_eccentricity_deg!r}")
    step = 360.0 / encoder_lines if encoder_lines else 0.0
    recs, points = [], []
    for a0 in accs:
        for f in freqs:
            n = int(round(max(revolutions / f, min_duration) * fs))
            t = np.arange(n) / fs
            theta0 = rng.uniform(20.0, 340.0)
            theta = theta0 + 360.0 * f * t
            h = complex(second_order_response(f, natural_frequency, damping))
            # Departures are drawn only when asked, so default simulations keep their random stream.
            s0 = static_sensitivity * (1.0 + sensitivity_scatter * rng.standard_normal()) if sensitivity_scatter \
                else static_sensitivity
            a_true = a0 * (1.0 + input_scatter * rng.standard_normal()) if input_scatter else a0
            # Steady-state proof-mass response to a0 cos(theta).
            x = a_true * abs(h) * np.cos(np.radians(theta) + np.angle(h))
            out = s0 * (x + quadratic * x**2 + cubic * x**3) + bias + rng.normal(0.0, noise, n)
            theta_enc = theta - encoder_zero_deg if encoder_zero_deg else theta
            if encoder_eccentricity_deg:
                theta_enc = theta_enc + encoder_eccentricity_deg * np.sin(np.radians(theta) + rng.uniform(0, 2 * math.pi))
            if angle_noise_deg > 0:
                theta_enc = theta_enc + rng.normal(0.0, angle_noise_deg, n)
            if step:
                theta_enc = step * np.floor(theta_enc / step)
            angle = np.mod(theta_enc, 360.0)
            recs.append(Recording(channels={"angle": angle, "output": out}, t=t, units={"angle": "deg", "output": "V"},
                                  metadata={"simulator": "centrifuge", "frequency_hz": f, "acceleration": a0}))
            amp_x = a_true * abs(h)
            fund = s0 * (amp_x + 0.75 * cubic * amp_x**3)
            points.append({"frequency_hz": f, "acceleration": a0, "acceleration_true": a_true,
                           "sensitivity": fund / a_true, "normalized_sensitivity": fund / a_true / static_sensitivity,
                           "output_amplitude": fund, "phase_delay_deg": math.degrees(np.angle(h)),
                           "main_speed_rad_s": math.sqrt(a_true / arm_radius)})
    truth = {"static_sensitivity": static_sensitivity, "unit": "V/(m/s^2)", "natural_frequency_hz": natural_frequency,
             "damping": damping, "bias": bias, "noise_std": noise, "quadratic": quadratic, "cubic": cubic,
             "arm_radius_m": arm_radius, "encoder_zero_deg": encoder_zero_deg, "encoder_lines": int(encoder_lines),
             "encoder_eccentricity_deg": encoder_eccentricity_deg,
             "initial_phase_deg": 90.0 + encoder_zero_deg + 0.5 * step, "sensitivity_scatter": sensitivity_scatter,
             "input_scatter": input_scatter, "points": points}
    return recs, truth


def simulate_shaker(*, frequencies: Sequence[float] = (20.0, 40.0, 80.0, 160.0, 315.0, 630.0, 1250.0),
                    fs: float = 25600.0, duration: float = 0.5, acceleration: float = 10.0,
                    reference_sensitivity: float = 0.0102, static_sensitivity: float = 0.005,
                    natural_frequency: float = 8000.0, damping: float = 0.03, noise: float = 5e-5,
                    reference_noise: float = 5e-5, seed: int | None = None) -> tuple[list[Recording], dict[str, Any]]:
    """Back-to-back calibration on a shaker: reference and DUT accelerometers.

    The shaker table moves at ``acceleration`` peak; the reference (flat,
    sensitivity ``S_ref``) and the device under test (second-order, ``S0``)
    see the same motion.

    Parameters
    ----------
    frequencies : sequence of float
        Hz.
    fs, duration : float
        Sample rate (Hz) and record length (s).
    acceleration : float
        Peak table acceleration, m/s^2.
    reference_sensitivity, static_sensitivity : float
        V/(m/s^2).
    natural_frequency, damping : float
        DUT second-order model (Hz, ratio).
    noise, reference_noise : float
        White-noise standard deviations of DUT and reference, V.
    seed : int, optional

    Returns
    -------
    recordings : list of Recording
        Channels ``reference`` and ``dut`` (V).
    truth : dict
        Per point ``frequency_hz``, ``sensitivity``, ``normalized_sensitivity``,
        ``phase_delay_deg`` (DUT vs reference).
    """
    rng = np.random.default_rng(seed)
    freqs = _check_freqs(frequencies, fs, "shaker")
    n = int(round(duration * fs))
    t = np.arange(n) / fs
    recs, points = [], []
    for f in freqs:
        h = complex(second_order_response(f, natural_frequency, damping))
        ph = rng.uniform(-math.pi, math.pi)
        w = TWO_PI * f
        ref = reference_sensitivity * acceleration * np.sin(w * t + ph) + rng.normal(0.0, reference_noise, n)
        dut = (static_sensitivity * acceleration * abs(h) * np.sin(w * t + ph + np.angle(h))
               + rng.normal(0.0, noise, n))
        recs.append(Recording(channels={"reference": ref, "dut": dut}, t=t, units={"reference": "V", "dut": "V"},
                              metadata={"simulator": "shaker", "frequency_hz": f}))
        points.append({"frequency_hz": f, "sensitivity": static_sensitivity * abs(h),
                       "normalized_sensitivity": abs(h), "phase_delay_deg": math.degrees(np.angle(h))})
    truth = {"reference_sensitivity": reference_sensitivity, "static_sensitivity": static_sensitivity, "unit": "V/(m/s^2)",
             "acceleration": acceleration, "natural_frequency_hz": natural_frequency, "damping": damping,
             "points": points}
    return recs, truth
