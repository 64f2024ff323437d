"""Plots of a three-axis calibration: sphere projections and norm error."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from senscal.report.plots import new_figure, save_figure
from senscal.triaxial.calibrate import nominal_raw

__all__ = ["plot_calibration", "plot_heading"]


def plot_calibration(h_raw: np.ndarray, h_corrected: np.ndarray, field: float, path: str | Path, *,
                     unit: str = "", title: str = "") -> Path:
    """Raw and corrected points on the sphere (three projections) and |H| - F against sample index.

    Parameters
    ----------
    h_raw, h_corrected : ndarray, shape (3, N)
        Readings before and after correction (sensor and field units).
    field : float
        Field magnitude (field units): the circle drawn and the reference of the error.
    path : str or Path
        Output image (.png, .svg, .pdf).

    Returns
    -------
    Path
    """
    raw, note = nominal_raw(h_raw, field)
    fig, axes = new_figure(2, 3, width=11.0, height=7.0)
    gs = axes[1, 0].get_gridspec()
    for a in axes[1]:
        a.remove()
    axn = fig.add_subplot(gs[1, :])
    th = np.linspace(0, 2 * np.pi, 200)
    for a, (p, q) in zip(axes[0], ((0, 1), (0, 2), (1, 2))):
        a.plot(raw[p], raw[q], ".", ms=2.5, alpha=0.6, label="raw" + (" (nominal conversion)" if note else ""))
        a.plot(h_corrected[p], h_corrected[q], ".", ms=2.5, alpha=0.6, label="corrected")
        a.plot(field * np.cos(th), field * np.sin(th), "k-", lw=0.6, label="|H| = F")
        a.set_aspect("equal", adjustable="datalim")
        a.locator_params(nbins=4)
        a.set_xlabel(f"{'XYZ'[p]} ({unit})" if unit else "XYZ"[p])
        a.set_ylabel(f"{'XYZ'[q]} ({unit})" if unit else "XYZ"[q])
    axes[0, 0].legend(loc="upper right", fontsize=7)
    idx = np.arange(raw.shape[1])
    axn.plot(idx, 100 * (np.linalg.norm(raw, axis=0) - field) / field, ".-", ms=3, lw=0.5, label="before")
    axn.plot(idx, 100 * (np.linalg.norm(h_corrected, axis=0) - field) / field, ".-", ms=3, lw=0.5, label="after")
    axn.axhline(0, color="k", lw=0.5)
    axn.set_xlabel("sample index")
    axn.set_ylabel("|H| - F (% of F)")
    axn.legend(loc="upper right")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def plot_heading(report: dict, path: str | Path, *, title: str = "") -> Path:
    """Heading deviation before calibration and its k=2 uncertainty after, against calibrated heading.

    Parameters
    ----------
    report : dict
        :func:`senscal.triaxial.heading.heading_report` output (with per-reading arrays).
    path : str or Path
        Output image.

    Returns
    -------
    Path
    """
    psi = np.asarray(report["heading_deg"])
    dev = np.asarray(report["deviation_before_deg"]["per_reading"])
    order = np.argsort(psi)
    fig, ax = new_figure(1, 1, width=7.5, height=4.0)
    ax.plot(psi[order], dev[order], ".", ms=2, label="before: raw heading minus calibrated")
    if "U_after_deg" in report:
        u = np.asarray(report["U_after_deg"]["per_reading"])
        ax.fill_between(psi[order], -u[order], u[order], color="C1", alpha=0.4,
                        label="after: calibrated heading, U (k=2)")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("calibrated heading (deg)")
    ax.set_ylabel("heading error (deg)")
    ax.set_xlim(0, 360)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title)
    return save_figure(fig, path)
