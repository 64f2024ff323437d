"""``--save --sensor SERIAL [--db URL] [--create-sensor KIND] [--date ISO]`` for calibration commands.

A calibration command records its result in the sensor registry by adding
the option aliases below to its signature and calling
:func:`save_if_requested` once with the job's result
(:class:`senscal.jobs.JobResult`): the registry stores
``result.quantities()`` and keeps ``result.to_dict()`` as the full result::

    from senscal.cli.registry_opts import (CreateSensorOpt, DateOpt, DbOpt, OperatorOpt, SaveOpt,
                                           SensorOpt, save_if_requested)

    @app.command("velocity")
    def velocity_cmd(file: ..., save: SaveOpt = False, sensor: SensorOpt = None, db: DbOpt = None,
                     create_sensor: CreateSensorOpt = None, date: DateOpt = None,
                     operator: OperatorOpt = None) -> None:
        result = jobs.velocity(file, options)
        save_if_requested(result, save=save, sensor=sensor, db=db, create_sensor=create_sensor, date=date,
                          operator=operator, method="sine-approximation", input_files=[file])

Nothing happens without ``--save``; the confirmation goes to stderr so
``--json`` output stays clean.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, List, Mapping, Optional, Sequence

import typer
from typing_extensions import Annotated

from senscal.cli.common import err_console
from senscal.errors import InputError

__all__ = ["SaveOpt", "SensorOpt", "DbOpt", "CreateSensorOpt", "DateOpt", "OperatorOpt", "StandardOpt",
           "open_named_registry", "print_head", "save_if_requested", "UsedStandards", "use_standards",
           "note_standards"]

_PANEL = "Sensor registry"

SaveOpt = Annotated[bool, typer.Option("--save", help="Record the result in the sensor registry (needs --sensor).",
                                       rich_help_panel=_PANEL)]
SensorOpt = Annotated[Optional[str], typer.Option("--sensor", metavar="SERIAL", help="Serial number of the calibrated sensor.",
                                                  rich_help_panel=_PANEL)]
DbOpt = Annotated[Optional[str], typer.Option(
    "--db", metavar="URL", help="Registry database: SQLAlchemy URL or SQLite file (default: $SENSCAL_DB or the "
                                "user data folder).", rich_help_panel=_PANEL)]
CreateSensorOpt = Annotated[Optional[str], typer.Option(
    "--create-sensor", metavar="KIND", help="Register the sensor with this kind if it is new (e.g. accelerometer).",
    rich_help_panel=_PANEL)]
DateOpt = Annotated[Optional[str], typer.Option(
    "--date", metavar="ISO", help="When the calibration was done (ISO 8601; no offset = UTC; default now).",
    rich_help_panel=_PANEL)]
OperatorOpt = Annotated[Optional[str], typer.Option("--operator", help="Who calibrated (default: login name).",
                                                    rich_help_panel=_PANEL)]
StandardOpt = Annotated[Optional[List[str]], typer.Option(
    "--standard", metavar="ID", help="Reference standard used, by its ID in the registry (repeatable; see 'senscal "
                                     "registry standard add'): recorded with --save, listed on the certificate; one "
                                     "past its due date on the calibration date gives the warning standard-overdue.",
    rich_help_panel=_PANEL)]


@dataclass(frozen=True)
class UsedStandards:
    """The reference standards a calibration command was told it used (``--standard``), as the registry holds them.

    Attributes
    ----------
    standards : tuple of ReferenceStandard
        Their current certificates.
    on : datetime.date
        The calibration date they were judged on.
    warnings : tuple of str
        ``standard-overdue`` for each one past its due date on ``on``.
    """

    standards: tuple
    on: _dt.date
    warnings: tuple[str, ...]

    @property
    def idents(self) -> tuple[str, ...]:
        return tuple(s.ident for s in self.standards)

    def lab_standards(self, profile: Sequence[Any] = ()) -> tuple:
        """The standards as the certificate lists them (:class:`senscal.report.lab.Standard`).

        A profile entry with the same ``id`` (or ``serial``) lends what the
        registry does not hold (its name or traceability statement); the
        certificate, due date, uncertainty and SHA-256 are the registry's.
        """
        from senscal.report.lab import Standard

        by_key = {(p.id or p.serial): p for p in profile if (p.id or p.serial)}
        out = []
        for s in self.standards:
            p = by_key.get(s.ident)
            out.append(Standard(name=s.name or (p.name if p else "") or s.ident, serial=s.serial or (p.serial if p else ""),
                                certificate=s.certificate,
                                traceability=s.traceability or (p.traceability if p else ""),
                                due=s.due.isoformat(), u_relative=s.u_relative, id=s.ident,
                                certificate_sha256=s.certificate_sha256 or ""))
        return tuple(out)


def _judging_date(date: str | None, calibration_date: str | None) -> _dt.date:
    """The calibration date a standard's due date is judged on: --calibration-date, else --date, else today."""
    from senscal.registry import parse_date

    if calibration_date:
        text = calibration_date.split("/")[-1].strip()  # a calibration over several days: its last day
        try:
            return _dt.date.fromisoformat(text[:10])
        except ValueError:
            raise InputError(f"--calibration-date must be a date YYYY-MM-DD, got {calibration_date!r}") from None
    if date:
        return parse_date(date).date()  # the date in the offset it was given in
    return _dt.date.today()


