"""Sensor registry: calibration history, drift between calibrations, due dates.

A lab calibrates the same sensors again and again; between two certificates
nobody knows whether a sensor is still right (the motive of seed 002). The
registry keeps every sensor and every calibration (append-only; a correction
supersedes a record, never edits it), fits the drift of a quantity through
its history with weights from the uncertainties, and predicts when the
deviation plus its uncertainty will reach a tolerance.

Storage is SQLAlchemy: one SQLite file by default (WAL mode), any SQLAlchemy
URL (PostgreSQL for a shared lab server) by ``url``; the schema is managed by
Alembic migrations shipped in this package and applied on open.

Examples
--------
>>> from senscal.registry import open_registry, Quantity
>>> reg = open_registry("sqlite:///lab.sqlite")                        # doctest: +SKIP
>>> reg.add_sensor("A123", kind="accelerometer", model="4371")         # doctest: +SKIP
>>> reg.record("A123", [Quantity("sensitivity", 0.01012, 2.0e-5, "V/(m/s^2)")],
...            performed_at="2023-03-01")                              # doctest: +SKIP
>>> reg.drift("A123", "sensitivity", tolerance=0.01).due_date          # doctest: +SKIP

References
----------
.. [1] Seed 002: patent CN102564486A, Shanghai Dianji University (2012).
.. [2] JCGM 100:2008 (GUM), annex H.3.
.. [3] ILAC-G24:2022 / OIML D 10, recalibration intervals of measuring equipment.
"""

from senscal.registry.chain import ChainReport
from senscal.registry.db import default_url, mask_url, parse_url
from senscal.registry.drift import DriftFit, DueDate, due_time, fit_drift
from senscal.registry.standards import ImpactReport, ImpactRow, ReferenceStandard, StandardUse
from senscal.registry.store import (
    Calibration,
    DriftReport,
    DuplicateSensorError,
    DuplicateStandardError,
    HistoryPoint,
    Quantity,
    Registry,
    Sensor,
    UnknownQuantityError,
    UnknownSensorError,
    UnknownStandardError,
    open_registry,
    parse_date,
    sha256_file,
)

__all__ = [
    "Registry", "open_registry", "Sensor", "Quantity", "Calibration", "HistoryPoint", "DriftReport",
    "DriftFit", "DueDate", "fit_drift", "due_time", "default_url", "mask_url", "parse_url", "parse_date",
    "sha256_file", "UnknownSensorError", "DuplicateSensorError", "UnknownQuantityError", "ChainReport",
    "ReferenceStandard", "StandardUse", "ImpactReport", "ImpactRow", "UnknownStandardError", "DuplicateStandardError",
]
