"""A homodyne quadrature interferometer watching an accelerometer on a vibration exciter (ISO 16063-11 method 3).

The table moves ``s(t) = D sin(w t + phi_d)`` (+ exciter harmonics); the
interferometer gives ``I = p + a cos(4 pi s / lambda) + noise`` and
``Q = q + g a sin(4 pi s / lambda + alpha) + noise`` (Heydemann errors: offsets,
gain ratio, quadrature error); the accelerometer reads ``S`` times the
acceleration delayed by its phase, plus noise.  Departures are options: exciter
harmonic distortion, output drift, mains hum on the output, laser intensity
drift.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording

__all__ = ["simulate_interferometer", "default_acceleration"]


def default_acceleration(freq: float) -> float:
    """Acceleration amplitude (m/s^2) of a realistic point: 1 m/s^2, at least 0.5 um displacement."""
    w = 2 * math.pi * freq
    return max(1.0, w * w * 0.5e-6)


def simulate_interferometer(*, freq: float = 160.0, acceleration: float | None = None, fs: float = 200_000.0,
                            duration: float = 1.0, wavelength_nm: float = 632.8, sensitivity: float = 0.01,
                            phase_deg: float = -2.0, offsets: tuple[float, float] = (0.03, -0.04),
                            gain_ratio: float = 1.03, quadrature_deg: float = 3.0, laser_noise: float = 2e-3,
                            output_noise_rel: float = 1e-3, harmonic_distortion: float = 0.0,
                            output_drift_rel: float = 0.0, hum_rel: float = 0.0, hum_hz: float = 50.0,
                            intensity_drift: float = 0.0, swap_iq: bool = False, heterodyne: bool = False,
                            carrier_hz: float = 250_000.0, carrier_offset_hz: float = 0.0,
                            carrier_drift_hz: float = 0.0, am_depth: float = 0.0, am_hz: float = 37.0,
                            reference: bool = True, transverse_rel: float = 0.0, displacement_noise_m: float = 0.0,
                            displacement_noise_ar1: float = 0.0,
                            seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
    """Simulate one frequency point of a primary calibration.

    Parameters
    ----------
    freq : float
        Excitation frequency, Hz.
    acceleration : float, optional
        Acceleration amplitude, m/s^2 (default :func:`default_acceleration`).
    fs, duration : float
        Sample rate (Hz) and record length (s).
    wavelength_nm : float
        Laser wavelength, nm.
    sensitivity : float
        Accelerometer sensitivity, V per m/s^2.
    phase_deg : float
        Output phase minus acceleration phase, deg.
    offsets : (float, float)
        Offsets of I and Q relative to the I amplitude.
    gain_ratio : float
        Q amplitude / I amplitude.
    quadrature_deg : float
        Quadrature phase error, deg.
    laser_noise : float
        White noise on I and Q relative to the I amplitude.
    output_noise_rel : float
        White noise on the output relative to its amplitude.
    harmonic_distortion : float
        Exciter's 2nd and 3rd harmonic displacement relative to the fundamental's
        acceleration (the 2nd at this, the 3rd at half of it).
    output_drift_rel : float
        Linear output drift over the record, relative to the output amplitude.
    hum_rel, hum_hz : float
        Mains hum on the output (relative amplitude, frequency).
    intensity_drift : float
        Linear change of the laser intensity over the record (relative).
    swap_iq : bool
        Write I and Q swapped (a wiring mistake).
    heterodyne : bool
        A heterodyne interferometer (ISO 16063-41) instead: one channel ``H = A(t) cos(2 pi f_c t +
        4 pi s / lambda) + noise`` (``laser_noise`` relative to its amplitude), and with ``reference`` the
        carrier itself in channel ``ref`` (the frequency shifter's drive, same offset and drift, its own
        noise). The Heydemann errors do not apply.
    carrier_hz : float
        Nominal carrier (frequency shift), Hz.
    carrier_offset_hz, carrier_drift_hz : float
        The true carrier's constant offset from ``carrier_hz``, and its linear change over the record, Hz.
    am_depth, am_hz : float
        Amplitude modulation of the carrier: ``A(t) = 1 + am_depth sin(2 pi am_hz t + random)``.
    reference : bool
        Write the reference carrier channel ``ref`` (heterodyne only).
    transverse_rel : float
        Transverse (parasitic) motion seen by the accelerometer's transverse sensitivity: the output gains
        ``S (c + i d)`` times the acceleration, ``c, d ~ N(0, transverse_rel)`` drawn per record (the product
        of the table's transverse-to-axial motion ratio and the sensor's relative transverse sensitivity,
        at a random angle and phase). The beam sees the axial motion only, so no recording shows it: the
        calibration's truth stays ``S``, and the effect belongs in the type B ``--u-other-rel`` /
        ``--u-other-phase-deg`` (ISO 16063-11 Annex A).
    displacement_noise_m, displacement_noise_ar1 : float
        Coloured noise of the measured displacement along the beam (laser frequency noise, air turbulence,
        the interferometer's own vibration): AR(1) with this lag-one coefficient and this standard
        deviation, m, added to the interferometer's phase only.
    seed : int, optional

    Returns
    -------
    (Recording, dict)
        Channels ``I``, ``Q`` (V) and ``out`` (V), or for ``heterodyne`` ``H`` (and ``ref``) and ``out``;
        truth with ``sensitivity`` and ``phase_deg`` at the fundamental.
    """
    rng = np.random.default_rng(seed)
    acc = default_acceleration(freq) if acceleration is None else float(acceleration)
    w = 2 * math.pi * freq
    n = int(round(duration * fs))
    t = np.arange(n) / fs
    ph0 = rng.uniform(-math.pi, math.pi)
    d1 = acc / (w * w)
    s = d1 * np.sin(w * t + ph0)
    hd = float(harmonic_distortion)
    dphi = math.radians(phase_deg)
    # the accelerometer: S times the acceleration advanced by its phase (a pure delay for the harmonics)
    out = sensitivity * (-acc * np.sin(w * t + ph0 + dphi))
    if hd:
        for k, r in ((2, hd), (3, hd / 2)):
            phk = rng.uniform(-math.pi, math.pi)
            dk = r * acc / (k * w) ** 2
            s = s + dk * np.sin(k * w * t + phk)
            out = out - sensitivity * r * acc * np.sin(k * w * t + phk + k * dphi)
    s_beam = s
    if displacement_noise_m:
        # drawn only when asked, so that every other option keeps its draws
        from scipy.signal import lfilter

        a1 = float(displacement_noise_ar1)
        e = rng.standard_normal(n) * float(displacement_noise_m) * math.sqrt(1.0 - a1 * a1)
        s_beam = s + lfilter([1.0], [1.0, -a1], e, zi=[a1 * float(displacement_noise_m) * rng.standard_normal()])[0]
    phi = 4 * math.pi * s_beam / (wavelength_nm * 1e-9)
    amp = 1.0 * (1.0 + intensity_drift * (t / max(duration, 1e-12) - 0.5))
    i_sig = offsets[0] + amp * np.cos(phi) + laser_noise * rng.standard_normal(n)
    q_sig = (offsets[1] + gain_ratio * amp * np.sin(phi + math.radians(quadrature_deg))
             + laser_noise * rng.standard_normal(n))
    out_amp = sensitivity * acc
    out = out + output_noise_rel * out_amp * rng.standard_normal(n)
    if output_drift_rel:
        out = out + output_drift_rel * out_amp * (t / duration - 0.5)
    if hum_rel:
        out = out + hum_rel * out_amp * np.sin(2 * math.pi * hum_hz * t + rng.uniform(-math.pi, math.pi))
    tr_c = tr_d = 0.0
    if transverse_rel:
        # the fundamental's output (-S a sin(w t + ph0 + dphi)) times (1 + c + i d): c in phase, d in quadrature
        tr_c, tr_d = (float(v) for v in float(transverse_rel) * rng.standard_normal(2))
        out = out - out_amp * (tr_c * np.sin(w * t + ph0 + dphi) + tr_d * np.cos(w * t + ph0 + dphi))
    if swap_iq:
        i_sig, q_sig = q_sig, i_sig
    channels = {"I": i_sig, "Q": q_sig, "out": out}
    het: dict[str, Any] = {}
    if heterodyne:
        # drawn after the homodyne channels so that a heterodyne option leaves every homodyne draw as it was
        fc = float(carrier_hz) + float(carrier_offset_hz)
        # carrier phase 2 pi (fc t + drift t^2 / (2 T)): its frequency runs from fc to fc + drift over the record
        cph = 2 * math.pi * ((fc * t) % 1.0 + float(carrier_drift_hz) * t * t / (2.0 * max(duration, 1e-12)))
        th0, thr, tham = rng.uniform(-math.pi, math.pi, 3)
        a_t = 1.0 + float(am_depth) * np.sin(2 * math.pi * am_hz * t + tham)
        channels = {"H": a_t * np.cos(cph + th0 + phi) + laser_noise * rng.standard_normal(n)}
        if reference:
            channels["ref"] = np.cos(cph + thr) + laser_noise * rng.standard_normal(n)
        channels["out"] = out
        het = {"heterodyne": True, "carrier_hz": float(carrier_hz), "carrier_offset_hz": float(carrier_offset_hz),
               "carrier_drift_hz": float(carrier_drift_hz), "am_depth": float(am_depth), "am_hz": float(am_hz),
               "doppler_max_hz": 2.0 * float(np.max(np.abs(np.gradient(s, 1.0 / fs)))) / (wavelength_nm * 1e-9)}
    rec = Recording(channels=channels, fs=fs, units={k: "V" for k in channels}, source="<interferometer>")
    truth = {"frequency_hz": freq, "sensitivity": sensitivity, "phase_deg": phase_deg, "acceleration": acc,
             "displacement_m": d1, "wavelength_nm": wavelength_nm, "offsets": list(offsets), "gain_ratio": gain_ratio,
             "quadrature_deg": quadrature_deg, "laser_noise": laser_noise, "output_noise_rel": output_noise_rel,
             "harmonic_distortion": hd, "output_drift_rel": output_drift_rel, "hum_rel": hum_rel, "hum_hz": hum_hz,
             "intensity_drift": intensity_drift, "swap_iq": swap_iq, "transverse_rel": float(transverse_rel),
             "transverse_drawn": [tr_c, tr_d], "displacement_noise_m": float(displacement_noise_m),
             "displacement_noise_ar1": float(displacement_noise_ar1), **het}
    return rec, truth
