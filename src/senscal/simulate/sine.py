"""A noisy multi-channel sine recording with known truth."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording

__all__ = ["simulate_sine"]


def simulate_sine(*, n_channels: int = 4, fs: float = 1000.0, duration: float = 2.0, frequency: float = 12.5,
                  noise: float = 0.05, t0: float = 0.0, seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
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
        Standard deviation of the white Gaussian noise (unit of the channel).
    t0 : float
        Time of the first sample in s.
    seed : int, optional
        Random seed.

    Returns
    -------
    recording : Recording
    truth : dict
        ``{"frequency_hz", "noise_std", "channels": {name: {"amplitude", "phase_deg", "offset"}}}``.
    """
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
        chans[name] = amp * np.sin(2 * math.pi * frequency * t + ph) + off + rng.normal(0.0, noise, n)
        truth_ch[name] = {"amplitude": amp, "phase_deg": math.degrees(ph), "offset": off}
    rec = Recording(channels=chans, t=t, units={k: "V" for k in chans}, metadata={"simulator": "sine"})
    return rec, {"frequency_hz": frequency, "noise_std": noise, "channels": truth_ch}
