"""``senscal registry ...``: sensors, calibration history, drift and due dates."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import List, Optional

import typer
from typing_extensions import Annotated

from senscal.cli.app import app, simulate_app
from senscal.cli.common import (JsonOpt, StrictOpt, console, emit_warnings, err_console, parse_relative, print_json,
                                table, write_json)
from senscal.cli.registry_opts import CreateSensorOpt, DbOpt, OperatorOpt, open_named_registry, print_head
from senscal.errors import FileFormatError, InputError

registry_app = typer.Typer(
    help="Sensor registry: calibration history, drift between calibrations, due dates.",
    no_args_is_help=True,
)
app.add_typer(registry_app, name="registry")

SerialArg = Annotated[str, typer.Argument(help="Sensor serial number.")]
CreateOpt = Annotated[bool, typer.Option(
    "--create", help="Create the --db registry file if it does not exist (without it a missing file is an error: "
                     "a typo must not open an empty registry).")]


def _open(db: str | None, create: bool = False, *, read_only: bool = False):
    """Open the registry; a ``--db`` SQLite file that does not exist needs ``create`` (see docs/registry.md).

    ``read_only`` commands also refuse an existing file without a registry in it (an empty file, a stray
    byte) instead of creating the schema there, unless ``create``.
    """
    return open_named_registry(db, create=create, remedy="--create to make a new registry there",
                               read_only=read_only)


def _tamper_warning(rep, url: str) -> str:
    """The one named warning of a broken hash chain (``registry verify`` exits 3 with it)."""
    from senscal.diagnostics import named

    more = len(rep.problems) - 1
    return named("registry-tampered", f"{url}: {rep.problems[0]}"
                 + (f" (and {more} more finding{'s' if more > 1 else ''})" if more else "")
                 + "; run 'senscal registry verify', restore the database from a backup or an export and compare")


def _chain_warnings(reg) -> list[str]:
    # History and due dates are only as good as the records: say when the chain is broken.
    rep = reg.verify()
    return [] if rep.intact else [_tamper_warning(rep, reg.url)]


def _parse_nominal(items: list[str] | None) -> dict:
    """``NAME=VALUE [UNIT]`` items into ``{name: {"value", "unit"}}``."""
    out = {}
    for item in items or []:
        name, sep, rest = item.partition("=")
        parts = rest.split(None, 1)
        try:
            if not sep or not name.strip() or not parts:
                raise ValueError
            value = float(parts[0])
            if not math.isfinite(value):
                raise ValueError
        except ValueError:
            raise InputError(f"--nominal must look like NAME=VALUE [UNIT], e.g. 'sensitivity=0.01 V/(m/s^2)', "
                             f"got {item!r}") from None
        unit = parts[1].strip() if len(parts) > 1 else ""
        if unit:
            from senscal.units import parse_unit

            parse_unit(unit, what=f"the unit of --nominal {name.strip()}")
        out[name.strip()] = {"value": value, "unit": unit}
    return out


@registry_app.command("sensors")
def sensors_cmd(db: DbOpt = None, create: CreateOpt = False, json_out: JsonOpt = False) -> None:
    """List the registered sensors and their number of calibration records."""
    with _open(db, create, read_only=True) as reg:
        sens = reg.sensors()
        counts = reg.counts()
        url = reg.url
    if json_out:
        print_json({"database": url, "sensors": [dict(s.to_dict(), n_calibrations=counts.get(s.serial, 0))
                                                 for s in sens]})
        return
    rows = [[s.serial, s.kind, s.model or "", s.manufacturer or "", str(counts.get(s.serial, 0)), s.notes or ""]
            for s in sens]
    console.print(table(f"Sensors in {url}", ["serial", "kind", "model", "manufacturer", "records", "notes"], rows))


@registry_app.command("add")
def add_cmd(
    serial: SerialArg,
    kind: Annotated[str, typer.Option("--kind", help="accelerometer, velocity sensor, magnetometer, ...")],
    model: Annotated[Optional[str], typer.Option("--model", help="Model designation.")] = None,
    manufacturer: Annotated[Optional[str], typer.Option("--manufacturer", help="Manufacturer.")] = None,
    nominal: Annotated[Optional[List[str]], typer.Option(
        "--nominal", help="Nominal value NAME=VALUE [UNIT] (repeatable), e.g. 'sensitivity=0.01 V/(m/s^2)'.")] = None,
    notes: Annotated[Optional[str], typer.Option("--notes", help="Free text.")] = None,
    db: DbOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Register a sensor (serials are unique); creates a --db registry file that does not exist yet."""
    nom = _parse_nominal(nominal)
    with _open(db, create=True) as reg:
        s = reg.add_sensor(serial, kind, model=model, manufacturer=manufacturer, nominal=nom, notes=notes)
        url = reg.url
    if json_out:
        print_json(s.to_dict())
    else:
        console.print(f"registered {s.kind} {s.serial} in {url}")


