"""Figure of a shock calibration: sensitivity per pulse against its peak, and each pulse's transfer function."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from senscal.report.plots import new_figure

__all__ = ["shock_figure"]


def shock_figure(pulses: Sequence, unit: str = "", labels: Sequence[str] = ()):
    """Two panels: the peak-ratio sensitivity against the peak acceleration, and ``|H(f)|`` per pulse.

    Parameters
    ----------
    pulses : sequence of senscal.shock.ShockPulse
    unit : str
        Sensitivity unit (output per m/s^2), for the axis labels.
    labels : sequence of str, optional
        A label per pulse for the legend of the transfer functions (default ``pulse i``).

    Returns
    -------
    matplotlib.figure.Figure
        Bars are U (k=2).
    """
    fig, ax = new_figure(2, 1, width=7.0, height=5.2, squeeze=False)
    ax = ax[:, 0]
    peak = np.abs([p.peak_acceleration for p in pulses])
    s = np.array([p.sensitivity for p in pulses], float)
    us = np.array([p.u_sensitivity for p in pulses], float)
    ax[0].errorbar(peak, s, yerr=2 * us, fmt="o", color="C0", capsize=3, ms=4)
    if peak.size and peak.max() > 10 * peak.min():
        ax[0].set_xscale("log")  # peaks over decades (ISO 16063-22 asks for several); else a linear axis reads better
    ax[0].set_xlabel("peak acceleration (m/s²)")
    ax[0].set_ylabel(f"shock sensitivity ({unit})" if unit else "shock sensitivity")
    ax[0].set_title("Peak ratio per pulse (bars: U, k=2)")
    ax[0].grid(True, which="both", alpha=0.3)
    for i, p in enumerate(pulses):
        tf = p.transfer_function
        lab = labels[i] if i < len(labels) else f"pulse {i}"
        ax[1].errorbar(np.asarray(tf.frequency_hz), np.asarray(tf.magnitude), yerr=2 * np.asarray(tf.u_magnitude),
                       fmt="o-", ms=3, capsize=2, color=f"C{i % 10}", label=f"{lab}, {p.duration_ms:.3g} ms")
    ax[1].set_xscale("log")
    ax[1].set_xlabel("frequency (Hz)")
    ax[1].set_ylabel(f"|H(f)| ({unit})" if unit else "|H(f)|")
    ax[1].set_title("Transfer function from each pulse's spectra (bars: U, k=2)")
    ax[1].grid(True, which="both", alpha=0.3)
    if len(pulses) <= 10:
        ax[1].legend(loc="best", fontsize="small")
    # plain tick labels on the log axes: the default ones are TeX, which the certificate's literal text shows raw
    from matplotlib.ticker import FuncFormatter, NullFormatter

    for a in ax:
        if a.get_xscale() != "log":
            continue
        a.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        a.xaxis.set_minor_formatter(NullFormatter())
    return fig
