"""A noisy multi-channel sine recording with known truth."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from senscal.io import Recording

__all__ = ["simulate_sine", "ar1_noise", "flicker_noise", "adc", "jittered_times"]


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


def flicker_noise(rng: np.random.Generator, shape: tuple[int, ...], level: float, fs: float,
                  span: int = 8) -> np.ndarray:
    """Gaussian 1/f (flicker) noise along the last axis.

    One-sided power spectral density ``S(f) = level^2 * (1 Hz / f)`` from
    ``fs / (span N)`` to ``fs / 2``: white Gaussian noise of ``span`` times the
    record length shaped by ``1/sqrt(f)`` in the frequency domain, of which
    the first ``N`` samples are kept (so the record holds the noise below
    ``1/T`` that makes its mean wander, as a real 1/f source does).

    Parameters
    ----------
    rng : numpy.random.Generator
    shape : tuple of int
        Output shape; samples along the last axis.
    level : float
        Amplitude spectral density at 1 Hz, in unit/sqrt(Hz) (0: no noise).
    fs : float
        Sample rate in Hz.
    span : int
        Length of the generated record in records (lowest frequency ``fs / (span N)``).

    Returns
    -------
    ndarray
    """
    n = int(shape[-1])
    if level == 0.0:
        return np.zeros(shape)
    m = span * n
    f = np.fft.rfftfreq(m, 1.0 / fs)
    gain = np.zeros_like(f)
    gain[1:] = level * np.sqrt(fs / 2.0 / f[1:])   # |X_k| = W_k sqrt(S(f_k) fs / 2): unit-variance W
    w = np.fft.rfft(rng.normal(size=tuple(shape[:-1]) + (m,)), axis=-1)
    return np.fft.irfft(w * gain, m, axis=-1)[..., :n]


def jittered_times(rng: np.random.Generator, t: np.ndarray, shape: tuple[int, ...], jitter: float) -> np.ndarray:
    """Instants at which a jittered sample clock really sampled: ``t + delta``, delta ~ N(0, jitter^2).

    The recording keeps the nominal stamps ``t``; the signal is evaluated at
    these instants (sample-clock or aperture jitter, independent per sample).

    Parameters
    ----------
    rng : numpy.random.Generator
    t : ndarray, shape (N,)
        Nominal time stamps in s.
    shape : tuple of int
        Output shape (..., N).
    jitter : float
        RMS timing error in s.
    """
    base = np.broadcast_to(np.asarray(t, dtype=float), shape)
    return base + rng.normal(0.0, jitter, shape) if jitter > 0 else np.array(base)


def adc(y: np.ndarray, *, clip=None, lsb: float | None = None) -> np.ndarray:
    """What an analogue-to-digital converter makes of a signal: clipped to its range, then quantised.

    Parameters
    ----------
    y : ndarray
        The analogue signal (unit of the channel).
    clip : float or (float, float), optional
        Input range: ``+/-clip`` or ``(low, high)``; samples beyond it read
        the range's end (the ADC saturates).  None: no clipping.
    lsb : float, optional
        Quantisation step (one least significant bit, unit of the channel):
        every sample is rounded to the nearest multiple of it.  None: no
        quantisation.

    Returns
    -------
    ndarray
    """
    out = np.asarray(y, dtype=float)
    if clip is not None:
        lo, hi = (-float(clip), float(clip)) if np.ndim(clip) == 0 else (float(clip[0]), float(clip[1]))
        out = np.clip(out, lo, hi)
    if lsb is not None and lsb > 0:
        out = lsb * np.round(out / lsb)
    return out



def simulate_sine(*, n_channels: int = 4, fs: float = 1000.0, duration: float = 2.0, frequency: float = 12.5,
                  noise: float = 0.05, t0: float = 0.0, noise_rho: float = 0.0, clip=None,
                  lsb: float | None = None, jitter: float = 0.0, flicker: float = 0.0,
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
    clip : float or (float, float), optional
        Departure: the ADC's input range, ``+/-clip`` or ``(low, high)`` in
        the channel's unit; samples beyond it read the range's end (clipped
        crests).  None (default): no clipping.
    lsb : float, optional
        Departure: ADC quantisation step in the channel's unit (e.g.
        ``2 * full_scale / 2**bits``); samples are rounded to multiples of it
        after clipping.  With ``noise`` below about 0.3 LSB the ADC is
        under-dithered.  None (default): no quantisation.
    jitter : float
        Departure: RMS sample-clock (aperture) jitter in s; each sample is
        taken at ``t + delta``, ``delta ~ N(0, jitter^2)``, but stamped ``t``.
    flicker : float
        Departure: 1/f noise added to the white noise, amplitude spectral
        density at 1 Hz in unit/sqrt(Hz) (one-sided PSD ``flicker^2 / f``).
    seed : int, optional
        Random seed.

    Returns
    -------
    recording : Recording
    truth : dict
        ``{"frequency_hz", "noise_std", "noise_rho", "channels": {name: {"amplitude", "phase_deg", "offset"}}}``,
        plus ``clip``, ``lsb``, ``jitter_s``, ``flicker`` when those departures are on.
    """
    if not -1.0 < noise_rho < 1.0:
        from senscal.errors import InputError

        raise InputError(f"noise_rho must lie strictly between -1 and 1 (stationary AR(1) noise), got {noise_rho!r}")
    for nm, v in (("lsb", lsb), ("jitter", jitter), ("flicker", flicker)):
        if v is not None and not (math.isfinite(v) and v >= 0):
            from senscal.errors import InputError

            raise InputError(f"{nm} must be a finite number >= 0, got {v!r}")
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
        ts = jittered_times(rng, t, (n,), jitter)
        y = amp * np.sin(2 * math.pi * frequency * ts + ph) + off + ar1_noise(rng, (n,), noise, noise_rho)
        if flicker:
            y = y + flicker_noise(rng, (n,), flicker, fs)
        chans[name] = adc(y, clip=clip, lsb=lsb)
        truth_ch[name] = {"amplitude": amp, "phase_deg": math.degrees(ph), "offset": off}
    rec = Recording(channels=chans, t=t, units={k: "V" for k in chans}, metadata={"simulator": "sine"})
    truth = {"frequency_hz": frequency, "noise_std": noise, "noise_rho": noise_rho, "channels": truth_ch}
    for key, v in (("clip", clip), ("lsb", lsb), ("jitter_s", jitter or None), ("flicker", flicker or None)):
        if v is not None:
            truth[key] = v
    return rec, truth