def use_standards(idents: Sequence[str] | None, *, db: str | None, date: str | None = None,
                  calibration_date: str | None = None) -> UsedStandards | None:
    """Look up ``--standard`` IDs in the registry before the job runs; None without any.

    Raises
    ------
    InputError
        A malformed or unknown ID (one line listing the registered ones), a
        bad date, or a ``--db`` file that does not exist.
    """
    if not idents:
        return None
    from senscal.diagnostics import named
    from senscal.registry.standards import check_ident

    wanted = list(dict.fromkeys(check_ident(i, "--standard") for i in idents))
    on = _judging_date(date, calibration_date)
    with open_named_registry(db, create=False, read_only=True,
                             remedy="'senscal registry standard add ID ...' first (--standard names a registered "
                                    "standard)") as reg:
        found = tuple(reg.standard(i) for i in wanted)
    warns = tuple(named("standard-overdue", (
        f"reference standard {s.ident}{' (' + s.name + ')' if s.name else ''}: its certificate {s.certificate} was "
        f"due {s.due.isoformat()}, before the calibration date {on.isoformat()}; its values may have drifted beyond "
        f"its stated u: recalibrate it (then 'senscal registry standard add {s.ident} ... --renew') or use another "
        "standard")) for s in found if s.overdue(on))
    return UsedStandards(standards=found, on=on, warnings=warns)


def open_named_registry(db: str | None, *, create: bool, remedy: str, read_only: bool = False):
    """Open the registry at ``db``; a named SQLite file that does not exist needs ``create``.

    A typo in ``--db`` must not open (and record into) a new, empty registry;
    the error ends with ``remedy``, the option that creates one.  With
    ``read_only`` (a command that only reads) an existing database without a
    registry schema (an empty or 1-byte file) is refused too, unless ``create``.
    """
    from senscal.registry import open_registry
    from senscal.registry.db import missing_registry_file

    missing = missing_registry_file(db)
    if missing is not None and not create:
        raise InputError(f"registry file {missing} does not exist; check the --db path, or add {remedy}")
    return open_registry(db, read_only=read_only and not create and db is not None, remedy=remedy)


def note_standards(doc: dict, used: UsedStandards | None) -> list[str]:
    """Put the used standards (``standards``) and their ``standard-overdue`` warnings into a command's JSON document.

    Returns the warnings, for the command's :func:`~senscal.cli.common.emit_warnings` (``--strict`` exits 3).
    """
    if used is None:
        return []
    doc["standards"] = [dict(s.to_dict(), overdue=s.overdue(used.on)) for s in used.standards]
    doc["warnings"] = [*doc.get("warnings", []), *used.warnings]
    return list(used.warnings)


def print_head(reg) -> None:
    """One stderr line with the registry's chain head after a write, to keep outside the database.

    The head row lives in the same file as the records, so deleting the newest
    records and rewriting it passes ``verify``; a head kept elsewhere
    (``registry verify --expect-head HASH``) catches that.
    """
    n, head = reg.chain_head()
    if head is not None:
        err_console.print(f"registry head after {n} records: {head} (keep it elsewhere; "
                          "'senscal registry verify --expect-head HASH' checks it)")


