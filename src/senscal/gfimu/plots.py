"""Plots of the array's angular-velocity estimates (edge code: matplotlib only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from senscal.report.plots import new_figure, save_figure

__all__ = ["plot_rates"]

_COLORS = {"integration": "tab:orange", "sqrt": "tab:green", "differential": "tab:purple", "kalman": "tab:blue"}
_ORDER = ["differential", "sqrt", "integration", "kalman"]
_MAX_POINTS = 20000


def plot_rates(t: np.ndarray, omega: dict, path: str | Path, *, truth: np.ndarray | None = None,
               title: str = "") -> Path:
    """Angular velocity per axis and method; with a truth, their errors over time.

    Absolute errors are drawn on a log axis so that the drift of the
    integration method, the near-zero failures of the square root and the
    gross errors of the differential method show beside the filter's.
    """
    step = max(1, t.size // _MAX_POINTS)
    ts = t[::step]
    ncol = 1 if truth is None else 2
    fig, ax = new_figure(3, ncol, width=6.0 * ncol, height=7.0, sharex=True, squeeze=False)
    for i, axis in enumerate("xyz"):
        a = ax[i, 0]
        # The noisiest methods first, so the better ones stay visible on top.
        lim = 1.5 * max(float(np.max(np.abs(truth[i]))), 0.1) if truth is not None else None
        off_scale = []
        for name in sorted(omega, key=_ORDER.index):
            # A method whose typical error exceeds the plotted range would
            # paint over the others: name it instead (its errors are on the right).
            if lim is not None and np.nanpercentile(np.abs(omega[name][i] - truth[i]), 90) > 0.5 * lim:
                off_scale.append(name)
                continue
            a.plot(ts, omega[name][i, ::step], lw=0.8, color=_COLORS.get(name), label=name)
        if truth is not None:
            a.plot(ts, truth[i, ::step], color="k", lw=0.8, ls="--", label="truth")
        if off_scale:
            a.text(0.01, 0.03, "off scale: " + ", ".join(off_scale), transform=a.transAxes, fontsize=7)
        a.set_ylabel(f"w{axis} (rad/s)")
        if lim is not None:
            a.set_ylim(-lim, lim)
        if truth is not None:
            b = ax[i, 1]
            # Moving RMS of the error: sample-to-sample scatter would hide the trend.
            win = max(1, t.size // 400)
            box = np.ones(win) / win
            for name in sorted(omega, key=_ORDER.index):
                err2 = np.nan_to_num((omega[name][i] - truth[i]) ** 2, nan=0.0)
                rms = np.sqrt(np.convolve(err2, box, mode="same"))
                b.plot(ts, rms[::step], lw=0.9, color=_COLORS.get(name), label=name)
            b.set_yscale("log")
            b.set_ylabel(f"moving RMS error w{axis} (rad/s)")
            b.grid(True, alpha=0.3)
    ax[0, 0].legend(loc="upper right", fontsize=7)
    if truth is not None:
        ax[0, 1].set_title(f"error, moving RMS over {max(1, t.size // 400)} samples (log scale)", fontsize=9)
        ax[0, 1].legend(loc="upper right", fontsize=7)
    for j in range(ncol):
        ax[2, j].set_xlabel("t (s)")
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)
