"""The registry: sensors and their append-only calibration history."""

from __future__ import annotations

import functools
import getpass
import hashlib
import math
import uuid
from dataclasses import dataclass, field, replace
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import sqlalchemy as sa
from sqlalchemy.exc import DBAPIError, IntegrityError, InterfaceError, OperationalError

from senscal._result import ResultMixin, to_jsonable
from senscal.errors import DataError, FileFormatError, InputError, SenscalError, TooFewSamplesError
from senscal.registry import db
from senscal.registry.chain import GENESIS, ChainReport, canonical_content, link, sensor_digest
from senscal.registry.db import (UTC, calibration_standards, calibrations, quantities, registry_chain, sensors,
                                 standards, standards_chain)
from senscal.registry.drift import DAYS_PER_YEAR, DriftFit, DueDate, due_time, fit_drift
from senscal.registry.standards import (ImpactReport, ImpactRow, ReferenceStandard, StandardUse, check_ident,
                                        check_sha256, check_u_relative, overdue_on, parse_due, standard_content)
from senscal.quantity import Quantity, check_text as _check_text

__all__ = [
    "Registry", "open_registry", "Sensor", "Quantity", "Calibration", "HistoryPoint", "DriftReport",
    "UnknownSensorError", "DuplicateSensorError", "UnknownQuantityError", "parse_date", "sha256_file",
    "EXPORT_FORMAT", "ChainReport", "drift_report", "ReferenceStandard", "StandardUse", "ImpactReport", "ImpactRow",
    "UnknownStandardError", "DuplicateStandardError",
]

EXPORT_FORMAT = "senscal-registry"
# 2: reference standards and the standards each record used (schema 0004); version 1 exports still import.
EXPORT_VERSION = 2


class UnknownSensorError(InputError):
    """A serial number the registry does not hold."""


class DuplicateSensorError(InputError):
    """A serial number that is already registered."""


class UnknownQuantityError(InputError):
    """A quantity a sensor's history (or a result) does not contain."""


class UnknownStandardError(InputError):
    """A reference-standard ID the registry does not hold."""


class DuplicateStandardError(InputError):
    """A reference-standard ID that is already registered (a recalibration is ``renew``)."""


@dataclass(frozen=True)
class Sensor(ResultMixin):
    """A registered sensor.

    Attributes
    ----------
    serial : str
        Unique serial number.
    kind : str
        accelerometer, velocity sensor, magnetometer, ...
    model, manufacturer, notes : str or None
    nominal : dict
        Nominal values ``{quantity: {"value": float, "unit": str}}``.
    created_at : datetime
        When the sensor was registered (UTC).
    """

    serial: str
    kind: str
    model: str | None = None
    manufacturer: str | None = None
    nominal: dict = field(default_factory=dict)
    notes: str | None = None
    created_at: datetime | None = None

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        d["created_at"] = _iso(self.created_at)
        return d


@dataclass(frozen=True)
class Calibration(ResultMixin):
    """One calibration record (never edited; corrections supersede it).

    Attributes
    ----------
    uid : str
        Unique id (UUID), stable across export/import.
    serial : str
    performed_at : datetime
        When the calibration was done (timezone-aware, in its original offset).
    recorded_at : datetime
        When it entered the registry (UTC).
    job, method : str
        e.g. ``fit`` / ``sine-fit``; ``manual`` for certificates entered by hand.
    quantities : tuple of Quantity
    conditions : dict
        Temperature, humidity, excitation, ... as given.
    result : dict or None
        The calibration command's full JSON result.
    certificate : str or None
        Path or reference of the certificate.
    input_files : tuple of dict
        ``{"path", "sha256"}`` of every input file (traceability).
    senscal_version, operator, note : str or None
    supersedes : str or None
        uid of the record this one corrects.
    superseded_by : str or None
        uid of the record that corrects this one (derived, not stored).
    already_recorded : bool
        True when :meth:`Registry.record` found this record already stored
        (same evidence) and added nothing (derived, not stored).
    standards : tuple of StandardUse
        The reference standards (their certificates) the calibration used,
        each marked overdue when its due date was before the calibration date.
    """

    uid: str
    serial: str
    performed_at: datetime
    recorded_at: datetime
    job: str
    method: str | None
    quantities: tuple[Quantity, ...]
    conditions: dict
    result: dict | None
    certificate: str | None
    input_files: tuple[dict, ...]
    senscal_version: str | None
    operator: str | None
    note: str | None
    supersedes: str | None
    superseded_by: str | None = None
    already_recorded: bool = False
    standards: tuple[StandardUse, ...] = ()

    def quantity(self, name: str) -> Quantity | None:
        return next((q for q in self.quantities if q.name == name), None)

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        d["performed_at"] = _iso(self.performed_at)
        d["recorded_at"] = _iso(self.recorded_at)
        return d


@dataclass(frozen=True)
class HistoryPoint(ResultMixin):
    """One row of a quantity's history (the JSON of ``registry history``)."""

    date: str
    quantity: str
    value: float
    uncertainty: float
    unit: str
    k: float
    expanded_uncertainty: float
    uid: str
    job: str
    method: str | None
    operator: str | None
    note: str | None
    certificate: str | None
    supersedes: str | None
    superseded_by: str | None


@dataclass(frozen=True)
class DriftReport(ResultMixin):
    """Drift of one quantity of one sensor and the date it is due.

    Attributes
    ----------
    serial, quantity, unit : str
    epoch : datetime
        Time origin of the fit (the first record).
    first_date, last_date : datetime
    fit : DriftFit
        Weighted line; slope in unit per year.
    drift_per_year, u_drift_per_year : float
        Copies of the fit's slope and its standard uncertainty (unit/year).
    relative_drift_per_year, u_relative_drift_per_year : float
        The same relative to the reference (1/year).
    significant : bool
    reference : float
        Nominal value, or the first recorded value.
    reference_source : str
        ``"nominal"`` or ``"first record"``.
    tolerance : float or None
        Allowed absolute deviation (unit).
    due : DueDate or None
    due_date : datetime or None
    as_of : datetime or None
        The date "overdue" is judged at (default: when the report was made).
    """

    serial: str
    quantity: str
    unit: str
    epoch: datetime
    first_date: datetime
    last_date: datetime
    fit: DriftFit
    drift_per_year: float
    u_drift_per_year: float
    relative_drift_per_year: float
    u_relative_drift_per_year: float
    significant: bool
    reference: float
    reference_source: str
    tolerance: float | None
    due: DueDate | None
    due_date: datetime | None
    as_of: datetime | None = None

    @property
    def overdue(self) -> bool | None:
        """Due at ``as_of`` or earlier: the due date has passed, or the bound already reached the
        tolerance at the last calibration (None without a tolerance)."""
        if self.due is None:
            return None
        passed = self.due_date is not None and self.as_of is not None and self.due_date <= self.as_of
        return bool(self.due.overdue or passed)

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        for key in ("epoch", "first_date", "last_date", "due_date", "as_of"):
            d[key] = _iso(getattr(self, key))
        d["overdue"] = self.overdue
        return d


# --- helpers -------------------------------------------------------------------

def _iso(dt: datetime | None) -> str | None:
    return None if dt is None else dt.isoformat()


def parse_date(text: str | datetime | None, *, what: str = "--date") -> datetime:
    """Parse an ISO 8601 date or date-time into an aware datetime.

    Dates and times without an offset are taken as UTC (so that a history
    does not depend on the computer's time zone); None means now.
    """
    if text is None:
        return datetime.now(UTC)
    if isinstance(text, datetime):
        dt = text
    else:
        try:
            dt = datetime.fromisoformat(str(text).strip())
        except ValueError:
            raise InputError(f"{what} must be an ISO 8601 date like 2024-03-01 or 2024-03-01T14:30+01:00, "
                             f"got {text!r}") from None
    return dt if dt.tzinfo is not None else dt.replace(tzinfo=UTC)


