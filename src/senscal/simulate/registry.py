"""Synthetic calibration histories with a known drift (for the registry)."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from typing import Any

import numpy as np

from senscal.errors import InputError

__all__ = ["simulate_calibration_history"]


def simulate_calibration_history(*, n_records: int = 7, value: float = 0.0100, drift_per_year: float = 4.0e-5,
                                 u_rel: float = 1.0e-3, interval_years: float = 1.0, jitter_days: float = 30.0,
                                 start: datetime | str = "2017-04-03T09:00:00+00:00", seed: int | None = None,
                                 ) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """A sensor's certificates: a linearly drifting quantity measured with stated uncertainties.

    Parameters
    ----------
    n_records : int
        Number of calibrations (>= 1).
    value : float
        True value at ``start`` (unit of the quantity, e.g. V/(m/s^2)).
    drift_per_year : float
        True drift (unit per year).
    u_rel : float
        Standard uncertainty of each calibration relative to ``value``; each
        record's uncertainty is this times a factor in [0.7, 1.5] (labs and
        methods differ) and its error is drawn from N(0, u).
    interval_years : float
        Nominal calibration interval (years).
    jitter_days : float
        Calibrations happen up to this many days before or after the nominal date.
    start : datetime or ISO str
        Date of the first calibration (timezone-aware).
    seed : int, optional

    Returns
    -------
    records : list of dict
        ``{"date": datetime, "value", "uncertainty"}`` in date order.
    truth : dict
        ``value``, ``drift_per_year``, ``start`` (ISO), ``true_values`` at the record dates.
    """
    if n_records < 1 or u_rel <= 0 or interval_years <= 0:
        raise InputError("n_records >= 1, u_rel > 0 and interval_years > 0 are required")
    rng = np.random.default_rng(seed)
    t0 = datetime.fromisoformat(start) if isinstance(start, str) else start
    records, true_values = [], []
    for i in range(n_records):
        shift = 0.0 if i == 0 else rng.uniform(-jitter_days, jitter_days)
        when = t0 + timedelta(days=365.25 * interval_years * i + shift)
        years = (when - t0).total_seconds() / 86400.0 / 365.25
        u = abs(value) * u_rel * rng.uniform(0.7, 1.5)
        truth_i = value + drift_per_year * years
        records.append({"date": when, "value": float(truth_i + rng.normal(0.0, u)), "uncertainty": float(u)})
        true_values.append(truth_i)
    truth = {"value": value, "drift_per_year": drift_per_year, "start": t0.astimezone(timezone.utc).isoformat(),
             "u_rel": u_rel, "true_values": true_values, "seed": seed}
    return records, truth
