"""Plot of an IMU calibration: |f| - g per pose and gravity-direction residual per rotation, before/after."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from senscal.report.plots import new_figure, save_figure

__all__ = ["plot_imu", "imu_figure"]


def plot_imu(g_before: np.ndarray, g_after: np.ndarray, dir_before: np.ndarray, dir_after: np.ndarray,
             path: str | Path, *, temperature: np.ndarray | None = None, temp_unit: str = "",
             title: str = "") -> Path:
    """Two panels (three with temperature): accelerometer and gyroscope residuals before and after.

    Parameters
    ----------
    g_before, g_after : ndarray, shape (K,)
        ``|f| - g`` per static pose, m/s^2, with the nominal accelerometer and calibrated.
    dir_before, dir_after : ndarray, shape (K-1,)
        Angle between the gravity direction predicted at the next pose and the one measured, deg, with the
        nominal gyro and calibrated.
    path : str or Path
        Output image (.png, .svg, .pdf).
    temperature : ndarray, shape (K,), optional
        Pose temperatures: a third panel.
    """
    return save_figure(imu_figure(g_before, g_after, dir_before, dir_after, temperature=temperature,
                                  temp_unit=temp_unit, title=title), path)


def imu_figure(g_before: np.ndarray, g_after: np.ndarray, dir_before: np.ndarray, dir_after: np.ndarray, *,
               temperature: np.ndarray | None = None, temp_unit: str = "", title: str = ""):
    """The figure of :func:`plot_imu` (also the certificate's), not saved."""
    n = 3 if temperature is not None else 2
    fig, axes = new_figure(n, 1, width=8.5, height=2.9 * n)
    k = np.arange(1, g_after.size + 1)
    ax = axes[0]
    ax.plot(k, g_before, "o", ms=4, color="0.6", label=f"nominal (std {np.std(g_before, ddof=1):.3g})")
    ax.plot(k, g_after, "o", ms=4, color="C0", label=f"calibrated (std {np.std(g_after, ddof=1):.3g})")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("static pose")
    ax.set_ylabel("|f| - g (m/s²)")
    ax.set_title("accelerometer: magnitude of the pose means")
    ax.legend(loc="best", fontsize=8)
    ax = axes[1]
    r = np.arange(1, dir_after.size + 1)
    rms_b, rms_a = (float(np.sqrt(np.mean(x ** 2))) for x in (dir_before, dir_after))
    ax.semilogy(r, np.maximum(dir_before, 1e-6), "s", ms=4, color="0.6", label=f"nominal gyro (rms {rms_b:.3g}°)")
    ax.semilogy(r, np.maximum(dir_after, 1e-6), "s", ms=4, color="C1", label=f"calibrated (rms {rms_a:.3g}°)")
    ax.set_xlabel("rotation (pose k to k+1)")
    ax.set_ylabel("gravity-direction error (°)")
    ax.set_title("gyroscope: gravity direction predicted at the next pose")
    ax.legend(loc="best", fontsize=8)
    if temperature is not None:
        ax = axes[2]
        ax.plot(k, temperature, "o-", ms=3, color="C3")
        ax.set_xlabel("static pose")
        ax.set_ylabel(f"temperature ({temp_unit or 'channel unit'})")
        ax.set_title("pose temperature")
    if title:
        fig.suptitle(title)
    return fig
