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


def simulate_drift_batch(n_series: int = 1, *, n: int = 600, dt: float = 1.0, channels: tuple[str, ...] = ("s1", "s2"),
                         trusted: tuple[str, ...] = ("s1",), noise: float = 0.1, signal: str = "random_walk",
                         signal_level: float = 0.1, signal_tau: float | None = None, signal_mean: float = 0.0,
                         bias: str = "random_walk", bias_rate: float = 0.01, ramp_start: float | None = None,
                         ramp_slope: float = 2e-3, covariate_coefficient: float | None = None,
                         covariate_reference: float = 20.0, covariate_offset: float = 0.0,
                         noise_rho: float = 0.0, coloured: tuple[str, ...] | None = None,
                         covariate_lag: float | None = None, seed: int | None = None) -> dict[str, Any]:
    """Many independent records of sensors watching one quantity (Monte Carlo).

    ``y_i = s + b_i + alpha_i (c - c_ref) + v_i`` for every channel not in
    ``trusted`` (trusted channels: ``s + v``), sampled every ``dt``.  Every
    departure from the drift filter's default model is an option, off by
    default:

    * ``signal``: ``random_walk`` (rate ``signal_level`` [unit/sqrt(s)]),
      ``gauss_markov`` (stationary std ``signal_level`` [unit], time constant
      ``signal_tau`` [s], around ``signal_mean``) or ``known`` (constant
      ``signal_mean``: a gyro at rest);
    * ``bias``: ``random_walk`` (rate ``bias_rate`` [unit/sqrt(s)]),
      ``ramp`` (zero until ``ramp_start`` [s], then ``ramp_slope``
      [unit/s]) or ``none``;
    * ``covariate_coefficient``: adds a covariate channel ``c`` (a
      temperature in degC: 20 + 3 sin over the record + a random walk of
      0.1 degC/sqrt(s), measured without noise) and a bias ``alpha (c -
      covariate_reference)``, plus a constant offset ``covariate_offset``
      (the sensor's offset at the reference, which one sensor cannot
      separate from the quantity);
    * ``noise_rho``: the measurement noise of the ``coloured`` channels
      (default: the biased ones) is AR(1), ``v_t = rho v_(t-1) + e_t``, with
      the same stationary std ``noise`` (coloured sensor noise: an
      anti-aliasing filter, a slow ADC reference);
    * ``covariate_lag``: the bias follows the covariate through a
      first-order lag of this time constant [s] (the sensor's own
      temperature lags the probe that is recorded); the recorded covariate
      is the probe's.

    Parameters
    ----------
    n_series : int
        Independent records S.
    n : int
        Samples per record.
    dt : float
        Sample interval [s].
    channels, trusted : tuple of str
    noise : float
        Measurement noise std of every channel [unit].
    noise_rho : float
        AR(1) coefficient of the coloured channels' noise per sample (0: white).
    coloured : tuple of str, optional
        Channels with AR(1) noise (default: every channel not in ``trusted``).
    covariate_lag : float, optional
        First-order lag between the recorded covariate and the one the bias
        follows [s].
    seed : int, optional

    Returns
    -------
    dict
        ``t`` (n,) [s], ``y`` (S, m, n), ``signal`` (S, n), ``bias`` (S, m,
        n) total bias of each channel, ``covariate`` (S, n) or None (as
        recorded), ``covariate_lagged`` (what the bias follows), and the
        scalars used.
    """
    rng = np.random.default_rng(seed)
    S, m = int(n_series), len(channels)
    t = np.arange(n) * dt
    if signal == "random_walk":
        steps = rng.normal(0.0, signal_level * math.sqrt(dt), (S, n))
        steps[:, 0] = rng.normal(0.0, 1.0, S)
        sig = np.cumsum(steps, axis=1)
    elif signal == "gauss_markov":
        a = math.exp(-dt / signal_tau)
        e = rng.normal(0.0, signal_level * math.sqrt(1 - a * a), (S, n))
        sig = np.empty((S, n))
        sig[:, 0] = rng.normal(0.0, signal_level, S)
        for k in range(1, n):
            sig[:, k] = a * sig[:, k - 1] + e[:, k]
        sig += signal_mean
    elif signal == "known":
        sig = np.full((S, n), float(signal_mean))
    else:
        raise ValueError(f"unknown signal model {signal!r}")
    b = np.zeros((S, m, n))
    cov = None
    if covariate_coefficient is not None:
        walk = np.cumsum(rng.normal(0.0, 0.1 * math.sqrt(dt), (S, n)), axis=1)
        phase = rng.uniform(-math.pi, math.pi, (S, 1))
        cov = 20.0 + 3.0 * np.sin(2 * math.pi * t / t[-1] + phase) + walk
    cov_b = cov
    if cov is not None and covariate_lag:
        # Exact first-order lag of a piecewise-linear input, started in equilibrium.
        a = math.exp(-dt / covariate_lag)
        cov_b = np.empty_like(cov)
        cov_b[:, 0] = cov[:, 0]
        g = 1.0 - covariate_lag / dt * (1.0 - a)
        for k in range(1, n):
            cov_b[:, k] = a * cov_b[:, k - 1] + (1.0 - a - g) * cov[:, k - 1] + g * cov[:, k]
    for i, c in enumerate(channels):
        if c in trusted:
            continue
        if bias == "random_walk":
            b[:, i] = np.cumsum(rng.normal(0.0, bias_rate * math.sqrt(dt), (S, n)), axis=1)
            b[:, i] -= b[:, i, :1]
        elif bias == "ramp":
            t_on = t[-1] * 0.5 if ramp_start is None else ramp_start
            b[:, i] = np.where(t >= t_on, ramp_slope * (t - t_on), 0.0)
        elif bias != "none":
            raise ValueError(f"unknown bias model {bias!r}")
        if cov is not None:
            b[:, i] += covariate_coefficient * (cov_b - covariate_reference) + covariate_offset
    v = rng.normal(0.0, noise, (S, m, n))
    if noise_rho:
        col = [i for i, c in enumerate(channels) if c in (coloured if coloured is not None else
                                                             tuple(x for x in channels if x not in trusted))]
        e = v[:, col] * math.sqrt(1.0 - noise_rho**2)
        for k in range(1, n):
            e[:, :, k] += noise_rho * e[:, :, k - 1]
        # e_0 ~ N(0, noise^2 (1 - rho^2)) so far: start it in the stationary distribution.
        v[:, col] = e + (v[:, col, :1] - e[:, :, :1]) * noise_rho ** np.arange(n)
    y = sig[:, None, :] + b + v
    return {"t": t, "y": y, "signal": sig, "bias": b, "covariate": cov, "noise": noise, "dt": dt,
            "channels": tuple(channels), "trusted": tuple(trusted), "signal_kind": signal,
            "signal_level": signal_level, "signal_tau": signal_tau, "signal_mean": signal_mean, "bias_kind": bias,
            "bias_rate": bias_rate, "ramp_slope": ramp_slope, "covariate_coefficient": covariate_coefficient,
            "covariate_reference": covariate_reference, "covariate_lagged": cov_b, "noise_rho": noise_rho,
            "covariate_lag": covariate_lag}