def sha256_file(path: str | Path) -> str:
    """SHA-256 of a file's bytes (hex), read in 1 MiB blocks."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError as exc:
        raise FileFormatError(f"cannot read input file {path} to fingerprint it: {exc.strerror}") from None
    return h.hexdigest()


def _senscal_version() -> str:
    from senscal import __version__

    return __version__


def _offset_s(dt: datetime) -> int:
    off = dt.utcoffset()
    return int(off.total_seconds()) if off is not None else 0


def _localise(dt_utc: datetime, offset_s: int) -> datetime:
    return dt_utc.astimezone(timezone(timedelta(seconds=offset_s)))


# --- the registry --------------------------------------------------------------

def _sensor_from(row) -> Sensor:
    return Sensor(serial=row["serial"], kind=row["kind"], model=row["model"], manufacturer=row["manufacturer"],
                  nominal=row["nominal"] or {}, notes=row["notes"], created_at=row["created_at"])


_INSERT_CALIBRATION = calibrations.insert()
_INSERT_QUANTITY = quantities.insert()
_INSERT_LINK = calibration_standards.insert()


def _standard_ref(row: Mapping[str, Any]) -> tuple[str, str]:
    """(ident, SHA-256 of the standard row's content): what a calibration's hash covers of a standard it used.

    The content digest (not the row's chain hash) so that an export imported
    into another registry, whose standards chain differs, hashes the same way.
    """
    return str(row["ident"]), hashlib.sha256(standard_content(row)).hexdigest()


def _standard_from(row, superseded_by: str | None = None) -> ReferenceStandard:
    return ReferenceStandard(
        ident=row["ident"], name=row["name"], serial=row["serial"], certificate=row["certificate"],
        certificate_sha256=row["certificate_sha256"], traceability=row["traceability"], due=_as_date(row["due"]),
        u_relative=float(row["u_relative"]), uid=row["uid"], recorded_at=row["recorded_at"],
        operator=row["operator"], note=row["note"], supersedes=row["supersedes"], superseded_by=superseded_by,
        chain_hash=row["chain_hash"])


def _as_date(value) -> "date":
    from datetime import date

    if isinstance(value, datetime):
        return value.date()
    if isinstance(value, date):
        return value
    return date.fromisoformat(str(value))


def _iso_local(value, offset_s: int) -> str:
    """A stored performed_at as ISO 8601 text in the record's own offset (what ``datetime.isoformat`` prints).

    ``value`` is SQLite's text (``YYYY-MM-DD HH:MM:SS.ffffff``, UTC) or a
    datetime (PostgreSQL); text in UTC is rewritten without parsing it.
    """
    if isinstance(value, str):
        if offset_s == 0 and len(value) == 26 and value[10] == " ":
            return value[:10] + "T" + value[11:19] + ("" if value[20:] == "000000" else value[19:]) + "+00:00"
        value = datetime.fromisoformat(value)
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return _localise(value, offset_s).isoformat()


def _use(row: Mapping[str, Any], when: datetime) -> StandardUse:
    """A standard row as a calibration performed at ``when`` (its own offset) used it."""
    due = _as_date(row["due"])
    return StandardUse(ident=row["ident"], certificate=row["certificate"], due=due,
                       u_relative=float(row["u_relative"]), uid=row["uid"], overdue=overdue_on(due, when),
                       certificate_sha256=row["certificate_sha256"])


class TamperedRegistryError(SenscalError):
    """The database holds a value senscal never writes (edited behind its back): exit 3, like a broken chain."""

    exit_code = 3


def _tampered(url: str, what: str) -> TamperedRegistryError:
    from senscal.diagnostics import named

    return TamperedRegistryError(named("registry-tampered", (
        f"{url}: {what}; it was edited behind senscal's back (the database's own checks bypassed); restore the "
        "database from a backup or an export and compare")))


def _db_errors(method):
    """Turn a lost server, a locked or read-only database into a one-line error (password masked).

    A stored value that does not decode (a date that is no date, JSON that is
    no JSON, bytes that are no UTF-8 text) was not written by senscal: it is
    reported as tampering (exit 3), not as an internal error.
    """

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except (OperationalError, InterfaceError) as exc:
            if "could not decode" in str(exc.orig).lower():
                raise _tampered(self.url, f"a stored text is not UTF-8 ({db._scrub(exc.orig, self._url)})") from None
            raise InputError(f"registry database {self.url} failed: {db._scrub(exc.orig, self._url)}") from None
        except SenscalError:
            raise
        except (ValueError, TypeError, KeyError, AttributeError) as exc:
            # Raised while the driver's rows are turned into datetimes / JSON (senscal's own checks raise
            # SenscalErrors): a value no senscal wrote.
            raise _tampered(self.url, f"a stored value does not decode ({type(exc).__name__}: "
                                      f"{' '.join(str(exc).split())[:160]})") from None

    return wrapper


class Registry:
    """Sensors and calibration history in a SQLAlchemy database.

    Parameters
    ----------
    url : str, Path or None
        SQLAlchemy URL (``sqlite:///file``, ``postgresql://user:pw@host/db``),
        a file path (SQLite), or None for :func:`senscal.registry.db.default_url`.
        The schema is created or upgraded (Alembic) on open.

    Examples
    --------
    >>> reg = Registry("sqlite:///lab.sqlite")                      # doctest: +SKIP
    >>> reg.add_sensor("A123", kind="accelerometer")                # doctest: +SKIP
    >>> reg.record("A123", [Quantity("sensitivity", 1.02e-2, 5e-5, "V/(m/s^2)")],
    ...            performed_at="2024-03-01")                       # doctest: +SKIP
    """

    def __init__(self, url: str | Path | None = None, *, read_only: bool = False, remedy: str = "--create"):
        self._url = db.parse_url(url)
        if read_only:
            _refuse_short_file(self._url, remedy)  # before SQLite opens it: opening would write a header
        self.engine = db.create_registry_engine(self._url)
        try:
            if read_only and db.current_revision(self.engine) is None:
                # Only reading: an empty file (or one stray byte, which SQLite takes as empty) is not a
                # registry with no records; creating the schema there would report "0 records, intact".
                self.engine.dispose()
                raise InputError(f"{self.url} holds no senscal registry (an empty file or another database); "
                                 f"check the --db path, or add {remedy}")
            db.upgrade(self.engine)
        except DBAPIError as exc:
            self.engine.dispose()
            raise InputError(f"cannot create or upgrade the registry schema in {self.url}: "
                             f"{db._scrub(exc.orig, self._url)}") from None

    @property
    def url(self) -> str:
        """The database URL with the password masked (safe to print)."""
        return db.mask_url(self._url)

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> "Registry":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # sensors -----------------------------------------------------------------

    @_db_errors
    def add_sensor(self, serial: str, kind: str, *, model: str | None = None, manufacturer: str | None = None,
                   nominal: Mapping[str, Any] | None = None, notes: str | None = None) -> Sensor:
        """Register a sensor.

        Raises
        ------
        DuplicateSensorError
            The serial is already registered.
        """
        serial, kind = _clean(serial, "serial"), _clean(kind, "kind")
        _check_free(model=model, manufacturer=manufacturer, notes=notes)
        with self.engine.begin() as conn:
            sid = self._insert_sensor(conn, serial, kind, model, manufacturer, nominal, notes)
            if sid is None:
                raise DuplicateSensorError(f"sensor {serial!r} is already registered in {self.url}; "
                                           "use another serial or record calibrations for the existing one")
            return self._sensor_row(conn, serial)

    def _insert_sensor(self, conn, serial, kind, model, manufacturer, nominal, notes, created_at=None) -> int | None:
        """Insert a sensor; None if the serial exists (safe against concurrent inserts)."""
        if conn.execute(sa.select(sensors.c.id).where(sensors.c.serial == serial)).first() is not None:
            return None
        try:
            with conn.begin_nested():
                return conn.execute(sensors.insert().values(
                    serial=serial, kind=kind, model=model, manufacturer=manufacturer,
                    nominal=to_jsonable(dict(nominal or {})), notes=notes,
                    created_at=created_at or db.now_utc())).inserted_primary_key[0]
        except IntegrityError:
            # Another process registered the same serial between our select and insert.
            return None

    def _sensor_row(self, conn, serial: str) -> Sensor:
        row = conn.execute(sa.select(sensors).where(sensors.c.serial == serial)).mappings().first()
        if row is None:
            raise UnknownSensorError(self._unknown_sensor_message(conn, serial))
        return _sensor_from(row)

    def _unknown_sensor_message(self, conn, serial: str) -> str:
        n = conn.execute(sa.select(sa.func.count()).select_from(sensors)).scalar_one()
        return (f"unknown sensor serial {serial!r} in {self.url} ({n} sensors registered); "
                "list them with 'senscal registry sensors' or add it with 'senscal registry add SERIAL --kind KIND'")

    @_db_errors
    def sensor(self, serial: str) -> Sensor:
        """The sensor with this serial (UnknownSensorError if absent)."""
        with db.read_connection(self.engine) as conn:
            return self._sensor_row(conn, serial)

    @_db_errors
    def sensors(self) -> list[Sensor]:
        """All sensors, sorted by serial."""
        with db.read_connection(self.engine) as conn:
            rows = conn.execute(sa.select(sensors).order_by(sensors.c.serial)).mappings().all()
        return [_sensor_from(r) for r in rows]

    @_db_errors
    def counts(self) -> dict[str, int]:
        """Number of calibration records per serial."""
        with db.read_connection(self.engine) as conn:
            rows = conn.execute(
                sa.select(sensors.c.serial, sa.func.count(calibrations.c.id))
                .select_from(sensors.outerjoin(calibrations, calibrations.c.sensor_id == sensors.c.id))
                .group_by(sensors.c.serial)).all()
        return {s: int(n) for s, n in rows}

    # calibrations ----------------------------------------------------------

    @_db_errors
    def record(self, serial: str, quantities_: Sequence[Quantity], *, performed_at: str | datetime | None = None,
               job: str = "manual", method: str | None = None, conditions: Mapping[str, Any] | None = None,
               result: Mapping[str, Any] | None = None, certificate: str | Path | None = None,
               input_files: Iterable[str | Path] = (), operator: str | None = None, note: str | None = None,
               supersedes: str | None = None, create_kind: str | None = None,
               standards: Sequence[str] = ()) -> Calibration:
        """Append one calibration record.

        Parameters
        ----------
        serial : str
            Sensor serial; must be registered unless ``create_kind`` is given.
        quantities_ : sequence of Quantity
            The quoted quantities (standard uncertainties, k=1, plus the coverage factor quoted).
        performed_at : str or datetime, optional
            When the calibration was done (ISO 8601; no offset means UTC); default now.
        job, method : str
            Which command/method produced it (``manual`` for an external certificate).
        conditions : mapping, optional
            Environmental/excitation conditions.
        result : mapping, optional
            The full JSON result of the calibration command.
        certificate : str or Path, optional
            Certificate file or reference.
        input_files : iterable of path
            Files the result was computed from; their SHA-256 is stored.
        operator : str, optional
            Who did it (default: the login name).
        note : str, optional
        supersedes : str, optional
            uid (or unique prefix of at least 6 characters) of a record of the
            same sensor that this one corrects.
        create_kind : str, optional
            Register the sensor with this kind if it is not registered yet.
        standards : sequence of str
            IDs of the reference standards used (their current certificates are
            linked; the links are part of the record's hashed content).

        Returns
        -------
        Calibration
            With ``standards`` marked overdue where a due date was before the calibration date.

        Raises
        ------
        UnknownStandardError
            A standard ID that is not registered.
        """
        serial = _clean(serial, "serial")
        qs = tuple(quantities_)
        if not qs:
            raise InputError("a calibration record needs at least one quantity")
        names = [q.name for q in qs]
        if len(set(names)) != len(names):
            raise InputError(f"quantity names in one calibration must be unique, got {names}")
        when = parse_date(performed_at)
        idents = list(dict.fromkeys(check_ident(i, "--standard") for i in standards))
        _check_free(job=job, method=method, note=note, operator=operator,
                    certificate=str(certificate) if certificate is not None else None)
        files = tuple({"path": str(Path(p).resolve()), "sha256": sha256_file(p)} for p in input_files)
        if operator is None:
            try:
                operator = getpass.getuser()
            except Exception:  # no login name (containers): leave it empty
                operator = None
        values = dict(
            uid=str(uuid.uuid4()), performed_at=when, utc_offset_s=_offset_s(when), recorded_at=db.now_utc(),
            job=job, method=method, conditions=to_jsonable(dict(conditions or {})),
            result=to_jsonable(dict(result)) if result is not None else None,
            certificate=str(certificate) if certificate is not None else None, input_files=list(files),
            senscal_version=_senscal_version(), operator=operator, note=note)
        with self.engine.begin() as conn:
            if create_kind is not None:
                self._insert_sensor(conn, serial, _clean(create_kind, "kind"), None, None, None, None)
            sid = self._sensor_id(conn, serial)
            values["supersedes"] = self._resolve_uid(conn, supersedes, sid, serial) if supersedes else None
            # The sensor's metadata as it is now goes into the record (and so into its chain hash).
            values["sensor_digest"] = sensor_digest(
                conn.execute(sa.select(sensors).where(sensors.c.id == sid)).mappings().one())
            self._lock_chain(conn)
            used = [self._current_standard(conn, i) for i in idents]
            # A retry after an output failure (or the same evidence saved twice) must not add a
            # second record: it would count as an independent calibration in the drift fit.
            same = self._same_evidence(conn, sid, values, qs, [u["id"] for u in used])
            if same is not None:
                return replace(self._calibrations(conn, calibrations.c.id == same)[0], already_recorded=True)
            self._insert_calibration(conn, sid, values, qs, used)
        # Built from what was stored (no second round trip); microseconds as the database keeps them.
        return Calibration(
            uid=values["uid"], serial=serial, performed_at=when, recorded_at=values["recorded_at"], job=job,
            method=method, quantities=tuple(Quantity(q.name, float(q.value), float(q.uncertainty), q.unit, float(q.k))
                                            for q in qs),
            conditions=values["conditions"], result=values["result"], certificate=values["certificate"],
            input_files=files, senscal_version=values["senscal_version"], operator=operator, note=note,
            supersedes=values["supersedes"], standards=tuple(_use(u, when) for u in used))

    @staticmethod
    def _lock_chain(conn) -> None:
        """Serialise appends to the hash chain (SQLite's BEGIN IMMEDIATE already does)."""
        if conn.dialect.name == "postgresql":
            conn.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": db.PG_APPEND_LOCK_KEY})

    def _same_evidence(self, conn, sensor_id: int, values: dict, qs: Sequence[Quantity],
                       standard_ids: Sequence[int] = ()) -> int | None:
        """id of a stored record of this sensor that carries the same evidence, else None.

        With input files, the same evidence is the same job and method on the
        same file contents (SHA-256) giving the same quantities, whatever the
        date. Without (certificates entered by hand), it is the same date,
        quantities, certificate, note and superseded record.
        """
        c = calibrations.c
        files = sorted(f["sha256"] for f in values["input_files"])
        stmt = sa.select(c.id, c.input_files).where(c.sensor_id == sensor_id, c.job == values["job"])
        stmt = stmt.where(c.method.is_(None) if values["method"] is None else c.method == values["method"])
        if not files:
            for col in ("performed_at", "certificate", "note", "supersedes"):
                v = values[col]
                stmt = stmt.where(getattr(c, col).is_(None) if v is None else getattr(c, col) == v)
        ids = [r.id for r in conn.execute(stmt)
               if sorted(f.get("sha256") for f in (r.input_files or ()) if isinstance(f, Mapping)) == files]
        if ids:
            # The same evidence measured against other standards is another calibration.
            links: dict[int, set] = {}
            cs = calibration_standards.c
            for cid, std in conn.execute(sa.select(cs.calibration_id, cs.standard_id)
                                         .where(cs.calibration_id.in_(ids))):
                links.setdefault(cid, set()).add(std)
            ids = [i for i in ids if links.get(i, set()) == set(standard_ids)]
        if not ids:
            return None
        want = sorted((q.name, float(q.value), float(q.uncertainty), q.unit, float(q.k)) for q in qs)
        have: dict[int, list] = {}
        for q in conn.execute(sa.select(quantities).where(quantities.c.calibration_id.in_(ids))).mappings():
            have.setdefault(q["calibration_id"], []).append((q["name"], q["value"], q["uncertainty"], q["unit"], q["k"]))
        return next((i for i in ids if sorted(have.get(i, ())) == want), None)

    def _insert_calibration(self, conn, sensor_id: int, values: dict, qs: Sequence[Quantity],
                            used: Sequence[Mapping[str, Any]] = ()) -> None:
        """Append one record, its quantities and its standards, extending the hash chain (caller holds the lock).

        ``used`` are standard rows (mappings with ``id``, ``ident`` and the other columns); their idents and
        content digests are part of the record's hashed content.
        """
        owner = conn.execute(sa.select(sensors.c.serial, sensors.c.kind).where(sensors.c.id == sensor_id)).one()
        head = conn.execute(sa.select(registry_chain.c.n_records, registry_chain.c.head)
                            .where(registry_chain.c.id == 1)).first()
        n, prev = (head.n_records, head.head) if head is not None else (0, GENESIS)
        hashed = dict(values, standards=[_standard_ref(u) for u in used]) if used else values
        chain_hash = link(prev, canonical_content(
            hashed, owner.serial, owner.kind, [(q.name, q.value, q.uncertainty, q.unit, q.k) for q in qs]))
        # Parameters passed to execute (not .values()) so the compiled statement is reused from the cache.
        cid = conn.execute(_INSERT_CALIBRATION, dict(values, sensor_id=sensor_id,
                                                     chain_hash=chain_hash)).inserted_primary_key[0]
        conn.execute(_INSERT_QUANTITY, [
            dict(calibration_id=cid, name=q.name, value=float(q.value), uncertainty=float(q.uncertainty),
                 unit=q.unit, k=float(q.k)) for q in qs])
        if used:
            conn.execute(_INSERT_LINK, [dict(calibration_id=cid, standard_id=u["id"]) for u in used])
        if head is None:
            conn.execute(registry_chain.insert().values(id=1, n_records=1, head=chain_hash))
        else:
            conn.execute(registry_chain.update().where(registry_chain.c.id == 1)
                         .values(n_records=n + 1, head=chain_hash))

    def _sensor_id(self, conn, serial: str) -> int:
        sid = conn.execute(sa.select(sensors.c.id).where(sensors.c.serial == serial)).scalar()
        if sid is None:
            raise UnknownSensorError(self._unknown_sensor_message(conn, serial)
                                     + " (or pass --create-sensor KIND when saving)")
        return sid

    def _resolve_uid(self, conn, prefix: str, sensor_id: int, serial: str) -> str:
        prefix = prefix.strip()
        if len(prefix) < 6:
            raise InputError(f"record id {prefix!r} is too short; give at least 6 characters of the id "
                             "shown by 'senscal registry history'")
        rows = conn.execute(sa.select(calibrations.c.uid, calibrations.c.sensor_id)
                            .where(calibrations.c.uid.startswith(prefix, autoescape=True))).all()
        if not rows:
            raise InputError(f"no calibration record with id {prefix!r}; see 'senscal registry history {serial}'")
        if len(rows) > 1:
            raise InputError(f"record id {prefix!r} is ambiguous ({len(rows)} records); give more characters")
        uid, owner = rows[0]
        if owner != sensor_id:
            raise InputError(f"record {prefix!r} belongs to another sensor, not {serial!r}; a correction must "
                             "supersede a record of the same sensor")
        return uid

    @_db_errors
    def calibration(self, uid: str) -> Calibration:
        """One record by its full uid."""
        with db.read_connection(self.engine) as conn:
            recs = self._calibrations(conn, calibrations.c.uid == uid)
        if not recs:
            raise InputError(f"no calibration record with id {uid!r}")
        return recs[0]

    def _calibrations(self, conn, where) -> list[Calibration]:
        c = calibrations.c
        rows = conn.execute(
            sa.select(calibrations, sensors.c.serial).join(sensors, sensors.c.id == c.sensor_id).where(where)
            .order_by(c.performed_at, c.recorded_at, c.id)).mappings().all()
        if not rows:
            return []
        ids = [r["id"] for r in rows]
        qrows = conn.execute(sa.select(quantities).where(quantities.c.calibration_id.in_(ids))
                             .order_by(quantities.c.id)).mappings().all()
        by_cal: dict[int, list[Quantity]] = {}
        for q in qrows:
            by_cal.setdefault(q["calibration_id"], []).append(
                Quantity(q["name"], q["value"], q["uncertainty"], q["unit"], q["k"]))
        uids = [r["uid"] for r in rows]
        later = dict(conn.execute(sa.select(c.supersedes, c.uid).where(c.supersedes.in_(uids))
                                  .order_by(c.recorded_at, c.id)).all())
        used: dict[int, list] = {}
        for srow in conn.execute(sa.select(standards, calibration_standards.c.calibration_id)
                                 .join(calibration_standards, calibration_standards.c.standard_id == standards.c.id)
                                 .where(calibration_standards.c.calibration_id.in_(ids))
                                 .order_by(calibration_standards.c.id)).mappings():
            used.setdefault(srow["calibration_id"], []).append(srow)
        return [Calibration(
            uid=r["uid"], serial=r["serial"], performed_at=_localise(r["performed_at"], r["utc_offset_s"]),
            recorded_at=r["recorded_at"], job=r["job"], method=r["method"], quantities=tuple(by_cal.get(r["id"], ())),
            conditions=r["conditions"] or {}, result=r["result"], certificate=r["certificate"],
            input_files=tuple(r["input_files"] or ()), senscal_version=r["senscal_version"], operator=r["operator"],
            note=r["note"], supersedes=r["supersedes"], superseded_by=later.get(r["uid"]),
            standards=tuple(_use(u, _localise(r["performed_at"], r["utc_offset_s"])) for u in used.get(r["id"], ())))
            for r in rows]

    @_db_errors
    def calibrations(self, serial: str, *, include_superseded: bool = False) -> list[Calibration]:
        """A sensor's records in date order (superseded ones only on request)."""
        with db.read_connection(self.engine) as conn:
            sid = self._sensor_id(conn, serial)
            recs = self._calibrations(conn, calibrations.c.sensor_id == sid)
        return recs if include_superseded else [r for r in recs if r.superseded_by is None]

    @_db_errors
    def history(self, serial: str, quantity: str | None = None, *,
                include_superseded: bool = False) -> list[HistoryPoint]:
        """The values of one (or every) quantity of a sensor over time.

        Raises
        ------
        UnknownSensorError, UnknownQuantityError
        """
        c, q = calibrations.c, quantities.c
        with db.read_connection(self.engine) as conn:
            sid = self._sensor_id(conn, serial)
            stmt = _history_select(include_superseded).where(c.sensor_id == sid)
            if quantity is not None:
                stmt = stmt.where(q.name == quantity)
            rows = conn.execute(stmt).all()
            known = None
            if quantity is not None and not rows:
                known = sorted(conn.execute(sa.select(q.name).distinct().join(calibrations, q.calibration_id == c.id)
                                            .where(c.sensor_id == sid)).scalars())
        points = [_history_point(r) for r in rows]
        if known is not None:
            raise UnknownQuantityError(
                f"sensor {serial!r} has no recorded quantity {quantity!r}; "
                + (f"recorded quantities: {', '.join(known)}" if known else "it has no calibration records yet"))
        return points

    @_db_errors
    def histories(self, *, include_superseded: bool = False) -> dict[str, list[HistoryPoint]]:
        """Every sensor's history at once, ``{serial: points}`` (sensors without records absent).

        One query for the whole registry (the web view's overview), the same
        points :meth:`history` gives per sensor.
        """
        with db.read_connection(self.engine) as conn:
            rows = conn.execute(_history_select(include_superseded, serial=True)).all()
        out: dict[str, list[HistoryPoint]] = {}
        for r in rows:
            out.setdefault(r.serial, []).append(_history_point(r))
        return out

    @_db_errors
    def drift(self, serial: str, quantity: str, *, tolerance: float | None = None, relative: bool = True,
              nominal: float | None = None, k: float = 2.0, alpha: float = 0.05,
              as_of: datetime | str | None = None) -> DriftReport:
        """Drift rate of a quantity and the date the sensor is due.

        Parameters
        ----------
        serial, quantity : str
        tolerance : float, optional
            Allowed deviation from the reference: a fraction of it when
            ``relative`` (0.01 = 1 %), else absolute in the quantity's unit.
            Without a tolerance no due date is computed.
        nominal : float, optional
            Reference value; default the first recorded value.
        k : float
            Coverage factor of the prediction uncertainty added to the deviation.
        alpha : float
            Significance level of the drift test.
        as_of : datetime or ISO 8601 str, optional
            Date at which :attr:`DriftReport.overdue` is judged (default now).

        Raises
        ------
        TooFewSamplesError
            Fewer than two (non-superseded) records of the quantity.
        """
        return drift_report(serial, quantity, self.history(serial, quantity), tolerance=tolerance, relative=relative,
                            nominal=nominal, k=k, alpha=alpha, as_of=as_of)

    # reference standards -----------------------------------------------------

    @_db_errors
    def add_standard(self, ident: str, *, certificate: str, due: str | Any, u_relative: float | str,
                     name: str | None = None, serial: str | None = None, traceability: str | None = None,
                     certificate_sha256: str | None = None, operator: str | None = None, note: str | None = None,
                     renew: bool = False) -> ReferenceStandard:
        """Register a reference standard's certificate, or (``renew``) its next certificate after a recalibration.

        Parameters
        ----------
        ident : str
            The lab's id of the standard, e.g. ``REF-8305`` (see :func:`~senscal.registry.standards.check_ident`).
        certificate : str
            Number or reference of the standard's own calibration certificate.
        due : str or date
            ``YYYY-MM-DD``: when its next calibration is due.
        u_relative : float or str
            Its relative standard uncertainty (k=1): 0.002 or "0.2%".
        name, serial, traceability : str, optional
            Description, serial number, traceability statement (``renew`` keeps the previous ones when omitted).
        certificate_sha256 : str, optional
            SHA-256 of the standard's own certificate file (DCC), linked from the DCCs that use it.
        operator, note : str, optional
        renew : bool
            Add a new certificate of a registered standard (the previous one is superseded, never edited).

        Raises
        ------
        DuplicateStandardError
            The ID is registered and ``renew`` is not given.
        UnknownStandardError
            ``renew`` of an ID that is not registered.
        """
        ident = check_ident(ident)
        due_d = parse_due(due)
        u = check_u_relative(u_relative)
        cert = str(certificate).strip() if certificate is not None else ""
        if not cert:
            raise InputError("--certificate must name the standard's own calibration certificate (its number or "
                             "file), e.g. --certificate PTB-12345-2026")
        sha = check_sha256(certificate_sha256) if certificate_sha256 is not None else None
        _check_free(certificate=cert, name=name, serial=serial, traceability=traceability, operator=operator,
                    note=note)
        if operator is None:
            try:
                operator = getpass.getuser()
            except Exception:  # no login name (containers)
                operator = None
        with self.engine.begin() as conn:
            self._lock_chain(conn)
            current = self._current_standard(conn, ident, missing_ok=True)
            if current is not None and not renew:
                raise DuplicateStandardError(
                    f"standard {ident!r} is already registered (certificate {current['certificate']}, due "
                    f"{_as_date(current['due']).isoformat()}); for its next certificate add --renew")
            if current is None and renew:
                raise UnknownStandardError(self._unknown_standard_message(conn, ident))
            if current is not None and current["certificate"] == cert:
                raise DuplicateStandardError(
                    f"standard {ident!r} already has certificate {cert!r}; --renew records a new certificate "
                    "after a recalibration: give its number with --certificate")
            prev = current or {}
            values = dict(uid=str(uuid.uuid4()), ident=ident, name=name if name is not None else prev.get("name"),
                          serial=serial if serial is not None else prev.get("serial"), certificate=cert,
                          certificate_sha256=sha,
                          traceability=traceability if traceability is not None else prev.get("traceability"),
                          due=due_d, u_relative=u, recorded_at=db.now_utc(), operator=operator, note=note,
                          supersedes=prev.get("uid"))
            row = self._insert_standard(conn, values)
        return _standard_from(row)

    @staticmethod
    def _insert_standard(conn, values: dict):
        """Append one standard row, extending the standards' chain (caller holds the chain lock); the stored row."""
        head = conn.execute(sa.select(standards_chain.c.n_records, standards_chain.c.head)
                            .where(standards_chain.c.id == 1)).first()
        n, prev_hash = (head.n_records, head.head) if head is not None else (0, GENESIS)
        values = dict(values, chain_hash=link(prev_hash, standard_content(values)))
        conn.execute(standards.insert(), values)
        if head is None:
            conn.execute(standards_chain.insert().values(id=1, n_records=1, head=values["chain_hash"]))
        else:
            conn.execute(standards_chain.update().where(standards_chain.c.id == 1)
                         .values(n_records=n + 1, head=values["chain_hash"]))
        return conn.execute(sa.select(standards).where(standards.c.uid == values["uid"])).mappings().one()

    def _current_standard(self, conn, ident: str, *, missing_ok: bool = False):
        """The newest certificate (row mapping) of a standard: the row no other row supersedes."""
        st, later = standards.c, standards.alias("later")
        row = conn.execute(sa.select(standards).outerjoin(later, later.c.supersedes == st.uid)
                           .where(st.ident == ident, later.c.id.is_(None))
                           .order_by(st.id.desc())).mappings().first()
        if row is None and not missing_ok:
            raise UnknownStandardError(self._unknown_standard_message(conn, ident))
        return row

    def _unknown_standard_message(self, conn, ident: str) -> str:
        known = sorted(set(conn.execute(sa.select(standards.c.ident)).scalars()))
        listed = (f"registered: {', '.join(known[:8])}{', ...' if len(known) > 8 else ''}" if known
                  else "none registered")
        return (f"unknown reference standard {ident!r} in {self.url} ({listed}); add it with 'senscal registry "
                f"standard add {ident} --certificate CERT --due YYYY-MM-DD --u-relative U'")

    @_db_errors
    def standards(self, *, include_superseded: bool = False) -> list[ReferenceStandard]:
        """The registered standards: each one's current certificate (every certificate on request), by ID."""
        st = standards.c
        with db.read_connection(self.engine) as conn:
            rows = conn.execute(sa.select(standards).order_by(st.ident, st.id)).mappings().all()
        later = {r["supersedes"]: r["uid"] for r in rows if r["supersedes"]}
        out = [_standard_from(r, later.get(r["uid"])) for r in rows]
        return out if include_superseded else [s for s in out if s.superseded_by is None]

    @_db_errors
    def standard(self, ident: str) -> ReferenceStandard:
        """The current certificate of one standard (UnknownStandardError if absent)."""
        ident = check_ident(ident)
        with db.read_connection(self.engine) as conn:
            return _standard_from(self._current_standard(conn, ident))

    @_db_errors
    def standard_history(self, ident: str) -> list[ReferenceStandard]:
        """Every certificate of one standard, oldest first."""
        ident = check_ident(ident)
        with db.read_connection(self.engine) as conn:
            rows = conn.execute(sa.select(standards).where(standards.c.ident == ident)
                                .order_by(standards.c.id)).mappings().all()
            if not rows:
                raise UnknownStandardError(self._unknown_standard_message(conn, ident))
        later = {r["supersedes"]: r["uid"] for r in rows if r["supersedes"]}
        return [_standard_from(r, later.get(r["uid"])) for r in rows]

    @_db_errors
    def impact(self, ident: str, *, since: str | datetime | None = None) -> ImpactReport:
        """Every calibration that used a standard (any of its certificates): the out-of-tolerance impact report.

        One indexed range scan of ``calibration_standards`` per certificate of
        the standard (index on standard, calibration), joined to the records
        and their sensors by primary key; the records' result JSON is not read.

        Parameters
        ----------
        ident : str
            The standard's ID.
        since : str or datetime, optional
            Only calibrations performed at or after this date (ISO 8601; no offset = UTC).

        Raises
        ------
        UnknownStandardError
        """
        ident = check_ident(ident)
        t0 = parse_date(since, what="--since") if since is not None else None
        c, cs, st = calibrations.c, calibration_standards.c, standards.c
        with db.read_connection(self.engine) as conn:
            srows = conn.execute(sa.select(standards).where(st.ident == ident).order_by(st.id)).mappings().all()
            if not srows:
                raise UnknownStandardError(self._unknown_standard_message(conn, ident))
            by_id = {r["id"]: r for r in srows}
            # performed_at as the driver gives it (SQLite: text in UTC): most records are in UTC, and turning
            # 100,000 of them into datetimes and back into ISO text would take most of the time.
            stmt = (sa.select(c.uid, sa.type_coerce(c.performed_at, sa.String).label("performed_at"), c.utc_offset_s,
                              c.job, c.method, c.certificate, c.operator, sensors.c.serial, cs.standard_id)
                    .select_from(calibration_standards)
                    .join(calibrations, c.id == cs.calibration_id)
                    .join(sensors, sensors.c.id == c.sensor_id)
                    .where(cs.standard_id.in_(list(by_id)))
                    .order_by(c.performed_at, c.id))
            if t0 is not None:
                stmt = stmt.where(c.performed_at >= t0)
            rows = conn.execute(stmt).all()
            # Corrections are few: one pass over them, not one index lookup per listed record.
            later = dict(conn.execute(sa.select(c.supersedes, c.uid).where(c.supersedes.is_not(None))
                                      .order_by(c.recorded_at, c.id)).all())
        later_std = {r["supersedes"]: r["uid"] for r in srows if r["supersedes"]}
        info = {i: (r["certificate"], _as_date(r["due"]).isoformat()) for i, r in by_id.items()}
        out = []
        for uid, when, off, job, method, cert, operator, serial, sid in rows:
            when = _iso_local(when, off)
            std_cert, due = info[sid]
            # ISO dates compare as text: overdue when the due day is before the (local) calibration day.
            out.append(ImpactRow(uid, serial, when, job, method, cert, operator, std_cert, due, due < when[:10],
                                 later.get(uid)))
        return ImpactReport(ident=ident, since=t0.isoformat() if t0 is not None else None,
                            standards=tuple(_standard_from(r, later_std.get(r["uid"])) for r in srows),
                            rows=tuple(out), n_calibrations=len(out), n_sensors=len({r.serial for r in out}),
                            n_certificates=sum(1 for r in out if r.certificate), n_overdue=sum(r.overdue for r in out))

    # integrity -----------------------------------------------------------------

    @_db_errors
    def chain_head(self) -> tuple[int, str | None]:
        """``(number of records, head hash)`` as the registry stores them (``(0, None)`` when empty).

        Printed after every write: kept outside the database (lab book,
        certificate), it lets :meth:`verify` detect a truncated or wiped history,
        which the database alone cannot (its head row can be rewritten too).
        """
        with db.read_connection(self.engine) as conn:
            row = conn.execute(sa.select(registry_chain.c.n_records, registry_chain.c.head)
                               .where(registry_chain.c.id == 1)).first()
        return (0, None) if row is None or not row.n_records else (int(row.n_records), str(row.head))

    @_db_errors
    def verify(self, expect_head: str | None = None) -> ChainReport:
        """Recompute the hash chain over every record (see :mod:`senscal.registry.chain`).

        Detects records changed, deleted or inserted behind senscal's back
        (triggers dropped, a copy of the file edited), quantities replaced,
        sensors deleted or renamed, and the newest records deleted without the
        head row being rewritten. Reads every record once.

        Parameters
        ----------
        expect_head : str, optional
            A head printed by an earlier write or verify and kept elsewhere
            (at least 12 hex digits).  It must be the hash of a record of the
            recomputed chain (the newest, or an older one when records were
            added since); otherwise the history was truncated, wiped or rebuilt.

        Returns
        -------
        ChainReport
        """
        if expect_head is not None:
            expect_head = _check_head(expect_head)
        c = calibrations.c
        with db.read_connection(self.engine) as conn:
            rows = conn.execute(sa.select(calibrations, sensors.c.serial, sensors.c.kind)
                                .outerjoin(sensors, sensors.c.id == c.sensor_id).order_by(c.id)).mappings().all()
            digests = {r["id"]: sensor_digest(r) for r in conn.execute(sa.select(sensors)).mappings()}
            qs: dict[int, list] = {}
            for q in conn.execute(sa.select(quantities).order_by(quantities.c.id)).mappings():
                qs.setdefault(q["calibration_id"], []).append((q["name"], q["value"], q["uncertainty"], q["unit"],
                                                               q["k"]))
            head = conn.execute(sa.select(registry_chain.c.n_records, registry_chain.c.head)
                                .where(registry_chain.c.id == 1)).first()
            srows = conn.execute(sa.select(standards).order_by(standards.c.id)).mappings().all()
            s_head = conn.execute(sa.select(standards_chain.c.n_records, standards_chain.c.head)
                                  .where(standards_chain.c.id == 1)).first()
            refs = {r["id"]: _standard_ref(r) for r in srows}
            links: dict[int, list] = {}
            dangling = 0
            for cid, sid in conn.execute(sa.select(calibration_standards.c.calibration_id,
                                                   calibration_standards.c.standard_id)):
                if sid in refs:
                    links.setdefault(cid, []).append(refs[sid])
                else:
                    dangling += 1
                    links.setdefault(cid, []).append(("?", "?"))
        problems: list[str] = self._verify_standards(srows, s_head)
        if dangling:
            problems.append(f"{dangling} link(s) from calibrations to reference standards point to standard rows "
                            "that were deleted")
        first = None
        prev = GENESIS
        changed: dict[int, bool] = {}
        for r in rows:
            if r["id"] in links:
                r = dict(r, standards=links[r["id"]])
            # Recompute from the stored hash of the predecessor, so one edit names one record.
            expected = link(prev, canonical_content(r, r["serial"], r["kind"], qs.get(r["id"], ())))
            if r["chain_hash"] != expected:
                if first is None:
                    first = r["uid"]
                why = ("its sensor row is missing" if r["serial"] is None else
                       "it has no quantities" if r["id"] not in qs else
                       "its content, its sensor or the record before it was changed, deleted or inserted")
                problems.append(f"record {r['uid']} (sensor {r['serial']!r}, performed "
                                f"{_iso(r['performed_at'])}) does not match its hash: {why}")
            prev = r["chain_hash"] or expected
            if r["sensor_digest"] is not None and r["serial"] is not None \
                    and digests.get(r["sensor_id"]) != r["sensor_digest"] and not changed.get(r["sensor_id"]):
                changed[r["sensor_id"]] = True
                problems.append(f"the metadata of sensor {r['serial']!r} (model, manufacturer, nominal values, "
                                f"notes) changed after record {r['uid']} was made")
                first = first or r["uid"]
        orphans = sorted(set(qs) - {r["id"] for r in rows})
        if orphans:
            problems.append(f"{len(orphans)} calibration record(s) were deleted: their quantities remain "
                            f"(calibration ids {', '.join(map(str, orphans[:5]))}{', ...' if len(orphans) > 5 else ''})")
        n_head, h_head = (head.n_records, head.head) if head is not None else (0, GENESIS)
        if n_head != len(rows) or (rows and h_head != rows[-1]["chain_hash"]):
            problems.append(f"the chain head says {n_head} records ending in {h_head[:12]}, the table holds "
                            f"{len(rows)} ending in {(rows[-1]['chain_hash'] or '-')[:12] if rows else '-'}: "
                            "records were deleted or added behind senscal's back")
        if expect_head is not None:
            at = next((i for i, r in enumerate(rows) if (r["chain_hash"] or "").startswith(expect_head)), None)
            if at is None:
                problems.append(f"the head kept elsewhere ({expect_head[:16]}) is not in the chain, which holds "
                                f"{len(rows)} records ending in {(prev[:16] if rows else '-')}: records were deleted "
                                "(the newest ones or all of them) or the history was rebuilt")
        return ChainReport(intact=not problems, n_records=len(rows), head=prev if rows else None,
                           first_broken=first, problems=tuple(problems), n_standards=len(srows))

    @staticmethod
    def _verify_standards(srows: Sequence[Mapping[str, Any]], head) -> list[str]:
        """Findings of the standards' own chain (one per changed, deleted or inserted row, and the head)."""
        problems = []
        prev = GENESIS
        for r in srows:
            if r["chain_hash"] != link(prev, standard_content(r)):
                problems.append(f"reference standard {r['ident']!r} (certificate {r['certificate']}, row {r['uid']}) "
                                "does not match its hash: its content or the row before it was changed, deleted or "
                                "inserted")
            prev = r["chain_hash"]
        n_head, h_head = (head.n_records, head.head) if head is not None else (0, GENESIS)
        if n_head != len(srows) or (srows and h_head != srows[-1]["chain_hash"]):
            problems.append(f"the standards' chain head says {n_head} rows, the table holds {len(srows)}: reference "
                            "standards were deleted or added behind senscal's back")
        return problems

    # export / import ---------------------------------------------------------

    @_db_errors
    def export(self) -> dict[str, Any]:
        """Every sensor and record as one JSON-ready document (import() reads it back exactly)."""
        out_sensors = []
        for s in self.sensors():
            d = s.to_dict()
            d["calibrations"] = []
            for r in self.calibrations(s.serial, include_superseded=True):
                rd = r.to_dict()
                rd.pop("serial")
                rd.pop("superseded_by")
                rd.pop("already_recorded")
                d["calibrations"].append(rd)
            out_sensors.append(d)
        with db.read_connection(self.engine) as conn:
            srows = conn.execute(sa.select(standards).order_by(standards.c.id)).mappings().all()
        out_standards = []
        for r in srows:
            d = _standard_from(r).to_dict()
            for key in ("superseded_by", "chain_hash"):  # derived, or recomputed on import
                d.pop(key)
            out_standards.append(d)
        return {"format": EXPORT_FORMAT, "version": EXPORT_VERSION, "schema": db.HEAD_REVISION,
                "standards": out_standards, "sensors": out_sensors}

    @_db_errors
    def import_(self, doc: Mapping[str, Any]) -> dict[str, int]:
        """Add the sensors and records of an export document.

        Records already present (same uid) are skipped, so importing twice
        adds nothing. A sensor already registered with another kind is an error.

        Returns
        -------
        dict
            ``{"sensors": added, "calibrations": added, "skipped": already present}``.
        """
        if not isinstance(doc, Mapping) or doc.get("format") != EXPORT_FORMAT:
            raise FileFormatError(f"not a senscal registry export (expected \"format\": \"{EXPORT_FORMAT}\")")
        if int(doc.get("version", 0)) > EXPORT_VERSION:
            raise FileFormatError(f"registry export version {doc.get('version')} is newer than this senscal "
                                  f"understands ({EXPORT_VERSION}); upgrade senscal")
        added = {"sensors": 0, "calibrations": 0, "skipped": 0}
        try:
            with self.engine.begin() as conn:
                self._lock_chain(conn)
                for st in doc.get("standards", []):
                    self._import_standard(conn, st, added)
                for s in doc.get("sensors", []):
                    self._import_sensor(conn, s, added)
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, InputError):
                raise
            raise FileFormatError(f"malformed registry export: {type(exc).__name__}: {exc}") from None
        return added

    def _import_standard(self, conn, st: Mapping[str, Any], added: dict[str, int]) -> None:
        if conn.execute(sa.select(standards.c.id).where(standards.c.uid == st["uid"])).first() is not None:
            return
        values = dict(uid=st["uid"], ident=check_ident(st["ident"]), name=st.get("name"), serial=st.get("serial"),
                      certificate=str(st["certificate"]),
                      certificate_sha256=check_sha256(st["certificate_sha256"]) if st.get("certificate_sha256") else None,
                      traceability=st.get("traceability"), due=parse_due(st["due"]),
                      u_relative=check_u_relative(st["u_relative"]), recorded_at=parse_date(st["recorded_at"]),
                      operator=st.get("operator"), note=st.get("note"), supersedes=st.get("supersedes"))
        self._insert_standard(conn, values)
        added["standards"] = added.get("standards", 0) + 1

    def _import_sensor(self, conn, s: Mapping[str, Any], added: dict[str, int]) -> None:
        serial = s["serial"]
        sid = self._insert_sensor(conn, serial, s["kind"], s.get("model"), s.get("manufacturer"),
                                  s.get("nominal"), s.get("notes"),
                                  created_at=parse_date(s["created_at"]) if s.get("created_at") else None)
        if sid is None:
            existing = self._sensor_row(conn, serial)
            if existing.kind != s["kind"]:
                raise InputError(f"sensor {serial!r} is already registered as {existing.kind!r}, the import says "
                                 f"{s['kind']!r}; resolve the conflict before importing")
            sid = self._sensor_id(conn, serial)
        else:
            added["sensors"] += 1
        pending = list(s.get("calibrations", []))
        while pending:
            # A correction must follow the record it supersedes (foreign key).
            present = set(conn.execute(sa.select(calibrations.c.uid)
                                       .where(calibrations.c.uid.in_([r["uid"] for r in pending]
                                                                     + [r["supersedes"] for r in pending
                                                                        if r.get("supersedes")]))).scalars())
            ready = [r for r in pending if not r.get("supersedes") or r["supersedes"] in present]
            if not ready:
                raise FileFormatError(f"records of {serial!r} supersede records missing from the export")
            for r in ready:
                if r["uid"] in present:
                    added["skipped"] += 1
                    continue
                when = parse_date(r["performed_at"])
                qs = [Quantity(q["name"], q["value"], q["uncertainty"], q["unit"], q["k"]) for q in r["quantities"]]
                used = []
                for u in r.get("standards") or ():
                    row = conn.execute(sa.select(standards).where(standards.c.uid == u["uid"])).mappings().first()
                    if row is None:
                        raise FileFormatError(f"record {r['uid']} uses reference standard {u.get('ident')!r} "
                                              f"(row {u['uid']}), which the export does not hold")
                    used.append(row)
                self._insert_calibration(conn, sid, dict(
                    uid=r["uid"], performed_at=when, utc_offset_s=_offset_s(when),
                    recorded_at=parse_date(r["recorded_at"]), job=r["job"], method=r.get("method"),
                    conditions=r.get("conditions") or {}, result=r.get("result"), certificate=r.get("certificate"),
                    input_files=list(r.get("input_files") or ()), senscal_version=r.get("senscal_version"),
                    operator=r.get("operator"), note=r.get("note"), supersedes=r.get("supersedes")), qs, used)
                present.add(r["uid"])
                added["calibrations"] += 1
            pending = [r for r in pending if r not in ready]


def drift_report(serial: str, quantity: str, points: Sequence[HistoryPoint], *, tolerance: float | None = None,
                 relative: bool = True, nominal: float | None = None, k: float = 2.0, alpha: float = 0.05,
                 as_of: datetime | str | None = None) -> DriftReport:
    """:meth:`Registry.drift` of a quantity's current (not superseded) history points (pure; no database).

    ``points`` are those of ``Registry.history(serial, quantity)``; the other
    parameters are :meth:`Registry.drift`'s.
    """
    pts = list(points)
    import numpy as np  # here, not at module level: record/show/list/due never need it

    pts = _in_one_unit(pts, serial, quantity)
    if len(pts) < 2:
        raise _too_few(serial, quantity, len(pts))
    dates = [datetime.fromisoformat(p.date) for p in pts]
    epoch = min(dates)
    t = np.array([(d - epoch).total_seconds() / 86400.0 / DAYS_PER_YEAR for d in dates])
    fit = fit_drift(t, [p.value for p in pts], [p.uncertainty for p in pts], alpha=alpha)
    if nominal is not None and not math.isfinite(nominal):
        raise InputError(f"--nominal must be a finite number, got {nominal}")
    reference = float(nominal) if nominal is not None else pts[0].value
    due = None
    due_date = None
    tol_abs = None
    if tolerance is not None:
        tol_abs = float(tolerance) * abs(reference) if relative else float(tolerance)
        due = due_time(fit, t_last=float(t.max()), reference=reference, tolerance=tol_abs, k=k)
        if due.t_due is not None:
            due_date = (epoch + timedelta(days=due.t_due * DAYS_PER_YEAR)).replace(microsecond=0)
    scale = abs(reference) if reference != 0 else math.nan
    return DriftReport(
        serial=serial, quantity=quantity, unit=pts[0].unit, epoch=epoch, first_date=min(dates), last_date=max(dates),
        fit=fit, drift_per_year=fit.drift_per_year, u_drift_per_year=fit.u_drift_per_year,
        relative_drift_per_year=fit.drift_per_year / scale, u_relative_drift_per_year=fit.u_drift_per_year / scale,
        significant=fit.significant, reference=reference,
        reference_source="nominal" if nominal is not None else "first record",
        tolerance=tol_abs, due=due, due_date=due_date, as_of=parse_date(as_of, what="as_of"))


def _history_select(include_superseded: bool, *, serial: bool = False):
    """The statement of a history (order: date, record, quantity); ``serial`` adds the sensor's serial."""
    c, q = calibrations.c, quantities.c
    later = calibrations.alias("later")
    # Only the columns a history shows: the full result JSON of each record is not read.
    cols = [c.performed_at, c.utc_offset_s, c.uid, c.job, c.method, c.operator, c.note, c.certificate, c.supersedes,
            later.c.uid.label("superseded_by"), q.name, q.value, q.uncertainty, q.unit, q.k]
    stmt = sa.select(*cols, sensors.c.serial) if serial else sa.select(*cols)
    stmt = stmt.join(quantities, q.calibration_id == c.id) if not serial else \
        stmt.select_from(calibrations).join(quantities, q.calibration_id == c.id).join(sensors,
                                                                                      sensors.c.id == c.sensor_id)
    stmt = stmt.outerjoin(later, later.c.supersedes == c.uid).order_by(c.performed_at, c.recorded_at, c.id, q.id)
    return stmt if include_superseded else stmt.where(later.c.uid.is_(None))


def _history_point(r) -> HistoryPoint:
    return HistoryPoint(date=_localise(r.performed_at, r.utc_offset_s).isoformat(), quantity=r.name, value=r.value,
                        uncertainty=r.uncertainty, unit=r.unit, k=r.k, expanded_uncertainty=r.k * r.uncertainty,
                        uid=r.uid, job=r.job, method=r.method, operator=r.operator, note=r.note,
                        certificate=r.certificate, supersedes=r.supersedes, superseded_by=r.superseded_by)


def _in_one_unit(pts: list, serial: str, quantity: str) -> list:
    """A quantity's history in the unit of its first record: another scale converted (mV/... to V/...),
    another dimension refused (a drift needs one quantity)."""
    if not pts:
        return pts
    from senscal.units import compatible, convert, is_unit

    unit = pts[0].unit
    out = []
    for p in pts:
        if p.unit == unit:
            out.append(p)
            continue
        if not (is_unit(p.unit) and is_unit(unit) and compatible(p.unit, unit)):
            raise DataError(f"records of {quantity!r} for {serial!r} use units that cannot be converted into each "
                            f"other ({unit}, {p.unit}); a drift needs one quantity: supersede the odd records")
        f = float(convert(1.0, p.unit, unit)) - float(convert(0.0, p.unit, unit))
        out.append(replace(p, value=float(convert(p.value, p.unit, unit)), uncertainty=abs(f) * p.uncertainty,
                           expanded_uncertainty=abs(f) * p.expanded_uncertainty, unit=unit))
    return out


def _too_few(serial: str, quantity: str, n: int) -> TooFewSamplesError:
    return TooFewSamplesError(f"sensor {serial!r} has {n} record{'s' if n != 1 else ''} of {quantity!r}; a drift "
                              "and a due date need at least two calibrations at different dates")


def _check_free(**fields: str | None) -> None:
    for what, text in fields.items():
        if text is not None:
            _check_text(str(text), what, free=True)


def _refuse_short_file(url, remedy: str) -> None:
    """Refuse an SQLite file too short to hold a database (its header is 100 bytes) without touching it."""
    if url.get_backend_name() != "sqlite" or not url.database or url.database == ":memory:" \
            or url.database.startswith("file:"):
        return
    try:
        size = Path(url.database).stat().st_size
    except OSError:
        return
    if size < 100:
        raise InputError(f"registry file {url.database} holds no senscal registry ({size} bytes: an empty or "
                         f"truncated file); check the --db path, restore it from a backup, or add {remedy}")


def _check_head(text: str) -> str:
    """A chain head given by the user: 12 to 64 hex digits, lower case."""
    h = str(text).strip().lower()
    if not 12 <= len(h) <= 64 or any(ch not in "0123456789abcdef" for ch in h):
        raise InputError(f"--expect-head must be the registry head as printed (12 to 64 hex digits), got {text!r}")
    return h


def _clean(text: str, what: str) -> str:
    s = str(text).strip() if text is not None else ""
    if not s:
        raise InputError(f"sensor {what} must not be empty")
    _check_text(s, f"sensor {what}")
    hidden = [ch for ch in s if _invisible(ch)]
    if hidden:
        # U+202E (right-to-left override) and its kin make a serial display as another one; zero-width
        # characters make two serials that look the same.  An identifier is printed, compared and typed.
        names = ", ".join(f"U+{ord(ch):04X}" for ch in dict.fromkeys(hidden))
        raise InputError(f"sensor {what} {s.encode('unicode_escape').decode('ascii')!r} holds invisible or "
                         f"direction-changing characters ({names}); type it with visible characters only")
    return s


def _invisible(ch: str) -> bool:
    """A format (bidi override, zero-width), control or line/paragraph separator character."""
    import unicodedata

    return unicodedata.category(ch) in ("Cf", "Cc", "Zl", "Zp", "Co", "Cn") and ch not in " "


def open_registry(url: str | Path | None = None, *, read_only: bool = False, remedy: str = "--create") -> Registry:
    """Open (creating or upgrading if needed) the registry at ``url``; see :class:`Registry`.

    ``read_only=True`` refuses a database without a registry schema instead of creating one.
    """
    return Registry(url, read_only=read_only, remedy=remedy)
