"""Half-sine shock pulses on an accelerometer, watched by a reference accelerometer (ISO 16063-22) or a laser
(ISO 16063-13).

The table's acceleration is a train of half-sine pulses ``A sin(pi t / T)``;
the reference reads ``S_ref`` times it (its true sensitivity drawn from the
stated ``u_reference_rel``, so the stated u is tested), the laser its velocity
or displacement (integrated exactly); the accelerometer reads ``S`` times the
acceleration through its mounted resonance.  Departures are options: noise
level and colour (AR(1)), the reference's u, the sensor's resonance (ringing),
a zero shift of the output that grows with the pulse.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording

__all__ = ["simulate_shock", "resonance_response"]


def resonance_response(f, resonance_hz: float | None, q: float = 30.0):
    """Complex gain of a mounted accelerometer's second-order resonance at ``f`` (Hz); 1 without one."""
    f = np.asarray(f, float)
    if resonance_hz is None:
        return np.ones_like(f, dtype=complex)
    r = f / resonance_hz
    return 1.0 / (1.0 - r * r + 1j * r / q)


def _noise(rng, n: int, sigma: float, ar1: float) -> np.ndarray:
    e = rng.standard_normal(n)
    if ar1:
        from scipy.signal import lfilter

        e = lfilter([math.sqrt(1 - ar1 * ar1)], [1.0, -ar1], e)
    return sigma * e


def simulate_shock(*, duration_ms: float = 1.0, peak: float = 1000.0, pulses: int = 1, fs: float | None = None,
                   sensitivity: float = 1e-4, mode: str = "comparison", reference_sensitivity: float = 1e-4,
                   u_reference_rel: float = 0.0, reference_noise_rel: float = 1e-3, output_noise_rel: float = 1e-3,
                   laser: str = "velocity", laser_noise: float | None = None, noise_ar1: float = 0.0,
                   resonance_hz: float | None = None, resonance_q: float = 30.0, zero_shift_rel: float = 0.0,
                   seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
    """Simulate one shock record.

    Parameters
    ----------
    duration_ms : float
        Half-sine duration T, ms.
    peak : float
        Peak acceleration, m/s^2 (pulse k of ``pulses`` at ``peak * (1 - 0.3 k / pulses)``).
    pulses : int
        Pulses in the record.
    fs : float, optional
        Sample rate, Hz (default: 200 samples per pulse, at least 100 kS/s).
    sensitivity : float
        The accelerometer's sensitivity, V per m/s^2.
    mode : {"comparison", "primary"}
        A reference accelerometer (channels ``ref``, ``out``) or a laser (``laser``, ``out``).
    reference_sensitivity, u_reference_rel : float
        Stated reference sensitivity (V per m/s^2) and its relative standard u; the true one is drawn from it.
    reference_noise_rel, output_noise_rel : float
        Noise of the reference and the output relative to their peak.
    laser : {"velocity", "displacement"}
        What the laser channel measures (m/s or m).
    laser_noise : float, optional
        Laser noise (m/s or m); default 1e-3 of the first pulse's velocity change (velocity) or 1 nm.
    noise_ar1 : float
        AR(1) coefficient of all noise (coloured noise).
    resonance_hz, resonance_q : float
        The mounted accelerometer's resonance (ringing); none when None.
    zero_shift_rel : float
        Zero shift of the output across each pulse, relative to its peak (grows with the pulse's area).
    seed : int, optional

    Returns
    -------
    (Recording, dict)
        The record and the truth (``sensitivity``, ``reference_sensitivity_true``, ``pulses``).
    """
    rng = np.random.default_rng(seed)
    T = duration_ms * 1e-3
    fs = float(fs) if fs else max(100_000.0, 200.0 / T)
    # quiet record before the first pulse, each pulse followed by 6 T of settling (at least 4 ms or 20 samples)
    gap = max(6 * T, 4e-3, 400 / fs)
    lead = max(4 * T, 2e-3, 256 / fs)
    total = lead + pulses * (T + gap)
    n = int(round(total * fs))
    t = np.arange(n) / fs
    acc = np.zeros(n)
    area = np.zeros(n)
    vel = np.zeros(n)
    disp = np.zeros(n)
    info = []
    for k in range(pulses):
        t0 = lead + k * (T + gap)
        a_k = peak * (1.0 - 0.3 * k / max(pulses, 1))
        tau = np.clip(t - t0, 0.0, T)
        inside = (t >= t0) & (t <= t0 + T)
        acc[inside] += a_k * np.sin(math.pi * (t[inside] - t0) / T)
        # exact integrals of the half-sine: velocity change 2 A T / pi per pulse
        v_k = a_k * T / math.pi * (1.0 - np.cos(math.pi * tau / T))
        vel += v_k
        disp += a_k * T / math.pi * (tau - T / math.pi * np.sin(math.pi * tau / T)) + np.where(
            t > t0 + T, 2 * a_k * T / math.pi * (t - t0 - T), 0.0)
        area += v_k / (2 * a_k * T / math.pi)
        info.append({"t_peak_s": t0 + T / 2, "peak_acceleration": a_k})
    # the DUT: S times the acceleration through its resonance (frequency domain on a padded record)
    m = 2 * n
    G = resonance_response(np.fft.rfftfreq(m, 1 / fs), resonance_hz, resonance_q)
    a_dut = np.fft.irfft(np.fft.rfft(acc, m) * G, m)[:n]
    out = sensitivity * a_dut + zero_shift_rel * sensitivity * peak * area
    out = out + _noise(rng, n, output_noise_rel * sensitivity * peak, noise_ar1)
    s_ref_true = reference_sensitivity * (1.0 + u_reference_rel * rng.standard_normal())
    units = {"out": "V"}
    if mode == "comparison":
        ref = s_ref_true * acc + _noise(rng, n, reference_noise_rel * s_ref_true * peak, noise_ar1)
        chans = {"ref": ref, "out": out}
        units["ref"] = "V"
    elif mode == "primary":
        if laser == "velocity":
            ln = laser_noise if laser_noise is not None else 1e-3 * 2 * peak * T / math.pi
            sig = vel + _noise(rng, n, ln, noise_ar1)
            units["laser"] = "m/s"
        elif laser == "displacement":
            ln = laser_noise if laser_noise is not None else 1e-9
            sig = disp + _noise(rng, n, ln, noise_ar1)
            units["laser"] = "m"
        else:
            raise ValueError("laser must be velocity or displacement")
        chans = {"laser": sig, "out": out}
    else:
        raise ValueError("mode must be comparison or primary")
    rec = Recording(channels=chans, fs=fs, units=units, source="<shock>")
    truth = {"mode": mode, "laser": laser if mode == "primary" else None, "duration_ms": duration_ms,
             "sensitivity": sensitivity, "reference_sensitivity": reference_sensitivity,
             "reference_sensitivity_true": s_ref_true, "u_reference_rel": u_reference_rel,
             "resonance_hz": resonance_hz, "resonance_q": resonance_q, "zero_shift_rel": zero_shift_rel,
             "noise_ar1": noise_ar1, "fs": fs, "pulses": info}
    return rec, truth
