"""Plot of a calibration history: values with expanded-uncertainty bars, drift line, tolerance, due date."""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path
from typing import Sequence

import numpy as np

from senscal.registry.drift import DAYS_PER_YEAR
from senscal.registry.store import DriftReport, HistoryPoint
from senscal.report.plots import new_figure, save_figure

__all__ = ["plot_history", "history_figure"]


def _literal(text: str) -> str:
    """User text shown as typed: a '$' would start matplotlib mathtext (and a lone one crashes it)."""
    return str(text).replace("$", r"\$")


def plot_history(points: Sequence[HistoryPoint], path: str | Path, *, report: DriftReport | None = None,
                 title: str | None = None) -> Path:
    """Save a history plot (one panel per quantity) to ``path``.

    Error bars are expanded uncertainties (k=2). With a ``report`` (one
    quantity) the fitted drift line, its k=2 band, the tolerance limits and
    the due date are drawn as well.
    """
    return save_figure(history_figure(points, report=report, title=title), path)


def history_figure(points: Sequence[HistoryPoint], *, report: DriftReport | None = None, title: str | None = None):
    """The figure of :func:`plot_history` (a matplotlib Figure, not saved; the web view inlines it as SVG)."""
    names = list(dict.fromkeys(p.quantity for p in points))
    fig, axes = new_figure(len(names), 1, height=2.2 + 2.3 * len(names), squeeze=False, sharex=True)
    for ax, name in zip(axes[:, 0], names):
        pts = [p for p in points if p.quantity == name]
        current = [p for p in pts if p.superseded_by is None]
        old = [p for p in pts if p.superseded_by is not None]
        for group, style in ((current, dict(fmt="o", label="calibrations (±U, k=2)")),
                             (old, dict(fmt="o", mfc="none", color="0.6", label="superseded records"))):
            if group:
                ax.errorbar([datetime.fromisoformat(p.date) for p in group], [p.value for p in group],
                            yerr=[2.0 * p.uncertainty for p in group], ms=4, capsize=3, **style)
        unit = pts[0].unit
        ax.set_ylabel(_literal(f"{name} ({unit})" if unit else name))
        if report is not None and report.quantity == name:
            _draw_drift(ax, report)
        ax.grid(alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    axes[0, 0].set_title(_literal(title or f"Calibration history of {points[0].quantity if len(names) == 1 else 'sensor'}"))
    axes[-1, 0].set_xlabel("calibration date")
    return fig


def _draw_drift(ax, report: DriftReport) -> None:
    t_end = (report.last_date - report.epoch).total_seconds() / 86400.0 / DAYS_PER_YEAR
    if report.due is not None and report.due.t_due is not None:
        t_end = max(t_end, report.due.t_due) * 1.05 + 0.05
    t = np.linspace(0.0, t_end, 200)
    value, u = report.fit.predict(t)
    dates = [report.epoch + timedelta(days=float(x) * DAYS_PER_YEAR) for x in t]
    ax.plot(dates, value, "-", lw=1.2,
            label=_literal(f"drift {report.drift_per_year:.3g} ± {2 * report.u_drift_per_year:.2g} {report.unit}/yr (k=2)"))
    ax.fill_between(dates, value - 2 * u, value + 2 * u, alpha=0.2, label="line ±2u")
    if report.tolerance is not None:
        for sign in (-1, 1):
            ax.axhline(report.reference + sign * report.tolerance, color="tab:red", ls="--", lw=1,
                       label="tolerance" if sign > 0 else None)
    if report.due_date is not None:
        ax.axvline(report.due_date, color="tab:red", lw=1.5, label=f"due {report.due_date.date().isoformat()}")