def save_if_requested(result: Any, *, save: bool, sensor: str | None, db: str | None = None,
                      create_sensor: str | None = None, date: str | None = None, operator: str | None = None,
                      job: str | None = None, method: str | None, quantities: Sequence[Any] | None = None,
                      input_files: Iterable[str | Path] = (), conditions: Mapping[str, Any] | None = None,
                      certificate: str | Path | None = None, note: str | None = None,
                      standards: UsedStandards | None = None):
    """Record a calibration command's result if ``--save`` was given.

    Parameters
    ----------
    result : JobResult or mapping
        The job's result: the registry stores ``result.quantities()`` and
        keeps ``result.to_dict()`` (the ``--json`` document) as the full
        result.  A plain JSON document is accepted with ``quantities``.
    job : str, optional
        Job name recorded with the calibration (default ``result.job``).
    quantities : sequence of Quantity or callable, optional
        Overrides ``result.quantities()``; a callable is only called when
        saving.
    standards : UsedStandards, optional
        The ``--standard`` IDs looked up by :func:`use_standards`: the record
        links their certificates (under its hash).

    Returns
    -------
    Calibration or None
        The stored record, or None without ``--save``.

    Raises
    ------
    InputError
        ``--save`` without ``--sensor``, or registry options without ``--save``.
    UnknownSensorError
        Serial not registered and no ``--create-sensor``.
    """
    if not save:
        # --db also names where --standard IDs are looked up; --date the day their due dates are judged on.
        given = [opt for opt, v in (("--sensor", sensor), ("--db", None if standards else db),
                                    ("--create-sensor", create_sensor), ("--date", None if standards else date),
                                    ("--operator", operator)) if v is not None]
        if given:
            raise InputError(f"{', '.join(given)} only apply when saving; add --save to record the result in the registry")
        return None
    if not sensor:
        raise InputError("--save needs --sensor SERIAL (the serial number of the calibrated sensor)")
    from senscal.registry import parse_date

    when = parse_date(date)  # checked before opening the database: a typo costs nothing
    if quantities is None and hasattr(result, "quantities"):
        quantities = result.quantities
    qs = list(quantities() if callable(quantities) else (quantities or []))
    doc = result.to_dict() if hasattr(result, "to_dict") else result
    from senscal.cli.common import run_window, with_window

    if run_window() is not None:
        # The part of the records it used (--start/--stop) is part of what was calibrated: in the chain.
        conditions = {**(conditions or {}), "window": run_window()}
        doc = with_window(doc)
    job = job or getattr(result, "job", "") or None
    if isinstance(certificate, Path):
        from senscal.io.guard import is_stdio

        if not is_stdio(certificate):
            # The file --report writes, as an absolute path: 'registry serve' offers it for download from
            # wherever it runs (a relative path would name another file there).
            certificate = certificate.resolve()
    with open_named_registry(db, create=create_sensor is not None,
                             remedy="--create-sensor KIND to start a new registry there with this sensor") as reg:
        rec = reg.record(sensor, qs, performed_at=when, job=job, method=method, conditions=conditions,
                         result=doc, certificate=certificate, input_files=input_files, operator=operator,
                         note=note, create_kind=create_sensor, standards=standards.idents if standards else ())
        if rec.already_recorded and date is not None and rec.performed_at != when:
            # The same evidence is one calibration whatever date it is given (a second record would count
            # twice in the drift fit), so the new date is not recorded: say so instead of keeping it silently.
            err_console.print(f"already saved as calibration {rec.uid[:8]} of sensor {sensor} in {reg.url} "
                              f"(same input files and result) dated {rec.performed_at.isoformat()}; the --date "
                              f"{when.isoformat()} given now differs and was NOT recorded; nothing added (to "
                              f"correct the date, enter a correcting record with 'senscal registry record {sensor} ... "
                              f"--supersedes {rec.uid[:8]}')")
        elif rec.already_recorded:
            err_console.print(f"already saved as calibration {rec.uid[:8]} of sensor {sensor} in {reg.url} "
                              "(same input files and result); nothing added")
        else:
            used = f" with standard(s) {', '.join(standards.idents)}" if standards else ""
            err_console.print(f"saved calibration {rec.uid[:8]} of sensor {sensor} ({len(qs)} quantities){used} "
                              f"to {reg.url}")
        print_head(reg)
    return rec