@registry_app.command("record")
def record_cmd(
    serial: SerialArg,
    quantity: Annotated[str, typer.Option("--quantity", help="Quantity name, e.g. sensitivity or sensitivity@160Hz.")],
    value: Annotated[float, typer.Option("--value", help="Calibrated value.")],
    uncertainty: Annotated[float, typer.Option(
        "--uncertainty", help="Uncertainty as quoted on the certificate (expanded with --k; standard if k=1).")],
    unit: Annotated[str, typer.Option("--unit", help="Unit of the value, e.g. 'mV/(m/s^2)'.")],
    date: Annotated[str, typer.Option("--date", metavar="ISO", help="Calibration date (ISO 8601; no offset = UTC).")],
    k: Annotated[Optional[float], typer.Option(
        "--k", help="Coverage factor of --uncertainty as the certificate states it (required: most quote k=2, "
                    "some k=1, and a wrong guess halves or doubles the uncertainty).")] = None,
    note: Annotated[Optional[str], typer.Option("--note", help="Free text (certificate number, lab, ...).")] = None,
    certificate: Annotated[Optional[str], typer.Option("--certificate", help="Certificate file or reference.")] = None,
    supersedes: Annotated[Optional[str], typer.Option(
        "--supersedes", metavar="ID", help="Id of a record this one corrects (records are never edited).")] = None,
    operator: OperatorOpt = None,
    create_sensor: CreateSensorOpt = None,
    db: DbOpt = None,
    create: CreateOpt = False,
    json_out: JsonOpt = False,
) -> None:
    """Enter a calibration done elsewhere (e.g. an old paper certificate)."""
    from senscal.registry import Quantity

    if k is None:
        # No default: certificates quote k=2 as a rule but not always, and a silent guess of either would
        # store an uncertainty twice or half the true one.
        raise InputError("give --k, the coverage factor the certificate states for --uncertainty (usually "
                         "--k 2; --k 1 for a standard uncertainty)")
    if not (math.isfinite(k) and k > 0):
        raise InputError(f"--k must be a positive, finite coverage factor, got {k}")
    from senscal.units import parse_unit

    parse_unit(unit, what="--unit")
    q = Quantity(quantity, value, uncertainty / k, unit, k)
    with _open(db, create or create_sensor is not None) as reg:
        rec = reg.record(serial, [q], performed_at=_date(date), job="manual", method="external certificate",
                         certificate=certificate, note=note, supersedes=supersedes, operator=operator,
                         create_kind=create_sensor)
        url = reg.url
        print_head(reg)
    if json_out:
        print_json(rec.to_dict())
    elif rec.already_recorded:
        console.print(f"already recorded as {rec.uid[:8]} in {url} (same date, value, certificate and note); "
                      "nothing added")
    else:
        console.print(f"recorded {quantity} = {value:.6g} ± {2 * q.uncertainty:.2g} {unit} (k=2) for {serial} "
                      f"on {rec.performed_at.isoformat()} as {rec.uid[:8]} in {url}")


