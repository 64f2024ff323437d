"""Simulator: a slowly varying quantity watched by drifting sensors."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording

__all__ = ["simulate_drift"]

DAY = 86400.0


def simulate_drift(*, days: float = 10.0, dt: float = 300.0, noise: float = 0.05,
                   ramp_start_day: float = 4.0, ramp_rate_per_day: float = 0.3,
                   temperature_coefficient: float = 0.04, temperature_reference: float = 20.0,
                   seed: int | None = None) -> tuple[Recording, dict[str, Any]]:
    """Three sensors of one slowly varying quantity (e.g. a pressure in kPa).

    * ``ref``: no drift (the trusted sensor);
    * ``drift``: a ramp drift of ``ramp_rate_per_day`` from
      ``ramp_start_day`` on;
    * ``thermal``: a bias ``alpha * (temperature - reference)``, with the
      temperature on a daily cycle (±6 degC around 20 degC plus weather);
    * ``temperature``: the covariate channel [degC], measured with 0.05 degC
      noise.

    The quantity is ``100 + 0.8 sin(2 pi t / 3.7 d + phi)`` plus a random
    walk of 0.02 kPa/sqrt(day).  White measurement noise ``noise`` [kPa].

    Parameters
    ----------
    days : float
        Record length [day].
    dt : float
        Sample interval [s].
    noise : float
        Measurement noise standard deviation of the three sensors [kPa].
    ramp_start_day, ramp_rate_per_day : float
        Drift onset [day] and ramp slope [kPa/day] of ``drift``.
    temperature_coefficient : float
        ``alpha`` of ``thermal`` [kPa/degC].
    temperature_reference : float
        Temperature of zero thermal bias [degC].
    seed : int, optional

    Returns
    -------
    Recording
        Channels ``ref``, ``drift``, ``thermal``, ``temperature`` on ``t`` [s].
    dict
        Truth: scalars and the arrays ``signal``, ``bias_drift``,
        ``bias_thermal``, ``temperature_true``.
    """
    rng = np.random.default_rng(seed)
    T = int(round(days * DAY / dt)) + 1
    t = np.arange(T) * dt
    phi = rng.uniform(-math.pi, math.pi)
    rw_rate = 0.02 / math.sqrt(DAY)
    walk = np.concatenate([[0.0], np.cumsum(rng.normal(0.0, rw_rate * math.sqrt(dt), T - 1))])
    signal = 100.0 + 0.8 * np.sin(2 * math.pi * t / (3.7 * DAY) + phi) + walk
    weather = np.concatenate([[0.0], np.cumsum(rng.normal(0.0, 1.0 / math.sqrt(DAY) * math.sqrt(dt), T - 1))])
    temp = 20.0 + 6.0 * np.sin(2 * math.pi * t / DAY - math.pi / 2) + weather
    t_on = ramp_start_day * DAY
    bias_drift = np.where(t >= t_on, ramp_rate_per_day * (t - t_on) / DAY, 0.0)
    bias_thermal = temperature_coefficient * (temp - temperature_reference)
    ch = {
        "ref": signal + rng.normal(0.0, noise, T),
        "drift": signal + bias_drift + rng.normal(0.0, noise, T),
        "thermal": signal + bias_thermal + rng.normal(0.0, noise, T),
        "temperature": temp + rng.normal(0.0, 0.05, T),
    }
    rec = Recording(ch, t=t, units={"ref": "kPa", "drift": "kPa", "thermal": "kPa", "temperature": "degC"},
                    metadata={"simulator": "drift", "seed": seed})
    truth = {
        "days": days, "dt_s": dt, "noise_std": noise, "temperature_noise_std": 0.05,
        "ramp_channel": "drift", "ramp_start_s": t_on, "ramp_rate_per_s": ramp_rate_per_day / DAY,
        "thermal_channel": "thermal", "temperature_coefficient": temperature_coefficient,
        "temperature_reference": temperature_reference, "signal_rate_std": rw_rate,
        "signal": signal, "bias_drift": bias_drift, "bias_thermal": bias_thermal, "temperature_true": temp,
    }
    return rec, truth
