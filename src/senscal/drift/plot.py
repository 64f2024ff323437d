"""Plot of a drift correction: raw, corrected, truth, bias estimate with its band."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from senscal.drift.core import DriftResult
from senscal.report.plots import new_figure, save_figure

__all__ = ["plot_drift"]


def plot_drift(res: DriftResult, raw: Mapping[str, np.ndarray], path: str | Path, *,
               truth_signal: np.ndarray | None = None, truth_bias: Mapping[str, np.ndarray] | None = None,
               time_unit: str = "auto", unit: str = "") -> Path:
    """Two panels per corrected channel, saved to ``path``.

    Top: raw and corrected measurement (and the true quantity when known).
    Bottom: the bias estimate with its expanded (k=2) band, the true bias
    when known, and the detected onset.

    Parameters
    ----------
    res : DriftResult
    raw : mapping of channel to ndarray (T,)
        The measurements before correction [unit].
    path : str or Path
        Output image (.png, .svg, .pdf).
    truth_signal : ndarray (T,), optional
        The true quantity (simulations).
    truth_bias : mapping of channel to ndarray (T,), optional
        The true biases (simulations).
    time_unit : {"auto", "s", "h", "day"}
    unit : str
        Measurement unit for the axis labels.

    Returns
    -------
    Path
    """
    t = res.t - res.t[0]
    span = t[-1] if t.size else 1.0
    if time_unit == "auto":
        time_unit = "day" if span >= 3 * 86400 else ("h" if span >= 3 * 3600 else "s")
    div = {"s": 1.0, "h": 3600.0, "day": 86400.0}[time_unit]
    tx = t / div
    k = len(res.channels)
    fig, axes = new_figure(2 * k, 1, height=3.2 * k + 1.0, sharex=True, squeeze=False)
    axes = axes[:, 0]
    u = f" ({unit})" if unit else ""
    for i, c in enumerate(res.channels):
        a, b = axes[2 * i], axes[2 * i + 1]
        a.plot(tx, raw[c], lw=0.6, color="0.6", label=f"{c} raw")
        a.plot(tx, res.corrected[i], lw=0.6, color="C0", label=f"{c} corrected")
        if truth_signal is not None:
            a.plot(tx, truth_signal, lw=1.0, color="k", ls="--", label="truth")
        a.set_ylabel(f"{c}{u}")
        a.legend(loc="upper left", fontsize=8, ncol=3)
        lo = res.bias[i] - 2 * res.bias_std[i]
        hi = res.bias[i] + 2 * res.bias_std[i]
        b.fill_between(tx, lo, hi, color="C1", alpha=0.3, lw=0, label="bias ±2σ (k=2)")
        b.plot(tx, res.bias[i], color="C1", lw=1.0, label=f"bias estimate ({res.method})")
        if truth_bias is not None and c in truth_bias:
            b.plot(tx, truth_bias[c], color="k", ls="--", lw=1.0, label="true bias")
        if res.onset_t.get(c) is not None:
            b.axvline((res.onset_t[c] - res.t[0]) / div, color="C3", lw=1.0, ls=":", label="detected onset")
        b.set_ylabel(f"{c} bias{u}")
        # The first samples' band reflects the vague prior; keep the scale on the data.
        settle = min(len(tx) - 1, max(1, len(tx) // 50))
        rng_lo = np.nanmin(lo[settle:]) if np.isfinite(lo[settle:]).any() else None
        rng_hi = np.nanmax(hi[settle:]) if np.isfinite(hi[settle:]).any() else None
        if rng_lo is not None and rng_hi is not None and rng_hi > rng_lo:
            pad = 0.15 * (rng_hi - rng_lo)
            b.set_ylim(rng_lo - pad, rng_hi + pad)
        b.legend(loc="upper left", fontsize=8, ncol=4)
    axes[-1].set_xlabel(f"time ({time_unit})")
    return save_figure(fig, path)
