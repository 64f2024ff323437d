"""A noisy multi-channel sine recording with known truth."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording

__all__ = ["simulate_sine", "ar1_noise"]


def ar1_noise(rng: np.random.Generator, shape: tuple[int, ...], std: float, rho: float) -> np.ndarray:
    """Stationary first-order autoregressive noise along the last axis.

    ``e_i = rho e_{i-1} + w_i`` with the innovation ``w`` scaled so that every
    sample has standard deviation ``std`` (the first sample is drawn from the
    stationary distribution, so there is no start-up transient).

    Parameters
    ----------
    rng : numpy.random.Generator
    shape : tuple of int
        Output shape; samples along the last axis.
    std : float
        Marginal standard deviation (unit of the signal).
    rho : float
        Lag-one correlation, ``-1 < rho < 1`` (0 is white noise).

    Returns
    -------
    ndarray
    """
    from scipy.signal import lfilter

    w = rng.normal(0.0, std, shape)
    if rho == 0.0:
        return w
    w[..., 1:] *= math.sqrt(1.0 - rho * rho)
    return lfilter([1.0], [1.0, -rho], w, axis=-1)


def simulate_sine(*, n_channels: int = 4, fs: float = 1000.0, duration: float = 2.0, frequency: float = 12.5,
                  noise: float = 0.05, t0: float = 0.0, noise_rho: float = 0.0,
                  seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
    """Channels ``A_i sin(2 pi f t + phi_i) + C_i + noise`` on one time base.

    Parameters
    ----------
    n_channels : int
        Number of channels ``ch1..chN``.
    fs : float
        Sample rate in Hz.
    duration : float
        Record length in s.
    frequency : float
        Common frequency in Hz.
    noise : float
        Standard deviation of the Gaussian noise of each sample (unit of the channel).
    t0 : float
        Time of the first sample in s.
    noise_rho : float
        Departure from white noise: lag-one correlation of first-order
        autoregressive (AR(1)) noise, ``-1 < rho < 1``; 0 (default) is white.
        The per-sample standard deviation stays ``noise``; the noise density
        near 0 Hz grows by ``(1 + rho) / (1 - rho)``.
    seed : int, optional
        Random seed.

    Returns
    -------
    recording : Recording
    truth : dict
        ``{"frequency_hz", "noise_std", "noise_rho", "channels": {name: {"amplitude", "phase_deg", "offset"}}}``.
    """
    if not -1.0 < noise_rho < 1.0:
        from senscal.errors import InputError

        raise InputError(f"noise_rho must lie strictly between -1 and 1 (stationary AR(1) noise), got {noise_rho!r}")
    rng = np.random.default_rng(seed)
    n = int(round(duration * fs))
    t = t0 + np.arange(n) / fs
    chans = {}
    truth_ch = {}
    for i in range(n_channels):
        amp = float(rng.uniform(0.5, 5.0))
        ph = float(rng.uniform(-math.pi, math.pi))
        off = float(rng.uniform(-2.0, 2.0))
        name = f"ch{i + 1}"
        chans[name] = amp * np.sin(2 * math.pi * frequency * t + ph) + off + ar1_noise(rng, (n,), noise, noise_rho)
        truth_ch[name] = {"amplitude": amp, "phase_deg": math.degrees(ph), "offset": off}
    rec = Recording(channels=chans, t=t, units={k: "V" for k in chans}, metadata={"simulator": "sine"})
    return rec, {"frequency_hz": frequency, "noise_std": noise, "noise_rho": noise_rho, "channels": truth_ch}
