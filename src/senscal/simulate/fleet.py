"""Simulator: a fleet of drifting sensors written as a Parquet dataset, block by block.

The dataset is a folder of Parquet files, one per block of channels, each
with a time column ``t`` [s] and one float column per channel (and, for the
``covariate`` kind, one ``<channel>.temperature`` column per channel [degC]).
Every file is cut into row groups of ``rows_per_group`` samples: the unit a
fleet run reads at once.  Nothing larger than one row group of one file is
ever held in memory, so datasets far larger than RAM can be written.

Two kinds, matching the two fleet set-ups of :mod:`senscal.drift.fleet`:

``known``
    Sensors whose true reading is zero (a gyro at rest, a thermometer in a
    reference bath): ``y = b_t + v_t`` with ``b`` a random walk of rate
    ``bias_rate`` [unit/sqrt(s)] and white noise ``noise`` [unit].
``covariate``
    A sensor of a slowly varying quantity (random walk of rate
    ``signal_rate``) whose bias is ``alpha_t (c_t - reference)`` with ``c``
    its own temperature (daily cycle, 20 degC +- 6 degC, plus weather) and
    ``alpha`` a random walk of rate ``coefficient_rate`` [unit/degC/sqrt(s)].
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from senscal.errors import InputError

__all__ = ["simulate_fleet", "FLEET_KINDS", "TEMPERATURE_REFERENCE"]

FLEET_KINDS = ("known", "covariate")
#: Temperature of zero covariate-linked bias in the ``covariate`` kind [degC].
TEMPERATURE_REFERENCE = 20.0
_DAY = 86400.0


def _fleet_config(kind: str, noise: float, bias_rate: float, signal_rate: float, coefficient_rate: float) -> dict:
    """The fleet configuration (set-up and true noise levels) of the simulated kind."""
    if kind == "known":
        setup = {"preset": "known", "value": 0.0}
        levels = {"y_noise_std": noise, "y_bias_rate_std": bias_rate}
    else:
        setup = {"preset": "covariate", "covariate": "temperature", "reference": TEMPERATURE_REFERENCE}
        levels = {"y_noise_std": noise, "signal_rate_std": signal_rate,
                  "y_temperature_coefficient_rate_std": coefficient_rate}
    group = {"name": kind, "channels": "*", "setup": setup, "levels": levels}
    if kind == "known":
        # One prior width for every channel (about the data's spread), so they share their covariance.
        group["prior_scale"] = noise
    return {"groups": [group]}


def simulate_fleet(out: str | Path, *, n_channels: int = 20, n_samples: int = 2000, fs: float = 1.0,
                   kind: str = "known", segments: int = 1, channels_per_file: int = 500,
                   rows_per_group: int = 3600, noise: float = 0.05, bias_rate: float = 2e-4,
                   signal_rate: float = 1e-3, coefficient_rate: float = 2e-5, missing: float = 0.0,
                   dtype: str = "float64", seed: int | None = 0) -> dict[str, Any]:
    """Write a fleet of drifting sensors as Parquet files with known truth.

    Parameters
    ----------
    out : path
        Folder to write.  With ``segments`` = 1 the Parquet files go straight
        in it; otherwise into ``out/seg-000``, ``out/seg-001``, ... which cover
        consecutive stretches of time (one file a day, say): the random
        walks continue from one segment to the next.
    n_channels : int
        Sensors.
    n_samples : int
        Samples per channel over all segments.
    fs : float
        Sample rate [Hz].
    kind : {"known", "covariate"}
        See the module docstring.
    segments : int
        Consecutive datasets the samples are split into.
    channels_per_file : int
        Channels per Parquet file.
    rows_per_group : int
        Samples per Parquet row group.
    noise : float
        White measurement noise std [unit].
    bias_rate : float
        Random-walk rate of the bias (``known``) [unit/sqrt(s)].
    signal_rate : float
        Random-walk rate of the measured quantity (``covariate``) [unit/sqrt(s)].
    coefficient_rate : float
        Random-walk rate of the temperature coefficient (``covariate``)
        [unit/degC/sqrt(s)].
    missing : float
        Fraction of samples set to NaN (missing), at random [1].
    dtype : {"float64", "float32"}
        Storage type of the channels (time is always float64).
    seed : int, optional

    Returns
    -------
    dict
        Truth: the arguments, ``channels``, ``config`` (the fleet
        configuration with the true levels, also written to
        ``out/fleet.json``), ``final_bias`` (per channel, the true bias at
        the last sample [unit]; for ``covariate`` the coefficient times the
        last true temperature offset) and ``segments`` (their folders).
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from senscal.io.guard import atomic_output, check_output_dir, write_text

    if kind not in FLEET_KINDS:
        raise InputError(f"fleet kind must be one of {', '.join(FLEET_KINDS)}, got {kind!r}")
    for name, v in (("n_channels", n_channels), ("n_samples", n_samples), ("segments", segments),
                    ("channels_per_file", channels_per_file), ("rows_per_group", rows_per_group)):
        if int(v) != v or v < 1:
            raise InputError(f"{name} must be a whole number >= 1, got {v}")
    if segments > n_samples:
        raise InputError(f"cannot split {n_samples} samples into {segments} segments")
    if not (math.isfinite(fs) and fs > 0):
        raise InputError(f"the sample rate must be > 0 Hz, got {fs}")
    if not 0.0 <= missing < 1.0:
        raise InputError(f"the missing fraction must lie in [0, 1), got {missing}")
    if dtype not in ("float64", "float32"):
        raise InputError(f"dtype must be float64 or float32, got {dtype!r}")
    out = check_output_dir(Path(out), what="fleet dataset folder")
    rng = np.random.default_rng(seed)
    width = max(5, len(str(n_channels - 1)))
    channels = [f"s{i:0{width}d}" for i in range(n_channels)]
    dt = 1.0 / fs
    bounds = np.linspace(0, n_samples, segments + 1).round().astype(int)
    seg_dirs = [out] if segments == 1 else [check_output_dir(out / f"seg-{k:03d}") for k in range(segments)]
    final = {}
    for f0 in range(0, n_channels, channels_per_file):
        names = channels[f0:f0 + channels_per_file]
        C = len(names)
        # Per-channel phases and walk states carried across row groups and segments.
        phase = rng.uniform(0, 2 * math.pi, C)
        walk_b = np.zeros(C)
        walk_s = np.zeros(C)
        weather = np.zeros(C)
        temp_last = np.full(C, TEMPERATURE_REFERENCE)
        for k, folder in enumerate(seg_dirs):
            path = folder / f"part-{f0 // channels_per_file:05d}.parquet"
            fields = [pa.field("t", pa.float64())] + [pa.field(c, pa.from_numpy_dtype(np.dtype(dtype))) for c in names]
            if kind == "covariate":
                fields += [pa.field(f"{c}.temperature", pa.float64()) for c in names]
            schema = pa.schema(fields)
            with atomic_output(path, what="fleet dataset file") as tmp:
                with pq.ParquetWriter(tmp, schema, compression="none") as writer:
                    for r0 in range(bounds[k], bounds[k + 1], rows_per_group):
                        r1 = min(r0 + rows_per_group, bounds[k + 1])
                        T = r1 - r0
                        t = np.arange(r0, r1) * dt
                        steps = rng.normal(0.0, math.sqrt(dt), (C, T))
                        if r0 == 0:
                            steps[:, 0] = 0.0  # the walks start at zero at t = 0
                        cols: dict[str, np.ndarray] = {"t": t}
                        if kind == "known":
                            b = walk_b[:, None] + np.cumsum(bias_rate * steps, axis=1)
                            walk_b = b[:, -1].copy()
                            y = b + rng.normal(0.0, noise, (C, T))
                            final_b = b[:, -1]
                        else:
                            s = walk_s[:, None] + np.cumsum(signal_rate * steps, axis=1)
                            walk_s = s[:, -1].copy()
                            steps2 = rng.normal(0.0, math.sqrt(dt), (C, T))
                            if r0 == 0:
                                steps2[:, 0] = 0.0
                            a = walk_b[:, None] + np.cumsum(coefficient_rate * steps2, axis=1)
                            walk_b = a[:, -1].copy()
                            w = weather[:, None] + np.cumsum(rng.normal(0.0, math.sqrt(dt / _DAY), (C, T)), axis=1)
                            weather = w[:, -1].copy()
                            temp = (TEMPERATURE_REFERENCE + 6.0 * np.sin(2 * math.pi * t / _DAY + phase[:, None]) + w)
                            temp_last = temp[:, -1].copy()
                            y = s + a * (temp - TEMPERATURE_REFERENCE) + rng.normal(0.0, noise, (C, T))
                            final_b = a[:, -1] * (temp_last - TEMPERATURE_REFERENCE)
                            for i, c in enumerate(names):
                                cols[f"{c}.temperature"] = temp[i]
                        if missing > 0:
                            y[rng.random(y.shape) < missing] = np.nan
                        for i, c in enumerate(names):
                            cols[c] = y[i].astype(dtype)
                        writer.write_table(pa.table(cols, schema=schema))
        final.update({c: float(v) for c, v in zip(names, final_b)})
    config = _fleet_config(kind, noise, bias_rate, signal_rate, coefficient_rate)
    write_text(out / "fleet.json", json.dumps(config, indent=2) + "\n", what="fleet configuration")
    return {"kind": kind, "n_channels": n_channels, "n_samples": n_samples, "fs": fs,
            "segments": [str(d) for d in seg_dirs],
            "noise": noise, "bias_rate": bias_rate, "signal_rate": signal_rate, "coefficient_rate": coefficient_rate,
            "channels": channels, "config": config, "final_bias": final, "seed": seed}