def _date(text: str):
    from senscal.registry import parse_date

    return parse_date(text)


@registry_app.command("history")
def history_cmd(
    serial: SerialArg,
    quantity: Annotated[Optional[str], typer.Option("--quantity", help="Only this quantity.")] = None,
    plot: Annotated[Optional[Path], typer.Option("--plot", metavar="FILE.png", help="Plot with uncertainty bars.")] = None,
    all_records: Annotated[bool, typer.Option("--all", help="Include superseded records.")] = False,
    db: DbOpt = None,
    create: CreateOpt = False,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """A sensor's calibration history (table, JSON, plot)."""
    with _open(db, create, read_only=True) as reg:
        points = reg.history(serial, quantity, include_superseded=all_records)
        report = None
        if plot is not None and quantity is not None and sum(p.superseded_by is None for p in points) >= 2:
            report = reg.drift(serial, quantity)
        warns = _chain_warnings(reg)
    if plot is not None:
        if not points:
            raise InputError(f"sensor {serial!r} has no calibration records to plot")
        from senscal.registry.plot import plot_history

        plot_history(points, plot, report=report, title=f"{serial}: calibration history")
        err_console.print(f"plot written to {plot}")
    if json_out:
        print_json({"serial": serial, "records": [p.to_dict() for p in points], "warnings": warns})
        emit_warnings(warns, strict)
        return
    # Midnight means "a date" (paper certificates): show the time only when there is one.
    rows = [[p.date[:10] if p.date[11:19] == "00:00:00" else p.date[:16].replace("T", " ")]
            + ([] if quantity else [p.quantity])
            + [p.value, 2 * p.uncertainty, p.unit, p.uid[:8], p.job,
               ("superseded by " + p.superseded_by[:8]) if p.superseded_by else (p.note or "")] for p in points]
    title = f"Calibration history of {serial}" + (f" {quantity}" if quantity else "")
    console.print(table(f"{title}  (U = expanded uncertainty, k=2)",
                        ["date"] + ([] if quantity else ["quantity"]) + ["value", "U", "unit", "id", "job", "note"],
                        rows))
    emit_warnings(warns, strict)


@registry_app.command("due")
def due_cmd(
    serial: SerialArg,
    quantity: Annotated[str, typer.Option("--quantity", help="Quantity whose drift decides the due date.")],
    tolerance: Annotated[str, typer.Option(
        "--tolerance", help="Allowed deviation, relative: 1% or 0.01 (of --nominal, else of the first record).")],
    nominal: Annotated[Optional[float], typer.Option("--nominal", help="Reference value (default: first record).")] = None,
    k: Annotated[float, typer.Option("--k", help="Coverage factor added to the predicted deviation.")] = 2.0,
    plot: Annotated[Optional[Path], typer.Option("--plot", metavar="FILE.png", help="History, drift line, due date.")] = None,
    as_of: Annotated[Optional[str], typer.Option(
        "--as-of", metavar="ISO", help="Judge 'overdue' at this date (ISO 8601; default now).")] = None,
    db: DbOpt = None,
    create: CreateOpt = False,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Drift per year (weighted line through the history), its significance, and the due date."""
    tol = parse_relative(tolerance, "--tolerance")
    if tol == 0:
        raise InputError("--tolerance must be larger than zero")
    from senscal.registry import parse_date

    when = parse_date(as_of, what="--as-of")  # checked before opening the database
    with _open(db, create, read_only=True) as reg:
        rep = reg.drift(serial, quantity, tolerance=tol, nominal=nominal, k=k, as_of=when)
        points = reg.history(serial, quantity) if plot is not None else []
        warns = _chain_warnings(reg)
    if plot is not None:
        from senscal.registry.plot import plot_history

        plot_history(points, plot, report=rep, title=f"{serial}: {quantity} drift and due date")
        err_console.print(f"plot written to {plot}")
    doc = due_document(rep, tol)
    doc["warnings"] = warns
    if json_out:
        print_json(doc)
        emit_warnings(warns, strict)
        return
    rows = [
        ["drift per year", f"{rep.drift_per_year:.6g} {rep.unit}/yr", f"{2 * rep.u_drift_per_year:.2g}"],
        ["relative drift per year", f"{100 * rep.relative_drift_per_year:.4g} %/yr",
         f"{200 * rep.u_relative_drift_per_year:.2g} %"],
        ["significant", f"{'yes' if rep.significant else 'no'} (p = {rep.fit.p_value:.3g})", ""],
        ["Birge ratio", f"{rep.fit.birge_ratio:.3g}" if rep.fit.dof > 0 else "- (2 records)", ""],
        ["reference", f"{rep.reference:.6g} {rep.unit} ({rep.reference_source})", ""],
        ["tolerance", f"± {rep.tolerance:.4g} {rep.unit} ({100 * tol:.4g} %)", ""],
        ["due date", (doc["due_date"] or "none within 100 years") + ("  OVERDUE" if rep.overdue else ""), ""],
    ]
    console.print(table(f"{serial} {quantity}: drift from {rep.fit.n_records} records  (U: k=2)",
                        ["", "value", "U"], rows))
    if rep.due is not None and rep.due.overdue:
        err_console.print(f"{serial} is overdue: at the last calibration the deviation plus "
                          f"{k:g} standard uncertainties already reaches the tolerance")
    elif rep.overdue:
        err_console.print(f"{serial} is overdue: its due date {doc['due_date'][:10]} is before "
                          f"{doc['as_of'][:10]}")
    emit_warnings(warns, strict)


def due_document(rep, tol: float) -> dict:
    """The JSON of ``registry due`` (CLI contract)."""
    return {
        "serial": rep.serial, "quantity": rep.quantity, "unit": rep.unit,
        "drift_per_year": rep.drift_per_year, "u_drift_per_year": rep.u_drift_per_year,
        "relative_drift_per_year": rep.relative_drift_per_year,
        "u_relative_drift_per_year": rep.u_relative_drift_per_year,
        "significant": rep.significant, "p_value": rep.fit.p_value, "birge_ratio": rep.fit.birge_ratio,
        "n_records": rep.fit.n_records, "first_date": rep.first_date.isoformat(),
        "last_date": rep.last_date.isoformat(), "reference": rep.reference, "reference_source": rep.reference_source,
        "tolerance_relative": tol, "tolerance": rep.tolerance, "k": rep.due.k,
        "due_date": rep.due_date.isoformat() if rep.due_date is not None else None,
        "overdue": rep.overdue, "as_of": rep.as_of.isoformat() if rep.as_of is not None else None,
        "deviation_at_due": rep.due.deviation_at_due, "u_deviation_at_due": rep.due.u_deviation_at_due,
    }


@registry_app.command("verify")
def verify_cmd(db: DbOpt = None, create: CreateOpt = False, json_out: JsonOpt = False,
               expect_head: Annotated[Optional[str], typer.Option(
                   "--expect-head", metavar="HASH",
                   help="A head printed by an earlier write and kept elsewhere: exit 3 if the chain no longer "
                        "holds it (newest records deleted, history wiped or rebuilt).")] = None) -> None:
    """Recompute the hash chain over every record; exit 3 naming the first broken record.

    Detects records changed, deleted or inserted with direct database access
    (the triggers refuse such edits through SQL, but whoever can drop them
    can edit). Prints the chain head: keep it elsewhere to detect a history
    rebuilt from scratch.
    """
    from senscal.errors import DiagnosticError

    with _open(db, create, read_only=True) as reg:
        rep = reg.verify(expect_head)
        url = reg.url
    if json_out:
        print_json({"database": url, "intact": rep.intact, "n_records": rep.n_records, "head": rep.head,
                    "first_broken": rep.first_broken, "problems": list(rep.problems),
                    "n_standards": rep.n_standards})
    elif rep.intact:
        stds = f" and {rep.n_standards} reference-standard certificates" if rep.n_standards else ""
        console.print(f"{url}: {rep.n_records} records{stds}, hash chain intact; head {rep.head or '-'}")
    if not rep.intact:
        raise DiagnosticError(_tamper_warning(rep, url))


@registry_app.command("export")
def export_cmd(
    file: Annotated[Path, typer.Argument(help="Output JSON file (- for stdout).")],
    db: DbOpt = None,
    create: CreateOpt = False,
) -> None:
    """Write every sensor and record to a JSON file (import reads it back exactly)."""
    with _open(db, create, read_only=True) as reg:
        doc = reg.export()
        url = reg.url
    write_json(doc, file)
    n = sum(len(s["calibrations"]) for s in doc["sensors"])
    stds = f", {len(doc['standards'])} reference-standard certificates" if doc.get("standards") else ""
    err_console.print(f"exported {len(doc['sensors'])} sensors{stds} and {n} records from {url} to {file}")


@registry_app.command("import")
def import_cmd(
    file: Annotated[Path, typer.Argument(help="JSON file written by 'senscal registry export'.")],
    db: DbOpt = None,
    json_out: JsonOpt = False,
) -> None:
    """Add the sensors and records of an export file (records already present are skipped); creates a --db
    registry file that does not exist yet."""
    from senscal.io.sidefiles import read_json

    doc = read_json(file, "registry export")  # one line for unreadable, non-UTF-8, invalid or too deep JSON
    with _open(db, create=True) as reg:
        added = reg.import_(doc)
        url = reg.url
        print_head(reg)
    if json_out:
        print_json(added)
    else:
        stds = f", {added['standards']} reference-standard certificates" if added.get("standards") else ""
        console.print(f"imported {added['sensors']} sensors{stds} and {added['calibrations']} records into {url} "
                      f"({added['skipped']} already present)")


@simulate_app.command("registry")
def simulate_registry_cmd(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")],
    seed: Annotated[Optional[int], typer.Option("--seed", help="Random seed.")] = None,
    records: Annotated[int, typer.Option("--records", help="Number of yearly calibrations.")] = 7,
    drift: Annotated[float, typer.Option("--drift", help="True relative drift per year, e.g. 0.0012 = 0.12 %/yr.")] = 0.0012,
    u_rel: Annotated[float, typer.Option("--u-rel", help="Relative standard uncertainty of each calibration.")] = 4e-4,
) -> None:
    """A calibration history with known drift as a registry export (history.json) and its truth."""
    from senscal.registry import Quantity, open_registry
    from senscal.simulate.common import write_truth
    from senscal.simulate.registry import simulate_calibration_history

    if records < 1 or u_rel <= 0:
        raise InputError("--records must be at least 1 and --u-rel positive")
    value = 0.0100
    recs, truth = simulate_calibration_history(n_records=records, value=value, drift_per_year=drift * value,
                                               u_rel=u_rel, seed=seed)
    # Written through an in-memory registry, so the file is exactly what 'registry export' produces.
    with open_registry("sqlite://") as reg:
        reg.add_sensor("SIM-001", "accelerometer", model="simulated",
                       nominal={"sensitivity": {"value": value, "unit": "V/(m/s^2)"}})
        for r in recs:
            reg.record("SIM-001", [Quantity("sensitivity", r["value"], r["uncertainty"], "V/(m/s^2)", 2.0)],
                       performed_at=r["date"], method="simulated certificate", operator="simulator")
        doc = reg.export()
    p = write_json(doc, out / "history.json")
    q = write_truth(truth, out / "history_truth.json")
    console.print(f"wrote {p} and {q}; try: senscal registry import {p}")

# `registry serve` (the web view) lives in its own module; importing it registers the command.
from senscal.cli import registry_serve as _registry_serve  # noqa: E402,F401
# `registry standard ...` and `registry impact` (reference standards) live in their own module.
from senscal.cli import registry_standards as _registry_standards  # noqa: E402,F401
