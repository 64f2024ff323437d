"""Reference standards in the registry: their certificates, due dates, and the calibrations that used them.

A lab traces every result to the reference standards it was measured
against (ISO/IEC 17025:2017, 6.4 and 6.5).  When a standard is found out of
tolerance at its next calibration, the lab must find every result that used
it since (7.10, the "impact" of nonconforming work).  The registry keeps

* one row per certificate of a standard (``ident`` is the lab's id of the
  standard, e.g. ``REF-8305``; a recalibration adds a row that supersedes
  the previous one), chained like the calibration records: ``chain_hash =
  sha256(previous || canonical content)`` over the table ``standards``, head
  in ``standards_chain``;
* the standard rows each calibration used (``calibration_standards``), whose
  idents and chain hashes are part of the calibration's own hashed content.

Pure values and checks here; the database work is in
:mod:`senscal.registry.store`.

References
----------
.. [1] ISO/IEC 17025:2017, 6.4.13 e-g (equipment records: calibration
   dates, due dates), 6.5 (metrological traceability), 7.10 (nonconforming
   work: evaluate the significance and take action on affected results).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from datetime import date, datetime, timezone
from typing import Any, Mapping, NamedTuple

from senscal._result import ResultMixin
from senscal.errors import InputError

__all__ = ["ReferenceStandard", "StandardUse", "ImpactRow", "ImpactReport", "parse_due", "check_ident",
           "check_u_relative", "check_sha256", "standard_content", "overdue_on", "CONTENT_VERSION"]

#: Version of the canonical encoding of a standard row (hashed with it).
CONTENT_VERSION = 1

_IDENT = re.compile(r"[A-Za-z0-9][A-Za-z0-9._:/+#-]{0,199}")
_HEX64 = re.compile(r"[0-9a-f]{64}")


def check_ident(text: Any, what: str = "standard ID") -> str:
    """A standard's ID as a lab types it: letters, digits and ``. _ : / + # -``, up to 200 characters.

    Raises
    ------
    InputError
        Empty, with spaces or other characters (an ID is typed, printed and compared: ``REF 1`` and ``REF-1``
        must not both exist).
    """
    s = str(text).strip() if text is not None else ""
    if not _IDENT.fullmatch(s):
        raise InputError(f"{what} {text!r} is not valid: use letters, digits and . _ : / + # - (no spaces, at most "
                         "200 characters, starting with a letter or digit), e.g. REF-8305")
    return s


def parse_due(text: Any, what: str = "--due") -> date:
    """A due date ``YYYY-MM-DD`` (a calendar date; no time: a standard is due for a whole day).

    Raises
    ------
    InputError
        Not a calendar date, or outside the years 1900..2999 (a typo).
    """
    if isinstance(text, datetime):
        return text.date()
    if isinstance(text, date):
        d = text
    else:
        s = str(text).strip() if text is not None else ""
        try:
            if not re.fullmatch(r"\d{4}-\d{2}-\d{2}", s):
                raise ValueError
            d = date.fromisoformat(s)
        except ValueError:
            raise InputError(f"{what} must be a calendar date YYYY-MM-DD, e.g. 2027-03-31, got {text!r}") from None
    if not 1900 <= d.year <= 2999:
        raise InputError(f"{what} {d.isoformat()} is outside the years 1900..2999; check the date")
    return d


def check_u_relative(value: Any, what: str = "--u-relative") -> float:
    """The standard's relative standard uncertainty (k=1): a fraction ``0.002`` or a percentage ``0.2%``.

    Raises
    ------
    InputError
        Not a number, not finite, negative, or 100 % or more (no reference standard is that poor: a typo).
    """
    s = str(value).strip() if value is not None else ""
    try:
        u = float(s[:-1]) / 100.0 if s.endswith("%") else float(s)
    except ValueError:
        raise InputError(f"{what} must be the relative standard uncertainty (k=1) as a fraction or a percentage, "
                         f"e.g. 0.002 or 0.2%, got {value!r}") from None
    if not math.isfinite(u) or u < 0 or u >= 1:
        raise InputError(f"{what} must be a finite relative standard uncertainty >= 0 and below 100 % (k=1), "
                         f"e.g. 0.2%, got {value!r}")
    return u


def check_sha256(text: Any, what: str = "--dcc-hash") -> str:
    """A SHA-256 digest as 64 hex digits (an optional ``sha256:`` prefix is dropped), lower case.

    Raises
    ------
    InputError
        Not 64 hex digits.
    """
    s = str(text).strip().lower() if text is not None else ""
    if s.startswith("sha256:"):
        s = s[7:]
    if not _HEX64.fullmatch(s):
        raise InputError(f"{what} must be the SHA-256 of the standard's own DCC (64 hex digits, e.g. from "
                         f"'sha256sum FILE.xml'), got {text!r}")
    return s


def _utc_iso(dt: datetime | None) -> str | None:
    if dt is None:
        return None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=timezone.utc)
    return dt.astimezone(timezone.utc).isoformat()


def standard_content(row: Mapping[str, Any]) -> bytes:
    """The bytes a standard row's chain hash covers (canonical JSON, sorted keys, no whitespace).

    Parameters
    ----------
    row : mapping
        ``uid, ident, name, serial, certificate, certificate_sha256,
        traceability, due (date), u_relative, recorded_at, operator, note,
        supersedes``.
    """
    due = row["due"]
    doc = {"v": CONTENT_VERSION, "type": "standard", "uid": row["uid"], "ident": row["ident"], "name": row["name"],
           "serial": row["serial"], "certificate": row["certificate"],
           "certificate_sha256": row["certificate_sha256"], "traceability": row["traceability"],
           "due": due.isoformat() if isinstance(due, date) else due, "u_relative": float(row["u_relative"]),
           "recorded_at": _utc_iso(row["recorded_at"]), "operator": row["operator"], "note": row["note"],
           "supersedes": row["supersedes"]}
    return json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=True).encode("utf-8")


def overdue_on(due: date, on: date | datetime) -> bool:
    """Whether a standard due on ``due`` is past due on ``on`` (still in date on the due day itself)."""
    day = on.date() if isinstance(on, datetime) else on
    return due < day


@dataclass(frozen=True)
class ReferenceStandard(ResultMixin):
    """One certificate of a lab's reference standard, as the registry keeps it.

    Attributes
    ----------
    ident : str
        The lab's id of the standard (the same for all its certificates), e.g. ``REF-8305``.
    name, serial : str or None
        Description (e.g. "Reference accelerometer B&K 8305") and serial number.
    certificate : str
        Number or reference of the standard's own calibration certificate.
    certificate_sha256 : str or None
        SHA-256 of the standard's own certificate file (its DCC), linked from
        the DCCs of the calibrations that use it (``hashType``).
    traceability : str or None
        To which national standard, e.g. "PTB, DKD-K-12345".
    due : date
        When its next calibration is due (it is in date on that day).
    u_relative : float
        Its relative standard uncertainty (k=1), e.g. 0.002 for 0.2 %.
    uid : str
        Id of this row (UUID).
    recorded_at : datetime
        When the row entered the registry (UTC).
    operator, note : str or None
    supersedes : str or None
        uid of the previous certificate of the same standard.
    superseded_by : str or None
        uid of the next one (derived, not stored): a superseded row is history.
    chain_hash : str
        Its hash in the standards' chain.
    """

    ident: str
    name: str | None
    serial: str | None
    certificate: str
    certificate_sha256: str | None
    traceability: str | None
    due: date
    u_relative: float
    uid: str
    recorded_at: datetime
    operator: str | None = None
    note: str | None = None
    supersedes: str | None = None
    superseded_by: str | None = None
    chain_hash: str = ""

    def overdue(self, on: date | datetime) -> bool:
        """Past its due date on ``on`` (a calibration date)."""
        return overdue_on(self.due, on)

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        d["due"] = self.due.isoformat()
        d["recorded_at"] = _utc_iso(self.recorded_at)
        return d


@dataclass(frozen=True)
class StandardUse(ResultMixin):
    """A standard as one calibration used it: which certificate, and whether it was overdue that day.

    Attributes
    ----------
    ident, certificate : str
    due : date
    u_relative : float
    uid : str
        The standard row (certificate) used.
    overdue : bool
        Its due date was before the calibration date.
    certificate_sha256 : str or None
    """

    ident: str
    certificate: str
    due: date
    u_relative: float
    uid: str
    overdue: bool
    certificate_sha256: str | None = None

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        d["due"] = self.due.isoformat()
        return d


class ImpactRow(NamedTuple):
    """One calibration that used a standard (a row of ``registry impact``).

    A named tuple, not a dataclass: an impact report lists up to every
    record of a registry (100,000 rows in a second, benchmarks/bench_impact.py).

    Attributes
    ----------
    calibration : str
        uid of the calibration record.
    serial : str
        The sensor calibrated.
    performed_at : str
        ISO 8601, in the record's own offset.
    job, method, certificate, operator : str or None
        What produced it and the certificate issued (path or reference).
    standard_certificate : str
        Which certificate of the standard was in use.
    standard_due : str
        Its due date (ISO).
    overdue : bool
        The standard was past its due date on the calibration date.
    superseded_by : str or None
        A record that corrects this one (the impact still lists it: it was issued).
    """

    calibration: str
    serial: str
    performed_at: str
    job: str
    method: str | None
    certificate: str | None
    operator: str | None
    standard_certificate: str
    standard_due: str
    overdue: bool
    superseded_by: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return self._asdict()


@dataclass(frozen=True)
class ImpactReport(ResultMixin):
    """Every calibration that used one reference standard (the out-of-tolerance impact report).

    Attributes
    ----------
    ident : str
    since : str or None
        Only calibrations performed on or after this date (ISO), when given.
    standards : tuple of ReferenceStandard
        Every certificate of the standard, oldest first.
    rows : tuple of ImpactRow
        The calibrations, in date order.
    n_calibrations, n_sensors, n_certificates, n_overdue : int
        Counts over ``rows`` (certificates: rows that name one).
    """

    ident: str
    since: str | None
    standards: tuple[ReferenceStandard, ...]
    rows: tuple[ImpactRow, ...]
    n_calibrations: int
    n_sensors: int
    n_certificates: int
    n_overdue: int

    def to_dict(self) -> dict[str, Any]:
        fields = ImpactRow._fields
        return {"ident": self.ident, "since": self.since, "standards": [s.to_dict() for s in self.standards],
                "rows": [dict(zip(fields, r)) for r in self.rows], "n_calibrations": self.n_calibrations,
                "n_sensors": self.n_sensors, "n_certificates": self.n_certificates, "n_overdue": self.n_overdue}
