"""Before/after plots of the gravity compensation (matplotlib, no pyplot)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from senscal.report.plots import new_figure, save_figure
from senscal.shaft.model import GravityModel

__all__ = ["plot_compensation"]

MAX_POINTS = 6000


def plot_compensation(path: str | Path, model: GravityModel, angle: np.ndarray, before: np.ndarray,
                      after: np.ndarray, *, unit: str = "", after_unit: str = "m/s^2", title: str = "",
                      t: np.ndarray | None = None, alphas: dict[str, np.ndarray] | None = None) -> Path:
    """Accelerometer against the shaft angle before and after removing gravity (the paper's figure 4).

    Parameters
    ----------
    path : path
        Output image (.png, .svg, .pdf).
    model : GravityModel
        The identified gravity term, drawn over the raw signal.
    angle : ndarray
        Unwrapped angle, rad.
    before : ndarray
        Raw accelerometer output (``unit``).
    after : ndarray
        Compensated signal (``after_unit``).
    t : ndarray, optional
        Time (s) for a third panel of angular accelerations.
    alphas : dict of str to ndarray, optional
        Angular acceleration series (rad/s^2) drawn against ``t``.
    """
    rows = 3 if (t is not None and alphas) else 2
    fig, ax = new_figure(rows, 1, height=2.6 * rows)
    step = max(1, angle.size // MAX_POINTS)
    deg = np.degrees(np.mod(angle, 2 * math.pi))[::step]
    ax[0].plot(deg, before[::step], ".", ms=1.5, alpha=0.5, label="accelerometer (before)")
    grid = np.linspace(0.0, 2 * math.pi, 361)
    ax[0].plot(np.degrees(grid), model.gravity(grid), "-", color="C3", lw=1.5,
               label=f"gravity fit: {model.amplitude:.4g} sin(theta {math.degrees(model.phase):+.4g} deg) "
                     f"{model.offset:+.3g}")
    ax[0].set_ylabel(f"output ({unit})" if unit else "output")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[1].plot(deg, after[::step], ".", ms=1.5, alpha=0.5, color="C2", label="after gravity compensation")
    ax[1].set_ylabel(f"tangential ({after_unit})")
    ax[1].set_xlabel("shaft angle (deg)")
    ax[1].legend(loc="upper right", fontsize=8)
    for a in ax[:2]:
        a.set_xlim(0, 360)
        a.set_xticks(range(0, 361, 45))
    if rows == 3:
        for i, (name, series) in enumerate(alphas.items()):
            ax[2].plot(t, series, lw=0.8 if i else 0.6, label=name)
        ax[2].set_xlabel("t (s)")
        ax[2].set_ylabel("angular acc. (rad/s^2)")
        ax[2].legend(loc="upper right", fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)
